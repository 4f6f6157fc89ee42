"""`ambiegen doctor` (issue 9): what it reports, and exit status 1 exactly when something is broken."""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

from ambiegen_ros import doctor

REPO = Path(__file__).resolve().parents[1]
ROS_VARS = ("AMENT_PREFIX_PATH", "RMW_IMPLEMENTATION", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS",
            "ROS_LOCALHOST_ONLY", "AMBIEGEN_TRANSPORT", "AMBIEGEN_MSGS_DIR")


def run_doctor(args: list[str], extra_path: Path | None = None, **env_vars: str) -> subprocess.CompletedProcess:
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    env.update(PYTHONPATH=os.pathsep.join(str(p) for p in (extra_path, REPO) if p), **env_vars)
    return subprocess.run([sys.executable, "-m", "ambiegen_ros.cli", "doctor", *args], cwd=REPO, env=env,
                          capture_output=True, text=True, timeout=300)


def by_name(payload: dict) -> dict[str, dict]:
    return {c["name"]: c for c in payload["checks"]}


@pytest.fixture(autouse=True)
def own_domain(ros_domain, monkeypatch) -> int:
    """A ROS domain id no other test holds (test/conftest.py), in this process and the doctor's."""
    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
    return ros_domain


@pytest.fixture
def clean_env(monkeypatch):
    for var in ROS_VARS:
        monkeypatch.delenv(var, raising=False)
    return monkeypatch


def test_healthy_machine_text_and_json(own_domain):
    text = run_doctor([])
    assert text.returncode == 0, text.stdout + text.stderr
    lines = text.stdout.splitlines()
    assert lines[-1] == "all fine"
    assert any(ln.startswith("[  ok] backend") for ln in lines)
    assert any("ambiegen_msgs" in ln and "not installed" in ln for ln in lines)

    got = run_doctor(["--json"], ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST", ROS_STATIC_PEERS="127.0.0.1;localhost")
    assert got.returncode == 0, got.stdout + got.stderr
    payload = json.loads(got.stdout)
    checks = by_name(payload)
    assert payload["ok"] is True and all(c["status"] in ("ok", "warn") for c in payload["checks"])
    backend = checks["backend"]["data"]
    assert backend["chosen"] in ("rclpy", "dds")
    if backend["rclpy_error"]:  # no ROS here: the reason is named
        assert backend["chosen"] == "dds" and "rclpy" in checks["backend"]["detail"]
    assert checks["domain_id"]["data"] == {"domain_id": own_domain}
    assert checks["discovery_range"]["data"] == {"range": "LOCALHOST", "campaign_range": "LOCALHOST"}
    assert checks["static_peers"]["data"] == {"peers": ["127.0.0.1", "localhost"]}
    assert checks["rmw"]["data"] == {"RMW_IMPLEMENTATION": None}
    assert checks["numba_loads"]["status"] == "ok"
    assert checks["shapely"]["data"]["minimum"] == "2.0" and checks["shapely"]["status"] == "ok"
    assert checks["ambiegen_msgs"]["data"] == {"installed": None}


def test_broken_dependencies_exit_1_and_are_named(tmp_path):
    info = tmp_path / "shapely-1.8.5.dist-info"
    info.mkdir()
    (info / "METADATA").write_text("Metadata-Version: 2.1\nName: shapely\nVersion: 1.8.5\n")
    (tmp_path / "numba").mkdir()
    (tmp_path / "numba" / "__init__.py").write_text("raise AttributeError(\"module 'coverage' has no attribute 'types'\")\n")
    got = run_doctor(["--json"], tmp_path)
    assert got.returncode == 1, got.stdout + got.stderr  # the start-up check does not stop the doctor itself
    checks = by_name(json.loads(got.stdout))
    assert checks["shapely"]["status"] == "fail"
    assert "shapely 1.8.5 is too old: 2.0 or newer" in checks["shapely"]["detail"]
    assert checks["numba_loads"]["status"] == "warn"  # optional: slower, not broken
    assert "AttributeError" in checks["numba_loads"]["detail"]
    assert checks["numpy"]["status"] == "ok"
    text = run_doctor([], tmp_path)
    assert text.returncode == 1 and "[fail] shapely" in text.stdout and "1 problem(s) found" in text.stdout


def test_bad_ros_environment_fails(clean_env):
    clean_env.setenv("ROS_DOMAIN_ID", "300")
    clean_env.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "LAN")
    clean_env.setenv("RMW_IMPLEMENTATION", "rmw_zenoh_cpp")
    checks = {c.name: c for c in doctor.run_checks()}
    assert checks["domain_id"].status == "fail" and "300" in checks["domain_id"].detail
    assert checks["discovery_range"].status == "fail" and "LAN" in checks["discovery_range"].detail
    assert checks["rmw"].status == "warn" and "rmw_zenoh_cpp" in checks["rmw"].detail
    assert doctor.report(list(checks.values())) == 1
    clean_env.setenv("ROS_DOMAIN_ID", "150")
    clean_env.delenv("ROS_AUTOMATIC_DISCOVERY_RANGE")
    assert doctor.check_domain().status == "warn"  # valid, but may collide with ephemeral ports
    clean_env.setenv("ROS_STATIC_PEERS", "no-such-host.invalid")
    peers = {c.name: c for c in doctor.check_discovery()}["static_peers"]
    assert peers.status == "fail" and "no-such-host.invalid" in peers.detail


def test_discovery_range_says_what_nodes_get_and_what_a_campaign_uses(clean_env):
    """Unset, nodes get SUBNET but `ambiegen campaign` LOCALHOST (issue 18): the doctor says both,
    from the very function the campaign uses."""
    from ambiegen_ros.campaign import discovery_scope

    check = {c.name: c for c in doctor.check_discovery()}["discovery_range"]
    assert check.data == {"range": "SUBNET", "campaign_range": "LOCALHOST"}
    assert check.detail.startswith("SUBNET (unset: SUBNET) for nodes started by hand or by ros2 launch; "
                                   "`ambiegen campaign` uses LOCALHOST (its default;")
    clean_env.setenv("ROS_AUTOMATIC_DISCOVERY_RANGE", "SUBNET")  # a campaign then follows the environment
    check = {c.name: c for c in doctor.check_discovery()}["discovery_range"]
    assert check.data == {"range": "SUBNET", "campaign_range": discovery_scope(None, dict(os.environ))}
    assert check.data["campaign_range"] == "SUBNET" and "`ambiegen campaign` uses SUBNET" in check.detail


def test_backend_forced_to_a_missing_one_fails(clean_env):
    from ambiegen_ros.ros.transport import rclpy_backend

    if rclpy_backend.is_available():
        pytest.skip("rclpy imports on this machine, so forcing it cannot fail")
    clean_env.setenv("AMBIEGEN_TRANSPORT", "rclpy")
    check = doctor.check_backend()
    assert check.status == "fail" and "rclpy" in check.detail and check.data["rclpy_error"]


def installed_msgs(root: Path) -> Path:
    msg = root / "share" / "ambiegen_msgs" / "msg"
    shutil.copytree(REPO / "ambiegen_msgs" / "msg", msg)
    return msg


def test_installed_messages_compared_with_ours(tmp_path, clean_env):
    from ambiegen_ros.ros.types import get_registry

    msg = installed_msgs(tmp_path / "ws")
    clean_env.setenv("AMENT_PREFIX_PATH", os.pathsep.join([str(tmp_path / "empty"), str(tmp_path / "ws")]))
    check = doctor.check_messages()
    assert check.status == "ok" and "same type hashes" in check.detail, check.detail

    victim = msg / "RunStatus.msg"  # no other message refers to it
    typename = "ambiegen_msgs/msg/RunStatus"
    (msg / f"{victim.stem}.json").write_text(json.dumps(
        {"type_hashes": [{"type_name": typename, "hash_string": "RIHS01_" + "0" * 64}]}))
    check = doctor.check_messages()  # rosidl built another hash than the .msg we read
    assert check.status == "fail" and typename in check.detail

    (msg / f"{victim.stem}.json").unlink()
    victim.write_text(victim.read_text() + "\nuint8 added_field\n")
    check = doctor.check_messages()
    assert check.status == "fail" and f"{typename} differs" in check.detail
    assert get_registry().type_hash(typename)[:15] in check.detail  # ours, next to the installed one

    victim.unlink()
    check = doctor.check_messages()
    assert check.status == "fail" and f"{typename} missing from the installed package" in check.detail


def test_python_m_doctor_is_the_librarys_own_main():
    """`python -m ambiegen_ros.doctor` runs ``ambiegen_ros.doctor.main`` (the library owns it; the
    command line imports it, never the other way round: test_architecture.py), with the same
    option and exit statuses as `ambiegen doctor`."""
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    env["PYTHONPATH"] = str(REPO)

    def run(*args: str) -> subprocess.CompletedProcess:
        return subprocess.run([sys.executable, "-m", "ambiegen_ros.doctor", *args], cwd=REPO, env=env,
                              capture_output=True, text=True, timeout=300)

    got = run("--json")
    assert got.returncode == 0, got.stdout + got.stderr
    assert json.loads(got.stdout)["ok"] is True
    shown = run("--help")
    assert shown.returncode == 0 and shown.stdout.startswith("usage: python -m ambiegen_ros.doctor [-h] [--json]")
    bad = run("--jsn")
    assert bad.returncode == 2 and bad.stderr.splitlines()[-1] == (
        "python -m ambiegen_ros.doctor: error: unrecognized arguments: --jsn")
    # the launcher's `ambiegen doctor` (ambiegen_ros.entry) runs the same main under its own name
    launched = subprocess.run([sys.executable, "-c", "import sys; from ambiegen_ros.entry import launch; "
                               "sys.exit(launch('ambiegen', ['doctor', '--bogus']))"], cwd=REPO, env=env,
                              capture_output=True, text=True, timeout=300)
    assert launched.returncode == 2 and "ambiegen doctor: error: unrecognized arguments: --bogus" in launched.stderr
