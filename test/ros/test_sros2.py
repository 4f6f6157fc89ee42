"""Secure ROS 2 (SROS2).

* DDS backend (PyPI cyclonedds): the wheel is measured to have no DDS Security, so a node refuses
  to start when security is enforced (ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY=Enforce) and
  warns that it runs unsecured when it is only requested (Permissive). If a future wheel gains
  DDS Security, ``test_pypi_cyclonedds_has_no_dds_security`` fails and says so.
* rclpy backend: where a ROS 2 Jazzy with ``ros2 security`` is installed (/opt/ros/jazzy or
  $AMBIEGEN_ROS_SETUP), a keystore and enclaves are created with ``ros2 security`` and a worker
  and a generator complete a run under ROS_SECURITY_ENABLE=true / Enforce; a node whose enclave
  does not exist must fail to start.
"""
from __future__ import annotations

import os
import shlex
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import pytest  # noqa: E402

from ambiegen_ros.ros.transport import dds_backend  # noqa: E402

DDS_DOMAIN = 9
RCLPY_DOMAIN = 6
ENFORCE = {"ROS_SECURITY_ENABLE": "true", "ROS_SECURITY_STRATEGY": "Enforce"}
needs_dds = pytest.mark.skipif(not dds_backend.is_available(), reason="cyclonedds is not installed")


def _env(domain: int, **extra: str) -> dict[str, str]:
    env = dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1", **extra)
    for key in ("ROS_SECURITY_ENABLE", "ROS_SECURITY_STRATEGY", "ROS_SECURITY_KEYSTORE", "ROS_SECURITY_ENCLAVE_OVERRIDE"):
        if key not in extra:
            env.pop(key, None)
    return env


# --- the DDS backend ---------------------------------------------------------------------------------
@needs_dds
def test_pypi_cyclonedds_has_no_dds_security():
    """The measurement behind the refusal: no plugins in the wheel, and its config rejects <Security>."""
    import cyclonedds

    site = Path(cyclonedds.__file__).resolve().parents[1]
    shipped = [p.name for d in site.glob("cyclonedds*") for p in d.rglob("*") if "security" in p.name.lower()]
    assert shipped == [], f"the wheel ships security files now: {shipped} -- revisit dds_backend.check_security_environment"
    probe = (
        "from cyclonedds.domain import Domain\n"
        "cfg = '<CycloneDDS><Domain Id=\"any\"><Security><Authentication><Library path=\"dds_security_auth\"/>"
        "<IdentityCA>file:/x</IdentityCA><IdentityCertificate>file:/x</IdentityCertificate>"
        "<PrivateKey>file:/x</PrivateKey></Authentication></Security></Domain></CycloneDDS>'\n"
        "try:\n    Domain(%d, cfg)\nexcept Exception as e:\n    print('REFUSED', type(e).__name__)\nelse:\n    print('ACCEPTED')\n"
    ) % DDS_DOMAIN
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=_env(DDS_DOMAIN))
    assert "REFUSED" in out.stdout, out.stdout + out.stderr
    assert "Security: unknown element" in out.stderr  # Cyclone's own words: built without DDS_HAS_SECURITY


@needs_dds
def test_dds_node_refuses_to_start_when_security_is_enforced(tmp_path):
    """A real worker process exits with status 2 and a clear message instead of running insecure."""
    args = [sys.executable, "-m", "sim_nodes.thermostat_sim", "--ros-args", "-p", "model:=surrogate"]
    out = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=180,
                         env=_env(DDS_DOMAIN, AMBIEGEN_TRANSPORT="dds", **ENFORCE))
    assert out.returncode == 2, out.stdout + out.stderr
    assert "refusing to start" in out.stderr and "ROS_SECURITY_STRATEGY=Enforce" in out.stderr, out.stderr
    assert "executing thermostat scenarios" not in out.stdout + out.stderr


@needs_dds
def test_dds_node_warns_when_security_is_only_permissive(monkeypatch, capsys):
    from ambiegen_ros.ros.transport import create_node

    monkeypatch.setenv("ROS_DOMAIN_ID", str(DDS_DOMAIN))
    monkeypatch.setenv("ROS_SECURITY_ENABLE", "true")
    monkeypatch.setenv("ROS_SECURITY_STRATEGY", "Permissive")
    node = create_node("permissive", argv=["x"], backend="dds")
    try:
        assert node.ok()
    finally:
        node.shutdown()
    assert "runs WITHOUT security" in capsys.readouterr().err
    monkeypatch.setenv("ROS_SECURITY_STRATEGY", "Enforce")
    with pytest.raises(dds_backend.SecurityUnsupported, match="refusing to start"):
        create_node("enforced", argv=["x"], backend="dds")
    monkeypatch.setenv("ROS_SECURITY_ENABLE", "false")  # anything but exactly "true" is off, as in rcl
    create_node("off", argv=["x"], backend="dds").shutdown()


# --- the rclpy backend under a real ROS 2 with sros2 ------------------------------------------------
def _ros_setup() -> Path | None:
    for candidate in (os.environ.get("AMBIEGEN_ROS_SETUP", ""), "/opt/ros/jazzy/setup.bash"):
        if candidate and Path(candidate).is_file():
            return Path(candidate)
    return None


def _in_ros(setup: Path, command: str, env: dict[str, str], timeout: float, cwd: Path = REPO) -> subprocess.CompletedProcess:
    return subprocess.run(["bash", "-c", f"source {shlex.quote(str(setup))} && {command}"], cwd=cwd, env=env,
                          capture_output=True, text=True, timeout=timeout)


def _ros_python() -> str:
    """The interpreter that runs the nodes under ROS ($AMBIEGEN_ROS_PYTHON, else this one)."""
    return shlex.quote(os.environ.get("AMBIEGEN_ROS_PYTHON") or sys.executable)


def _sros2_setup() -> Path:
    setup = _ros_setup()
    if setup is None:
        pytest.skip("no ROS 2 installation (/opt/ros/jazzy/setup.bash or $AMBIEGEN_ROS_SETUP): rclpy SROS2 cannot run here")
    probe = _in_ros(setup, f"ros2 security --help && {_ros_python()} -c 'import rclpy'", _env(RCLPY_DOMAIN), 120)
    if probe.returncode != 0:
        pytest.skip(f"ROS 2 at {setup} has no `ros2 security` (sros2) or its rclpy does not import: {probe.stderr[-300:]}")
    return setup


def test_rclpy_run_under_enforced_sros2(tmp_path):
    setup = _sros2_setup()
    keystore = tmp_path / "keystore"
    env = _env(RCLPY_DOMAIN)
    made = _in_ros(setup, f"ros2 security create_keystore {shlex.quote(str(keystore))} && "
                          f"ros2 security create_enclave {shlex.quote(str(keystore))} /ambiegen/worker && "
                          f"ros2 security create_enclave {shlex.quote(str(keystore))} /ambiegen/generator", env, 300)
    assert made.returncode == 0, made.stdout + made.stderr
    secure = _env(RCLPY_DOMAIN, AMBIEGEN_TRANSPORT="rclpy", ROS_SECURITY_KEYSTORE=str(keystore), **ENFORCE)
    py = _ros_python()

    missing = _in_ros(setup, f"timeout 60 {py} -m sim_nodes.thermostat_sim --ros-args --enclave /ambiegen/nowhere "
                             "-p model:=surrogate", secure, 120)
    assert missing.returncode != 0, "a node with no enclave ran under Enforce:\n" + missing.stderr[-2000:]

    log = open(tmp_path / "worker.log", "wb")
    worker = subprocess.Popen(["bash", "-c", f"source {shlex.quote(str(setup))} && exec {py} -m sim_nodes.thermostat_sim "
                               "--ros-args --enclave /ambiegen/worker -p model:=surrogate -p worker_id:=secure_w"],
                              cwd=REPO, env=secure, stdout=log, stderr=subprocess.STDOUT)
    try:
        gen = _in_ros(setup, f"timeout 300 {py} -m ambiegen_ros.nodes.generator --ros-args --enclave /ambiegen/generator "
                             "-p problem:=thermostat -p algorithm:=random -p evaluations:=20 -p population:=10 "
                             "-p mode:=in_the_loop -p min_workers:=1 -p subscriber_wait:=120.0 -p seed:=1", secure, 360)
        worker_log = (tmp_path / "worker.log").read_text(errors="replace")
        assert gen.returncode == 0, gen.stderr[-3000:] + "\nworker:\n" + worker_log[-2000:]
        assert " done: " in gen.stderr and " 0 timeouts" in gen.stderr, gen.stderr[-2000:]
    finally:
        worker.terminate()
        try:
            worker.wait(30)
        except subprocess.TimeoutExpired:
            worker.kill()
            worker.wait()
        log.close()
