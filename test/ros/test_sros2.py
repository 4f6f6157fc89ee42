"""Secure ROS 2 (SROS2).

* DDS backend (PyPI cyclonedds): the wheel is measured to have no DDS Security, so a node refuses
  to start when security is enforced (ROS_SECURITY_ENABLE=true, ROS_SECURITY_STRATEGY=Enforce) and
  warns that it runs unsecured when it is only requested (Permissive). If a future wheel gains
  DDS Security, ``test_pypi_cyclonedds_has_no_dds_security`` fails and says so.
* rclpy backend: test/real_ros/test_sros2_rclpy.py (runs where a ROS 2 Jazzy with sros2 is installed).
"""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
if str(REPO) not in sys.path:
    sys.path.insert(0, str(REPO))

import pytest  # noqa: E402

from ambiegen_ros.ros.transport import dds_backend  # noqa: E402

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
def test_pypi_cyclonedds_has_no_dds_security(ros_domain):
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
    ) % ros_domain
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=120, env=_env(ros_domain))
    assert "REFUSED" in out.stdout, out.stdout + out.stderr
    assert "Security: unknown element" in out.stderr  # Cyclone's own words: built without DDS_HAS_SECURITY


@needs_dds
def test_dds_node_refuses_to_start_when_security_is_enforced(tmp_path, ros_domain):
    """A real worker process exits with status 2 and a clear message instead of running insecure."""
    args = [sys.executable, "-m", "sim_nodes.thermostat_sim", "--ros-args", "-p", "model:=surrogate"]
    out = subprocess.run(args, cwd=REPO, capture_output=True, text=True, timeout=180,
                         env=_env(ros_domain, AMBIEGEN_TRANSPORT="dds", **ENFORCE))
    assert out.returncode == 2, out.stdout + out.stderr
    assert "refusing to start" in out.stderr and "ROS_SECURITY_STRATEGY=Enforce" in out.stderr, out.stderr
    assert "executing thermostat scenarios" not in out.stdout + out.stderr


@needs_dds
def test_dds_node_warns_when_security_is_only_permissive(monkeypatch, capsys, ros_domain):
    from ambiegen_ros.ros.transport import create_node

    monkeypatch.setenv("ROS_DOMAIN_ID", str(ros_domain))
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
