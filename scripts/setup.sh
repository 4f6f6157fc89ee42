#!/usr/bin/env bash
# Sets up a fresh Debian/Ubuntu machine for AmbieGen-ROS without ROS:
#   - Debian packages for the offline .msg check (python3-rosidl) and iproute2 for the multi-host network-namespace tests (skipped when not root / no apt),
#   - a virtual environment in .venv with the package (editable) and its test tools.
# Idempotent: running it again only installs what is missing.
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
.venv/bin/python -m pip install -q --disable-pip-version-check --upgrade pip >/dev/null
.venv/bin/python -m pip install -q --disable-pip-version-check -e '.[test]'
echo "setup: ready ($(.venv/bin/python --version), ambiegen $(.venv/bin/ambiegen --version | cut -d' ' -f2))"
