"""Suite-wide setup: this tree importable, a headless matplotlib, ROS domain ids per test, and workers.

``pytest.ini`` runs the suite on pytest-xdist workers, one test file per worker at a time
(``--dist loadfile``: a module's shared fixtures, such as a recorded campaign, are built once).
``-n auto`` means one worker per core this process may use, at most ``MAX_WORKERS``; ``-n 0`` runs
everything in this process. Part of the suite waits on node subprocesses, and a second worker
uses that time (measured in docs/testing.md: 692 s against 839 s on 2 cores).

``ros_domain`` gives a test a ROS_DOMAIN_ID no other test holds, in this run or in any other
pytest run on the machine at the same time (several checkouts, CI jobs, agents): an id is held
through an exclusive ``flock`` on a file under the temp dir, released when the test ends or its
process dies. Two runs that share an id would see each other's workers and topics.
"""
import fcntl
import os
import sys
import tempfile
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
for _path in (ROOT, ROOT / "test"):  # the package, and test/helpers for every test module
    if str(_path) not in sys.path:
        sys.path.insert(0, str(_path))
os.environ.setdefault("MPLBACKEND", "Agg")

# 0 is every ROS user's default; ids above 101 put DDS ports into Linux's ephemeral range
# (32768+); 72-73 stay fixed in test/ros/test_multihost.py (inside its own network namespaces).
DOMAIN_POOL = [d for d in range(10, 102) if d not in (72, 73)]
LOCK_DIR = Path(tempfile.gettempdir()) / "ambiegen-test-domains"


MAX_WORKERS = 4  # each worker starts its own node subprocesses; more would crowd a shared machine


def pytest_xdist_auto_num_workers(config) -> int:
    """``-n auto``: the cores this process may run on (not the machine's), at most ``MAX_WORKERS``."""
    from ambiegen_ros.experiment.runner import default_jobs  # the experiment harness's own count

    return max(1, min(default_jobs(), MAX_WORKERS))


_used_here: set[int] = set()  # ids this process has had: a DDS domain keeps its settings in-process


class DomainPool:
    """Free ROS domain ids, each held by a lock file until ``release``.

    Ids this process has not used yet come first: Cyclone keeps a domain's settings (e.g. the size
    limit of the first node on it) for the life of the process, so a reused id is not a clean one."""

    def __init__(self) -> None:
        self.held: dict[int, int] = {}  # domain -> lock file descriptor

    def take(self) -> int:
        LOCK_DIR.mkdir(parents=True, exist_ok=True)
        for domain in sorted(DOMAIN_POOL, key=lambda d: d in _used_here):
            if domain in self.held:
                continue
            fd = os.open(LOCK_DIR / f"{domain}.lock", os.O_CREAT | os.O_RDWR, 0o666)
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                os.close(fd)
                continue
            self.held[domain] = fd
            _used_here.add(domain)
            return domain
        raise RuntimeError(f"every ROS domain id in {DOMAIN_POOL[0]}..{DOMAIN_POOL[-1]} is held (locks in {LOCK_DIR})")

    def release(self) -> None:
        for fd in self.held.values():
            os.close(fd)  # closing drops the flock
        self.held.clear()


@pytest.fixture
def domains():
    """A callable giving a new free ROS domain id per call, all held until the test ends."""
    pool = DomainPool()
    yield pool.take
    pool.release()


@pytest.fixture
def ros_domain(domains) -> int:
    """One free ROS domain id for this test (see the module docstring)."""
    return domains()


@pytest.fixture(scope="module")
def module_domains():
    """As ``domains``, held until the module's last test ends (for module-scoped fixtures)."""
    pool = DomainPool()
    yield pool.take
    pool.release()


@pytest.fixture(scope="session")
def session_domains():
    """As ``domains``, held until the session ends (for session-scoped fixtures)."""
    pool = DomainPool()
    yield pool.take
    pool.release()
