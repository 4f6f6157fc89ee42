"""The libraries AmbieGen-ROS needs and the oldest version of each that works: one table.

setup.py builds ``install_requires`` from it, package.xml carries the same minimums as
``version_gte`` (test/test_deps.py checks both), and every node's main and the CLI call
``startup_errors`` first, so a too-old library is one line and exit status 2 at start-up instead
of an AttributeError in the middle of a run (shapely 1.8 has no ``shapely.is_simple``).

Standard library only: setup.py reads this file before anything is installed.
"""
from __future__ import annotations

import re
from dataclasses import dataclass


@dataclass(frozen=True)
class Dependency:
    name: str  # distribution name, as pip knows it
    minimum: str  # oldest version the code works with
    why: str  # what in the code needs that version
    pin: str = ""  # the exact version pip installs (setup.py), when one is pinned for reproducibility
    rosdep: str = ""  # its key in package.xml (apt on a ROS machine); '' = from PyPI only
    optional: str = ""  # what is lost without it ('' = required)

    def requirement(self) -> str:
        """The setup.py line: the pin when there is one, else the minimum."""
        return f"{self.name}=={self.pin}" if self.pin else f"{self.name}>={self.minimum}"


DEPENDENCIES: tuple[Dependency, ...] = (
    Dependency("numpy", "1.24", "no numpy 2 API is used; numba 0.57 pairs with numpy 1.24",
               rosdep="python3-numpy"),
    Dependency("scipy", "1.10", "splprep/splev, csgraph.dijkstra, ndimage, mannwhitneyu", rosdep="python3-scipy"),
    Dependency("shapely", "2.0", "the vectorised shapely 2 functions (is_simple, linestrings, union_all, prepare)",
               rosdep="python3-shapely"),
    Dependency("matplotlib", "3.6", "the pictures of `ambiegen show`", rosdep="python3-matplotlib"),
    Dependency("PyYAML", "6.0", "config and parameter files", rosdep="python3-yaml"),
    Dependency("pymoo", "0.6.1.6", "operator signatures changed inside 0.6.1.x", pin="0.6.1.6"),
    Dependency("mcap", "1.6.0", "the MCAP writer and chunk reader the recorder uses (tested release)", pin="1.6.0"),
    Dependency("rosbags", "0.11.9", "CDR codec, the Jazzy type store and RIHS01 hashes (tested release)",
               pin="0.11.9"),
    Dependency("cyclonedds", "11.0.1", "one exact version for all our processes (wire-level type matching)",
               pin="11.0.1", optional="the DDS transport used when rclpy is not importable"),
    Dependency("numba", "0.57", "njit(cache=True, error_model=...) on Python 3.11", pin="0.68.1",
               optional="speed only: the numpy paths give the same results"),
)


def install_requires() -> list[str]:
    return [dep.requirement() for dep in DEPENDENCIES]


def version_tuple(text: str) -> tuple[int, ...]:
    """The release numbers of a version string ('2.0.1rc1' -> (2, 0, 1)); () when there are none."""
    match = re.match(r"\s*v?(\d+(?:\.\d+)*)", text or "")
    return tuple(int(part) for part in match.group(1).split(".")) if match else ()


def installed_version(name: str) -> str | None:
    """The version of the installed distribution (first on the path, as ``import`` would find it), or None.

    Read as ``importlib.metadata.version`` reads it, from the first ``<name>-*.dist-info/METADATA``
    (or ``.egg-info``) in ``sys.path``'s directories, but without importing ``importlib.metadata``:
    its e-mail parser alone cost every command about 20 ms of start-up (issue 47). What that quick
    reading does not find or cannot read (a zip or an egg on the path, a file without a Version line,
    a distribution not on the path) is asked of ``importlib.metadata`` itself.
    """
    found = _version_on_path(name)
    if found:
        return found
    from importlib import metadata

    try:
        return metadata.version(name)
    except metadata.PackageNotFoundError:
        return None


def _normalized(name: str) -> str:
    return re.sub(r"[-_.]+", "_", name).lower()  # importlib.metadata's Prepared.normalize


def _version_on_path(name: str) -> str | None:
    """The Version line of the first metadata directory of ``name`` in ``sys.path``'s directories;
    None where ``importlib.metadata`` has to decide (see ``installed_version``)."""
    import os
    import sys

    wanted = _normalized(name)
    for root in sys.path:
        try:
            children = os.listdir(root or ".")
        except OSError:
            if os.path.exists(root):
                return None  # a zip file on the path
            continue
        if root.lower().endswith(".egg"):
            return None
        for child in children:
            low = child.lower()
            is_info = low.endswith((".dist-info", ".egg-info"))
            if is_info and _normalized(low.rpartition(".")[0].partition("-")[0]) == wanted:
                path = os.path.join(root or ".", child)
                if not os.path.isfile(path):
                    path = os.path.join(path, "METADATA" if low.endswith(".dist-info") else "PKG-INFO")
                return _header_version(path)
    return None


def _header_version(path: str) -> str | None:
    """The ``Version:`` field of a core-metadata file's header (None: unreadable, or no such field)."""
    try:
        with open(path, encoding="utf-8") as fh:
            for line in fh:
                if not line.strip():
                    return None  # the header ends at the first empty line
                key, _, value = line.partition(":")
                if key.strip().lower() == "version":
                    return value.strip() or None
    except (OSError, UnicodeDecodeError):
        return None
    return None


@dataclass(frozen=True)
class Status:
    dependency: Dependency
    installed: str | None

    @property
    def too_old(self) -> bool:
        return self.installed is not None and version_tuple(self.installed) < version_tuple(self.dependency.minimum)

    @property
    def ok(self) -> bool:
        """Usable, or an optional library that is simply absent."""
        return not self.too_old and (self.installed is not None or bool(self.dependency.optional))

    def problem(self) -> str | None:
        """One line naming the package and the version needed, or None when fine."""
        dep = self.dependency
        if self.too_old:
            return (f"{dep.name} {self.installed} is too old: {dep.minimum} or newer is needed for {dep.why} "
                    f"(pip install '{dep.name}>={dep.minimum}')")
        if self.installed is None and not dep.optional:
            return f"{dep.name} is not installed: {dep.minimum} or newer is needed (pip install '{dep.name}>={dep.minimum}')"
        return None


def statuses() -> list[Status]:
    return [Status(dep, installed_version(dep.name)) for dep in DEPENDENCIES]


def startup_errors() -> list[str]:
    """Every dependency problem, one line each ([] when the environment is fit to run).

    An optional library that is absent is fine; one that is installed but too old is not (it would
    be imported and fail mid-run).
    """
    return [line for line in (s.problem() for s in statuses()) if line]


def broken_environment(label: str) -> bool:
    """Print ``<label>: error: ...`` for each dependency problem on stderr; True when there was one.

    The callers (every node's main, the CLI) then exit with status 2 before doing any work.
    """
    import sys

    errors = startup_errors()
    for line in errors:
        print(f"{label}: error: {line}", file=sys.stderr)
    if errors:
        print(f"{label}: `ambiegen doctor` (or `python -m ambiegen_ros.doctor`) checks the whole environment",
              file=sys.stderr)
    return bool(errors)
