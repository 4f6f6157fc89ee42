"""Helpers of the real-ROS suite: find a ROS 2 Jazzy install, build the repo with colcon, run nodes.

The suite runs when ``$AMBIEGEN_ROS_SETUP`` (if set, it replaces the default; set it to a path
that does not exist to switch the suite off) or ``/opt/ros/jazzy/setup.bash`` exists and
``import rclpy`` works under it; otherwise every test is skipped with the reason.

pytest runs in the project's venv, which has no rclpy. Every ROS command is therefore a
subprocess ``bash -c 'source <setup> && source <workspace>/install/setup.bash && exec CMD'`` on
the ROS python (the interpreter colcon used, /usr/bin/python3 for a Debian build). The
executables of ``ambiegen_ros`` import pymoo, numpy, mcap, shapely, rosbags, scipy, which the
venv has and a ROS install usually has not: the venv's site-packages directory
(``sysconfig.get_paths()['purelib']`` of the pytest interpreter) is APPENDED to ``PYTHONPATH``
after sourcing, so ROS's own packages come first and the venv supplies the rest (its numpy 2
then also serves rclpy's message extensions: this needs a Jazzy whose rosidl_generator_py was
compiled against numpy 2 headers, or a venv numpy of the same major version as the install's).
The same python major.minor is required (checked by the probe). colcon itself runs WITHOUT the
venv on the path, so the build uses only the install's python packages.

Every ROS-side process gets ``AMBIEGEN_TRANSPORT=rclpy`` (a broken rclpy is an error, never a
silent fall-back to the DDS backend); venv-side processes get ``AMBIEGEN_TRANSPORT=dds`` and no
ROS variables. ``ROS_AUTOMATIC_DISCOVERY_RANGE=SUBNET`` everywhere; each test has its own
ROS_DOMAIN_ID (``ros_domain``, test/conftest.py).
"""
from __future__ import annotations

import functools
import json
import os
import shlex
import shutil
import signal
import subprocess
import sys
import sysconfig
import time
from pathlib import Path
from typing import Any

import pytest

REPO = Path(__file__).resolve().parents[2]
SETUP_VAR = "AMBIEGEN_ROS_SETUP"
DEFAULT_SETUP = "/opt/ros/jazzy/setup.bash"
VENV_SITE = sysconfig.get_paths()["purelib"]
RMWS = ("rmw_cyclonedds_cpp", "rmw_fastrtps_cpp")
EXECUTABLES = ("ambiegen", "generator", "recorder", "replay", "robot_sim", "car_sim", "thermostat_sim",
               "sut_adapter", "external_sim", "robot_world", "nd_driver")
# variables of a sourced ROS environment: never leak them into venv-side processes
ROS_VARS = ("PYTHONPATH", "AMENT_PREFIX_PATH", "CMAKE_PREFIX_PATH", "COLCON_PREFIX_PATH", "LD_LIBRARY_PATH",
            "ROS_DISTRO", "ROS_VERSION", "ROS_PYTHON_VERSION", "RMW_IMPLEMENTATION", "ROS_LOCALHOST_ONLY",
            "AMBIEGEN_TRANSPORT", "ROS_DOMAIN_ID", "ROS_AUTOMATIC_DISCOVERY_RANGE", "ROS_STATIC_PEERS")

PROBE = f"""
import json, sys
import rclpy
from ament_index_python.packages import get_packages_with_prefixes
pkgs = get_packages_with_prefixes()
print(json.dumps({{"rclpy": rclpy.__file__, "python": list(sys.version_info[:2]), "executable": sys.executable,
                  "distro": __import__("os").environ.get("ROS_DISTRO", ""),
                  "packages": sorted(p for p in pkgs if p.startswith(("rmw_", "nav2_", "dwb_", "opennav_", "rosbag2_storage_mcap", "ros2bag", "sros2")))}}))
"""


def setup_path() -> Path:
    return Path(os.environ.get(SETUP_VAR) or DEFAULT_SETUP)


@functools.lru_cache(maxsize=1)
def probe() -> dict[str, Any]:
    """What the install offers, or {'skip': reason}. Run once per session."""
    setup = setup_path()
    where = f"{SETUP_VAR}={os.environ[SETUP_VAR]}" if os.environ.get(SETUP_VAR) else f"default {DEFAULT_SETUP}"
    if not setup.is_file():
        return {"skip": f"no ROS 2 Jazzy: {setup} does not exist ({where})"}
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    try:
        # the ROS python is the interpreter of the install's own `ros2` script (not whatever
        # `python3` comes first on PATH, e.g. a pyenv shim without the install's build tools)
        run = subprocess.run(["bash", "-c", f"source {shlex.quote(str(setup))} && "
                              'py=$(sed -n "1s/^#! *//p" "$(command -v ros2)") && '
                              f"exec $py -c {shlex.quote(PROBE)}"],
                             env=env, capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        return {"skip": f"sourcing {setup} and importing rclpy took over 120 s"}
    if run.returncode != 0:
        return {"skip": f"import rclpy fails under {setup}: {run.stderr.strip().splitlines()[-1:]}"}
    info = json.loads(run.stdout.strip().splitlines()[-1])
    if tuple(info["python"]) != sys.version_info[:2]:
        return {"skip": f"ROS python is {info['python']}, the venv's is {list(sys.version_info[:2])}: "
                        "the venv's packages cannot be put on its path"}
    info["setup"] = setup
    return info


def require(jazzy: dict[str, Any], *packages: str) -> None:
    """Skip, naming them, when the install lacks packages a test needs (e.g. Fast DDS, rosbag2)."""
    missing = [p for p in packages if p not in jazzy["packages"]]
    if missing:
        pytest.skip(f"{', '.join(missing)} not built in the install sourced by {jazzy['setup']}")


# --- commands ------------------------------------------------------------------------------------
def ros_env(domain: int | None = None, rmw: str = "rmw_cyclonedds_cpp", **extra: str) -> dict[str, str]:
    """Environment of a ROS-side process (before sourcing)."""
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    env.update(PYTHONUNBUFFERED="1", AMBIEGEN_TRANSPORT="rclpy", RMW_IMPLEMENTATION=rmw,
               ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", MPLBACKEND="Agg", AMBIEGEN_VENV_SITE=VENV_SITE)
    if domain is not None:
        env["ROS_DOMAIN_ID"] = str(domain)
    env.update(extra)
    return env


def venv_env(domain: int, **extra: str) -> dict[str, str]:
    """Environment of a venv-side process: the DDS backend (PyPI cyclonedds), no ROS variables."""
    env = {k: v for k, v in os.environ.items() if k not in ROS_VARS}
    env.update(PYTHONUNBUFFERED="1", AMBIEGEN_TRANSPORT="dds", ROS_DOMAIN_ID=str(domain),
               ROS_AUTOMATIC_DISCOVERY_RANGE="SUBNET", MPLBACKEND="Agg")
    env.update(extra)
    return env


def ros_command(command: str, install: Path | None = None, venv: bool = True) -> list[str]:
    """``bash -c`` that sources the install (and the workspace overlay), then execs ``command``."""
    setup = probe()["setup"]
    parts = [f"source {shlex.quote(str(setup))}"]
    if install is not None:
        parts.append(f"source {shlex.quote(str(install / 'setup.bash'))}")
    if venv:
        parts.append('export PYTHONPATH="${PYTHONPATH:+$PYTHONPATH:}$AMBIEGEN_VENV_SITE"')
    return ["bash", "-c", " && ".join(parts + [f"exec {command}"])]


def ros_run(command: str, install: Path | None = None, env: dict[str, str] | None = None, timeout: float = 120,
            venv: bool = True, cwd: Path | None = None) -> subprocess.CompletedProcess:
    try:
        return subprocess.run(ros_command(command, install, venv), env=env or ros_env(), cwd=cwd,
                              capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as exc:
        pytest.fail(f"`{command}` still running after {timeout} s\n{(exc.stdout or b'')[-3000:]!r}")


def ros_args(node: str | None = None, **params: Any) -> str:
    """``--ros-args [-r __node:=NODE] -p k:=v ...`` as one shell string."""
    out = ["--ros-args"] + (["-r", f"__node:={node}"] if node else [])
    for key, value in params.items():
        value = ("true" if value else "false") if isinstance(value, bool) else value
        out += ["-p", shlex.quote(f"{key}:={value}")]
    return " ".join(out)


class Graph:
    """Processes of one test, each in its own session (``ros2 run`` forwards nothing: SIGINT goes
    to the whole process group), logs in one folder; whatever still runs at teardown is killed."""

    def __init__(self, log_dir: Path):
        self.log_dir = log_dir
        self.procs: dict[str, subprocess.Popen] = {}

    def start(self, name: str, args: list[str], env: dict[str, str], cwd: Path = REPO) -> subprocess.Popen:
        self.log_dir.mkdir(parents=True, exist_ok=True)
        with open(self.log_dir / f"{name}.log", "wb") as log:
            self.procs[name] = subprocess.Popen(args, env=env, cwd=cwd, stdout=log, stderr=subprocess.STDOUT,
                                                start_new_session=True)
        return self.procs[name]

    def ros(self, name: str, command: str, install: Path, env: dict[str, str]) -> subprocess.Popen:
        return self.start(name, ros_command(command, install), env)

    def venv(self, name: str, module: str, params: dict[str, Any], env: dict[str, str]) -> subprocess.Popen:
        """A node of this repo on the venv's python (DDS backend when ``env`` is ``venv_env``)."""
        return self.start(name, [sys.executable, "-m", module, *shlex.split(ros_args(name, **params))], env)

    def log(self, name: str) -> str:
        path = self.log_dir / f"{name}.log"
        return path.read_text(errors="replace") if path.exists() else ""

    def logs(self, tail: int = 2500) -> str:
        return "\n".join(f"--- {n} (exit {p.poll()})\n{self.log(n)[-tail:]}" for n, p in self.procs.items())

    def wait(self, name: str, timeout: float) -> int:
        try:
            return self.procs[name].wait(timeout)
        except subprocess.TimeoutExpired:
            pytest.fail(f"{name} still running after {timeout} s\n{self.logs()}")

    def wait_for(self, name: str, text: str, timeout: float) -> None:
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            if text in self.log(name):
                return
            if self.procs[name].poll() is not None:
                pytest.fail(f"{name} exited ({self.procs[name].returncode}) before printing {text!r}\n{self.logs()}")
            time.sleep(0.2)
        pytest.fail(f"{name} did not print {text!r} within {timeout} s\n{self.logs()}")

    def stop(self, name: str, timeout: float = 20.0) -> int:
        proc = self.procs[name]
        if proc.poll() is None:
            os.killpg(proc.pid, signal.SIGINT)
            try:
                proc.wait(timeout)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                proc.wait()
                pytest.fail(f"{name} ignored SIGINT for {timeout} s\n{self.logs()}")
        return proc.returncode

    def cleanup(self) -> None:
        for proc in self.procs.values():
            if proc.poll() is None:
                try:
                    os.killpg(proc.pid, signal.SIGKILL)
                except ProcessLookupError:
                    pass
                proc.wait()


# --- the workspace -------------------------------------------------------------------------------
def colcon_build(src: Path, out: Path, timeout: float = 600) -> tuple[Path, subprocess.CompletedProcess, float]:
    """``colcon build`` of ambiegen_ros + ambiegen_msgs in ``src`` (no venv on the path)."""
    if shutil.which("colcon") is None:
        pytest.skip("colcon is not installed (apt install python3-colcon-common-extensions)")
    install = out / "install"
    cmd = (f"colcon build --paths {shlex.quote(str(src))} {shlex.quote(str(src / 'ambiegen_msgs'))} "
           f"--build-base {shlex.quote(str(out / 'build'))} --install-base {shlex.quote(str(install))} --merge-install "
           f"--event-handlers console_direct- --cmake-args -DBUILD_TESTING=OFF "
           f"-DPython3_EXECUTABLE={shlex.quote(probe()['executable'])}")
    t0 = time.monotonic()
    run = ros_run(cmd, env=ros_env(), timeout=timeout, venv=False, cwd=out)
    return install, run, time.monotonic() - t0


def copy_working_tree(dest: Path) -> Path:
    """The working tree as it is now (tracked and untracked files, minus what .gitignore names)."""
    files = subprocess.run(["git", "ls-files", "-z", "-co", "--exclude-standard"], cwd=REPO, check=True,
                           capture_output=True).stdout.decode().split("\0")
    for rel in filter(None, files):
        src = REPO / rel
        if src.is_file():
            (dest / rel).parent.mkdir(parents=True, exist_ok=True)
            shutil.copy2(src, dest / rel)
    return dest


def working_tree_install(root: Path) -> Path:
    """The working tree copied to ``root`` and built there with colcon; its install dir (the test
    fails, showing colcon's output, when the build does)."""
    src = copy_working_tree(root / "src" / "ambiegen")
    install, run, took = colcon_build(src, root)
    if run.returncode != 0:
        pytest.fail(f"colcon build of the working tree failed ({took:.0f} s):\n{run.stdout[-3000:]}\n{run.stderr[-3000:]}")
    return install
