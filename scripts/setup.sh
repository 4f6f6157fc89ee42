#!/usr/bin/env bash
# Sets up a fresh Debian/Ubuntu machine for AmbieGen-ROS without ROS:
#   - Debian packages for the offline .msg check (python3-rosidl) and iproute2 for the multi-host network-namespace tests (skipped when not root / no apt),
#   - a virtual environment in .venv with the package (editable) and its test tools, at the versions
#     pinned in constraints.txt (the ones the suite was last verified with; see that file).
# AMBIEGEN_LATEST=1 ignores constraints.txt and installs the newest releases setup.py allows, to find
# drift on purpose:  AMBIEGEN_LATEST=1 bash scripts/setup.sh && .venv/bin/python -m pytest
# Idempotent: running it again only installs what is missing or not at its pin (an existing .venv is
# kept; a run without AMBIEGEN_LATEST after one with it moves every package back to its pin).
set -euo pipefail
cd "$(dirname "$0")/.."

SUDO=""
if [ "$(id -u)" != "0" ] && command -v sudo >/dev/null 2>&1; then SUDO="sudo"; fi
if command -v apt-get >/dev/null 2>&1 && { [ "$(id -u)" = "0" ] || [ -n "$SUDO" ]; }; then
  need=()
  for pkg in python3-rosidl python3-catkin-pkg python3-empy iproute2; do
    dpkg -s "$pkg" >/dev/null 2>&1 || need+=("$pkg")
  done
  python3 -m venv --help >/dev/null 2>&1 || need+=(python3-venv)
  if [ ${#need[@]} -gt 0 ]; then
    echo "setup: apt-get install ${need[*]}"
    export DEBIAN_FRONTEND=noninteractive
    $SUDO apt-get update -qq
    $SUDO env DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" >/dev/null
  fi
else
  echo "setup: no apt-get (or no root/sudo): skipping python3-rosidl (only test/ros/test_msgs.py needs it)"
fi

PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  "$PY" -m venv .venv
fi
PIP=(.venv/bin/python -m pip install -q --disable-pip-version-check)
LOCK=constraints.txt
rm -f .venv/ambiegen-install  # written again only when the install below succeeds
if [ "${AMBIEGEN_LATEST:-}" = "1" ]; then
  echo "setup: AMBIEGEN_LATEST=1: ignoring $LOCK, installing the newest releases the package metadata allows"
  "${PIP[@]}" --upgrade pip >/dev/null
  "${PIP[@]}" --upgrade --upgrade-strategy eager -e '.[test]'
  echo "latest" > .venv/ambiegen-install  # test/test_deps.py: versions need not match the pins
else
  venv_py=$(.venv/bin/python -c 'import sys; print("%d.%d" % sys.version_info[:2])')
  lock_py=$(sed -n 's/^# verified-python: *//p' "$LOCK")
  if [ "$venv_py" != "$lock_py" ]; then
    echo "setup: warning: $LOCK was verified on Python $lock_py, .venv has Python $venv_py; installing its pins anyway" \
         "(if pip finds no match: rm -rf .venv && PYTHON=python$lock_py bash scripts/setup.sh, or AMBIEGEN_LATEST=1)"
  fi
  echo "setup: installing the versions pinned in $LOCK (AMBIEGEN_LATEST=1 for the newest releases)"
  "${PIP[@]}" -c "$LOCK" pip >/dev/null  # first, so the next step has --build-constraint
  "${PIP[@]}" -c "$LOCK" --build-constraint "$LOCK" -e '.[test]'
  echo "$LOCK" > .venv/ambiegen-install  # test/test_deps.py then checks every pin is what is installed
fi
# numba's cache of robot_world's compiled loops (laser, contact), written once here: on a fresh clone
# every world process of the tests compiled them at once otherwise (10-50 s each on a loaded machine,
# against about 1 s to load the cache). The world warms them before it joins the graph (HostedWorld.warm_up).
.venv/bin/python -c "from ambiegen_ros.sims.hosted_world import HostedWorld
from ambiegen_ros.sims.robot import RobotSimConfig
HostedWorld(RobotSimConfig()).warm_up()" || echo "setup: warning: could not warm the robot world's compiled loops"
echo "setup: ready ($(.venv/bin/python --version), ambiegen $(.venv/bin/ambiegen --version | cut -d' ' -f2))"
