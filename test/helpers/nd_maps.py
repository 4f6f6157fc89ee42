"""Robot maps on which our ND robot fails, for tests and ``bench/nd_stack.py`` (one draw, one place).

Refined maps of a seeded draw that the problem calls valid and whose reference passes (a
clearance route exists), so every failure on them is the robot's; with ``safety_dist`` 0.3 m the
ND robot fails on most of them (the paper's 0 passes nearly every such map).
"""
from __future__ import annotations

import os
import subprocess
import sys
from contextlib import contextmanager

import numpy as np

FAILING_SAFETY_DIST = 0.3


def certified_maps(problem, full, count: int, seed: int = 11) -> list:
    """The first ``count`` maps of a seeded draw that are valid and pass the reference check."""
    from ambiegen_ros.sims import reference

    rng = np.random.default_rng(seed)
    maps = []
    while len(maps) < count:
        sc = problem.codec.from_rows(problem.sample_rows(1, rng))[0]
        if full.validity(sc)[0] and reference.before(problem, sc, full.config).passed:
            maps.append(sc)
    return maps


@contextmanager
def busy_loops(count: int):
    """``count`` processes spinning at full speed beside the test: a loaded machine, on purpose."""
    env = dict(os.environ, OMP_NUM_THREADS="1")
    procs = [subprocess.Popen([sys.executable, "-c", "while True: pass"], env=env) for _ in range(count)]
    try:
        yield procs
    finally:
        for proc in procs:
            proc.kill()
            proc.wait()
