"""Dependency minimums (issue 9): one table, the same in setup.py and package.xml, checked at start-up.

A too-old library is simulated with a fake ``.dist-info`` first on PYTHONPATH (what
``importlib.metadata`` reads); a broken numba with a fake ``numba`` package whose import raises
AttributeError, as an old ``coverage`` on the path made the real one do.
"""
from __future__ import annotations

import json
import os
import runpy
import subprocess
import sys
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np
import pytest
import setuptools

from ambiegen_ros import deps

REPO = Path(__file__).resolve().parents[1]


def fake_dist(root: Path, name: str, version: str) -> None:
    info = root / f"{name}-{version}.dist-info"
    info.mkdir(parents=True)
    (info / "METADATA").write_text(f"Metadata-Version: 2.1\nName: {name}\nVersion: {version}\n")


def run(args: list[str], extra_path: Path | None = None, timeout: float = 180.0) -> subprocess.CompletedProcess:
    env = dict(os.environ, PYTHONUNBUFFERED="1")  # ROS_DOMAIN_ID: this test's own (own_domain)
    env["PYTHONPATH"] = os.pathsep.join(str(p) for p in (extra_path, REPO) if p)
    return subprocess.run([sys.executable, *args], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=timeout)


@pytest.fixture(autouse=True)
def own_domain(ros_domain, monkeypatch) -> None:
    """A ROS domain id no other test holds (test/conftest.py), for the nodes these tests start."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))


# --- one table ------------------------------------------------------------------------------------
def test_setup_py_takes_install_requires_from_the_table(monkeypatch):
    captured = {}
    monkeypatch.setattr(setuptools, "setup", lambda **kw: captured.update(kw))
    monkeypatch.chdir(REPO)
    runpy.run_path(str(REPO / "setup.py"), run_name="__main__")
    assert captured["install_requires"] == deps.install_requires()
    by_name = {d.name: d for d in deps.DEPENDENCIES}
    for line in captured["install_requires"]:
        name, op, version = line.partition("==") if "==" in line else line.partition(">=")
        dep = by_name[name]
        assert version == (dep.pin if op == "==" else dep.minimum)
        assert deps.version_tuple(version) >= deps.version_tuple(dep.minimum)


def test_package_xml_carries_the_same_minimums():
    root = ET.parse(REPO / "package.xml").getroot()
    declared = {e.text.strip(): e.get("version_gte") for e in root if e.tag in ("depend", "exec_depend")}
    for dep in deps.DEPENDENCIES:
        if dep.rosdep:
            assert declared.get(dep.rosdep) == dep.minimum, (dep.rosdep, declared.get(dep.rosdep), dep.minimum)
    python_keys = {k for k, v in declared.items() if v is not None}
    assert python_keys == {d.rosdep for d in deps.DEPENDENCIES if d.rosdep}  # no stray minimum


def test_requirements_ros_txt_pins_match_the_table():
    lines = [ln.strip() for ln in (REPO / "requirements-ros.txt").read_text().splitlines()
             if ln.strip() and not ln.startswith("#")]
    table = {d.name: d.requirement() for d in deps.DEPENDENCIES}
    assert lines and all(table[ln.split("=")[0].split(">")[0]] == ln for ln in lines)
    # everything without an apt package (rosdep key) must come from that file, except the DDS
    # transport, which a ROS machine (rclpy) does not need
    needed = {d.name for d in deps.DEPENDENCIES if not d.rosdep and d.name != "cyclonedds"}
    assert needed == {ln.split("=")[0] for ln in lines}


def test_version_parsing_and_status_lines():
    assert deps.version_tuple("2.0.1rc1") == (2, 0, 1)
    assert deps.version_tuple("1.8.5") < deps.version_tuple("2.0")
    assert deps.version_tuple("0.6.1.6") > deps.version_tuple("0.6.1")
    shapely = next(d for d in deps.DEPENDENCIES if d.name == "shapely")
    numba = next(d for d in deps.DEPENDENCIES if d.name == "numba")
    assert deps.Status(shapely, "2.0.0").problem() is None
    assert "shapely 1.8.5 is too old: 2.0 or newer" in deps.Status(shapely, "1.8.5").problem()
    assert "shapely is not installed" in deps.Status(shapely, None).problem()
    assert deps.Status(numba, None).problem() is None  # optional: absent is fine
    assert "numba 0.50.0 is too old" in deps.Status(numba, "0.50.0").problem()  # installed and old is not


def test_this_environment_passes():
    assert deps.startup_errors() == []


def test_versions_are_read_as_importlib_metadata_reads_them_without_importing_it(tmp_path, monkeypatch):
    """deps reads the first metadata directory on the path itself (start-up, issue 47): the same
    answers as ``importlib.metadata.version``, a fake dist-info or egg-info file first on the path too."""
    from importlib import metadata

    def expected(name: str) -> str | None:
        try:
            return metadata.version(name)
        except metadata.PackageNotFoundError:
            return None

    for name in [d.name for d in deps.DEPENDENCIES] + ["pyyaml", "Shapely", "no-such-distribution"]:
        assert deps.installed_version(name) == expected(name), name
    fake_dist(tmp_path, "shapely", "1.8.5")
    (tmp_path / "PyYAML-5.1-py3.11.egg-info").write_text("Metadata-Version: 1.1\nName: PyYAML\nVersion: 5.1\n")
    monkeypatch.syspath_prepend(str(tmp_path))
    assert deps.installed_version("shapely") == expected("shapely") == "1.8.5"
    assert deps.installed_version("PyYAML") == expected("PyYAML") == "5.1"
    got = run(["-c", "import sys; from ambiegen_ros import deps; deps.startup_errors(); "
                     "print('importlib.metadata' in sys.modules)"])
    assert got.stdout.strip() == "False", got.stderr


# --- fail early: one line, status 2 ------------------------------------------------------------------
@pytest.mark.parametrize("entry", [
    ["-m", "ambiegen_ros.cli", "evaluate", "test/data/does-not-matter.json"],
    ["-m", "sim_nodes.car_sim", "--ros-args", "-p", "model:=surrogate"],
    ["-m", "ambiegen_ros.nodes.replay", "--ros-args", "-p", "log:=missing.mcap"],
])
def test_too_old_shapely_stops_at_start_up(tmp_path, entry):
    fake_dist(tmp_path, "shapely", "1.8.5")
    got = run(entry, tmp_path)
    assert got.returncode == 2, got.stderr
    first = got.stderr.splitlines()[0]
    assert "error: shapely 1.8.5 is too old: 2.0 or newer is needed" in first
    assert "Traceback" not in got.stderr
    assert "ambiegen doctor" in got.stderr  # where to look next


def old_pymoo(root: Path) -> None:
    """A pymoo 0.5.0 first on the path, too old for ``pymoo.core.problem`` to import at all."""
    fake_dist(root, "pymoo", "0.5.0")
    (root / "pymoo").mkdir()
    (root / "pymoo" / "__init__.py").write_text("__version__ = '0.5.0'\n")


@pytest.mark.parametrize("entry", [
    ["-m", "ambiegen_ros", "search", "--problem", "robot", "--out", "run"],  # what the `ambiegen` script runs
    ["-c", "import sys; from ambiegen_ros.entry import generator; sys.exit(generator())"],  # `ros2 run ... generator`
])
def test_library_too_old_to_import_is_one_line_not_a_traceback(tmp_path, entry):
    """The script's module imports pymoo before its main could check it: the launcher reports it."""
    old_pymoo(tmp_path)
    got = run(entry, tmp_path)
    assert got.returncode == 2, got.stderr
    assert "error: pymoo 0.5.0 is too old: 0.6.1.6 or newer is needed" in got.stderr.splitlines()[0]
    assert "Traceback" not in got.stderr


def test_doctor_runs_when_the_cli_cannot_import(tmp_path):
    old_pymoo(tmp_path)
    got = run(["-m", "ambiegen_ros", "doctor", "--json"], tmp_path)
    assert "Traceback" not in got.stderr, got.stderr
    report = json.loads(got.stdout)
    assert got.returncode != 0
    assert any("pymoo 0.5.0 is too old" in line for line in json.dumps(report).split('"')), report


def test_a_bug_is_not_disguised_as_a_dependency_problem():
    """An import error that no dependency explains still shows its traceback."""
    got = run(["-c", "import sys; from ambiegen_ros import entry; entry.SCRIPTS['ambiegen'] = 'ambiegen_ros.nope'; "
                     "sys.exit(entry.launch('ambiegen', ['--help']))"])
    assert got.returncode == 1 and "ModuleNotFoundError: No module named 'ambiegen_ros.nope'" in got.stderr


# --- a broken accelerator falls back ----------------------------------------------------------------
BROKEN_NUMBA = "raise AttributeError(\"module 'coverage' has no attribute 'types'\")\n"
EVALUATE = """
import json, warnings
import numpy as np
from ambiegen_ros.problems import get_problem
warnings.simplefilter("always")
out = {}
with warnings.catch_warnings(record=True) as caught:
    for name in ("vehicle", "robot", "thermostat"):
        problem = get_problem(name)
        G, lengths = problem.sample(40, np.random.default_rng(5))  # > SMALL_BATCH: the kernels' turn
        out[name] = [float(f) for f in problem.evaluate(G, lengths).f1]
out["warnings"] = [str(w.message) for w in caught]
print(json.dumps(out))
"""


def test_numba_failing_with_attribute_error_falls_back_to_numpy(tmp_path):
    (tmp_path / "numba").mkdir()
    (tmp_path / "numba" / "__init__.py").write_text(BROKEN_NUMBA)
    got = run(["-c", EVALUATE], tmp_path, timeout=600)
    assert got.returncode == 0, got.stderr[-3000:]
    out = json.loads(got.stdout.splitlines()[-1])
    assert any("numba unavailable (AttributeError" in w for w in out["warnings"]), out["warnings"]
    from ambiegen_ros.problems import get_problem

    for name in ("vehicle", "robot", "thermostat"):  # the same bits as this process (numba, when it loads)
        problem = get_problem(name)
        G, lengths = problem.sample(40, np.random.default_rng(5))
        np.testing.assert_array_equal(out[name], problem.evaluate(G, lengths).f1)


# --- reproducible installs (issue 18): constraints.txt ----------------------------------------------
def constraint_pins() -> dict[str, str]:
    """constraints.txt as {canonical name: version}."""
    from packaging.utils import canonicalize_name

    pins = {}
    for line in (REPO / "constraints.txt").read_text().splitlines():
        line = line.split("#", 1)[0].strip()
        if line:
            name, sep, version = line.partition("==")
            assert sep and version, f"constraints.txt: {line!r} is not NAME==VERSION"
            pins[canonicalize_name(name)] = version
    return pins


def declared_requirements(monkeypatch) -> list[str]:
    """What setup.py asks for with the test extra (its ranges, not the pins)."""
    captured: dict = {}
    monkeypatch.setattr(setuptools, "setup", lambda **kw: captured.update(kw))
    monkeypatch.chdir(REPO)
    runpy.run_path(str(REPO / "setup.py"), run_name="__main__")
    assert "tests_require" not in captured  # setuptools warns about it at every install
    return captured["install_requires"] + captured["extras_require"]["test"]


def needed_distributions(requirements: list[str]) -> dict[str, object]:
    """Every distribution the requirements need on this Python, transitive ones included, with the
    requirement that brought it in (read from the installed metadata)."""
    from importlib import metadata

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    needed: dict[str, object] = {}
    seen: set[tuple[str, tuple[str, ...]]] = set()
    todo = [(Requirement(r), "") for r in requirements]
    while todo:
        req, extra = todo.pop()
        if req.marker is not None and not req.marker.evaluate({"extra": extra}):
            continue
        name = canonicalize_name(req.name)
        if (name, tuple(sorted(req.extras))) in seen:
            continue
        seen.add((name, tuple(sorted(req.extras))))
        needed.setdefault(name, req)
        try:
            dist = metadata.distribution(req.name)
        except metadata.PackageNotFoundError:
            continue  # the completeness test still requires its pin
        for line in dist.requires or []:
            sub = Requirement(line)
            for sub_extra in sorted(req.extras) or [""]:
                todo.append((sub, sub_extra))
    return needed


def test_constraints_pin_every_needed_package_inside_the_declared_ranges(monkeypatch):
    pins = constraint_pins()
    requirements = declared_requirements(monkeypatch)
    assert any(r.startswith("pytest-random-order") for r in requirements)
    needed = needed_distributions(requirements)
    assert {"numpy", "numba", "llvmlite", "pytest", "pluggy", "pytest-random-order"} <= set(needed)
    missing = sorted(set(needed) - set(pins))
    assert not missing, f"constraints.txt lacks {missing} (regenerate it: see its header)"
    for name, req in needed.items():  # a pin outside the metadata's range could never be installed
        assert req.specifier.contains(pins[name], prereleases=True), (name, str(req), pins[name])
    for dep in deps.DEPENDENCIES:  # deps.py's exact pins and the lock agree
        if dep.pin:
            assert pins[dep.name.lower()] == dep.pin, dep.name
    assert {"pip", "setuptools"} <= set(pins)  # the installer and the build backend are pinned too


def test_setup_sh_installed_the_pinned_versions(monkeypatch):
    """After `bash scripts/setup.sh` (as CI runs it), what is installed is what constraints.txt pins."""
    from importlib import metadata

    marker = Path(sys.prefix) / "ambiegen-install"
    if not marker.exists() or marker.read_text().strip() != "constraints.txt":
        pytest.skip("not a .venv that scripts/setup.sh installed from constraints.txt")
    pins = constraint_pins()
    needed = needed_distributions(declared_requirements(monkeypatch))
    drift = {name: (metadata.version(name), pins[name]) for name in sorted(set(needed) | {"pip"})
             if metadata.version(name) != pins[name]}
    assert not drift, f"installed vs pinned: {drift} (re-run bash scripts/setup.sh)"


def fake_venv_setup(tmp_path: Path, python_version: str = "3.11") -> tuple[Path, dict[str, str]]:
    """A copy of setup.sh and constraints.txt whose .venv/bin/python only logs its arguments, and a
    PATH without apt-get: the install logic runs in a blink, with no network."""
    root = tmp_path / "repo"
    (root / "scripts").mkdir(parents=True)
    (root / "scripts" / "setup.sh").write_text((REPO / "scripts" / "setup.sh").read_text())
    (root / "constraints.txt").write_text((REPO / "constraints.txt").read_text())
    venv_bin = root / ".venv" / "bin"
    venv_bin.mkdir(parents=True)
    (venv_bin / "python").write_text(
        "#!/bin/bash\n"
        f'echo "$*" >> "{root}/calls.log"\n'
        f'case "$1" in -c) echo {python_version};; --version) echo "Python {python_version}.0";; esac\n')
    (venv_bin / "ambiegen").write_text("#!/bin/bash\necho 'ambiegen 0.1.0'\n")
    tools = tmp_path / "tools"
    tools.mkdir()
    for tool in ("bash", "cat", "cut", "dirname", "id", "rm", "sed"):
        found = next(Path(d) / tool for d in ("/usr/bin", "/bin") if (Path(d) / tool).exists())
        (tools / tool).symlink_to(found)
    for script in (venv_bin / "python", venv_bin / "ambiegen"):
        script.chmod(0o755)
    return root, {"PATH": str(tools), "HOME": str(tmp_path)}


def test_setup_sh_installs_from_the_lock_and_latest_ignores_it(tmp_path):
    root, env = fake_venv_setup(tmp_path)
    bash = str(Path(env["PATH"]) / "bash")
    done = subprocess.run([bash, "scripts/setup.sh"], cwd=root, env=env, capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    calls = (root / "calls.log").read_text().splitlines()
    installs = [c for c in calls if c.startswith("-m pip install")]
    assert installs[0].endswith("-c constraints.txt pip")  # pip first, at its pin
    assert installs[-1].endswith("-c constraints.txt --build-constraint constraints.txt -e .[test]")
    assert not any("--upgrade" in c for c in installs)
    assert (root / ".venv" / "ambiegen-install").read_text().strip() == "constraints.txt"
    assert "installing the versions pinned in constraints.txt" in done.stdout
    assert "warning" not in done.stdout

    (root / "calls.log").unlink()
    latest = subprocess.run([bash, "scripts/setup.sh"], cwd=root, env={**env, "AMBIEGEN_LATEST": "1"},
                            capture_output=True, text=True, timeout=60)
    assert latest.returncode == 0, latest.stderr
    assert "AMBIEGEN_LATEST=1: ignoring constraints.txt" in latest.stdout
    installs = [c for c in (root / "calls.log").read_text().splitlines() if c.startswith("-m pip install")]
    assert installs and not any("constraints.txt" in c for c in installs)
    assert installs[-1].endswith("--upgrade --upgrade-strategy eager -e .[test]")
    assert (root / ".venv" / "ambiegen-install").read_text().strip() == "latest"


def test_setup_sh_says_when_the_python_is_not_the_verified_one(tmp_path):
    root, env = fake_venv_setup(tmp_path, python_version="3.12")
    done = subprocess.run([str(Path(env["PATH"]) / "bash"), "scripts/setup.sh"], cwd=root, env=env,
                          capture_output=True, text=True, timeout=60)
    assert done.returncode == 0, done.stderr
    assert "verified on Python 3.11, .venv has Python 3.12" in done.stdout
