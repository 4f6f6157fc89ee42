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
    env = dict(os.environ, ROS_DOMAIN_ID="71", PYTHONUNBUFFERED="1")
    env["PYTHONPATH"] = os.pathsep.join(str(p) for p in (extra_path, REPO) if p)
    return subprocess.run([sys.executable, *args], cwd=REPO, env=env, capture_output=True, text=True,
                          timeout=timeout)


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
    ["-m", "ambiegen_ros", "search", "--problem", "robot"],  # what the `ambiegen` script runs
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
        G, lengths = problem.sample(6, np.random.default_rng(5))
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

    for name in ("vehicle", "robot", "thermostat"):  # same numbers as this process (numba, when it loads)
        problem = get_problem(name)
        G, lengths = problem.sample(6, np.random.default_rng(5))
        np.testing.assert_allclose(out[name], problem.evaluate(G, lengths).f1, rtol=1e-9, atol=1e-9)
