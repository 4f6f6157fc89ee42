"""Shrinking a failing scenario (issue 68): ddmin, the map's parts, cleared cells and the feed's
steps, without ROS. The feed is driven here by a pure judge of the map it is given (a stand-in for
the stack: which cells a failure needs is known, so the minimal map can be checked exactly); the
same feed on a real runner and a planner stack over DDS is test/ros/test_shrink_planner.py.
"""
from __future__ import annotations

import json
import random
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from ambiegen_ros.core.attributes import ScenarioError
from ambiegen_ros.core.shrink import Ddmin, chunks
from ambiegen_ros.problems.robot.problem import CLEARED
from ambiegen_ros.run_config import make_run
from ambiegen_ros.sims.outcome import Outcome
from ambiegen_ros.trials.shrink import ShrinkFeed, signature
from ambiegen_ros.trials.suite import Entry, scenario_key

REPO = Path(__file__).resolve().parents[1]
CONFIG = str(REPO / "config" / "robot_planner.yaml")
FINDING = REPO / "docs" / "results" / "nav2" / "planner_bugs" / "smac_checker_round" / "smac_checker_round_suite.json"


def run_ddmin(parts, fails):
    d = Ddmin(parts)
    while (kept := d.ask()) is not None:
        assert d.ask() is kept  # asking twice asks the same
        d.tell(fails(set(kept)))
    return d


def test_chunks_cover_the_items_in_order_with_sizes_one_apart():
    for n_items in range(0, 12):
        for n in range(1, 14):
            parts = chunks(list(range(n_items)), n)
            assert sum(parts, []) == list(range(n_items))
            sizes = [len(p) for p in parts]
            assert max(sizes, default=0) - min(sizes, default=0) <= 1


def test_ddmin_finds_exactly_the_parts_a_monotone_failure_needs():
    rng = random.Random(7)
    for _ in range(300):
        n = rng.randint(0, 70)
        need = set(rng.sample(range(n), min(n, rng.randint(0, 5))))
        d = run_ddmin(list(range(n)), lambda kept: need <= kept)
        assert set(d.current) == need


def test_ddmin_result_is_one_minimal_for_a_failure_with_alternatives():
    # fails when {0, 1} or {5} is present: the result must fail, and lose it without any one part
    fails = lambda kept: {0, 1} <= kept or 5 in kept  # noqa: E731
    d = run_ddmin(list(range(10)), fails)
    assert fails(set(d.current))
    assert all(not fails(set(d.current) - {p}) for p in d.current)


def test_ddmin_tell_without_ask_is_an_error():
    with pytest.raises(RuntimeError):
        Ddmin([1, 2]).tell(True)


@pytest.fixture(scope="module")
def problem():
    return make_run("robot", CONFIG, seed=0)[0]


@pytest.fixture(scope="module")
def finding():
    return json.loads(FINDING.read_text())["suite"][0]["scenario"]


def test_cleared_cells_free_the_map_and_bad_ones_are_one_line(problem, finding):
    base = problem.environment(problem.parse(finding)).grid
    ys, xs = np.nonzero(base)
    pick = [[int(xs[i]), int(ys[i])] for i in (0, 7, len(xs) - 1)]
    shrunk = problem.environment(problem.parse({**finding, "metadata": {CLEARED: pick}})).grid
    assert base.sum() - shrunk.sum() == 3 and not any(shrunk[y, x] for x, y in pick)
    for bad in ([1, 2, 3], [[1, 2, 3]], [[0.5, 1]], [[50, 1]], [[-1, 0]], "x", [[float("nan"), 1]]):
        with pytest.raises(ScenarioError, match=f"metadata.{CLEARED}"):
            problem.parse({**finding, "metadata": {CLEARED: bad}})
    assert problem.parse({**finding, "metadata": {CLEARED: []}})


def test_the_map_parts_are_the_walls_and_border_sides_and_make_up_the_map(problem, finding):
    scenario = problem.parse(finding)
    parts = problem.map_parts(scenario)
    grid = problem.environment(scenario).grid
    union = np.zeros_like(grid)
    for _, cells in parts:
        union[cells[:, 1], cells[:, 0]] = True
    assert (union == grid).all()
    names = [n for n, _ in parts]
    assert names[-4:] == ["border south", "border north", "border west", "border east"]
    assert all(n.startswith("wall ") for n in names[:-4]) and len(names) > 20
    # a cleared cell is in no part
    x, y = parts[0][1][0]
    again = problem.map_parts(problem.parse({**finding, "metadata": {CLEARED: [[int(x), int(y)]]}}))
    assert all(not ((cells[:, 0] == x) & (cells[:, 1] == y)).any() for _, cells in again)


def judge(problem, needed: set, kind: str = "collision", flaky_every: int = 0):
    """A stand-in for a stack: the map fails with ``kind`` when it holds every ``needed`` cell; with
    ``flaky_every`` k, only every k-th such run fails (a failure that comes and goes)."""
    count = {"n": 0}

    def run(scenario: dict) -> Outcome:
        grid = problem.environment(problem.parse(scenario)).grid
        if all(grid[y, x] for x, y in needed):
            count["n"] += 1
            if not flaky_every or count["n"] % flaky_every == 0:
                return Outcome({}, True, kind if kind != "tight_turn" else "requirement", "stand-in",
                               metrics={"plan_oracle": kind})
        return Outcome({}, False)
    return run


def drive(feed: ShrinkFeed, run) -> int:
    """The runner's part: every entry the feed gives, run and told, until it gives none."""
    runs = 0
    while entries := feed.more():
        for entry in entries:
            runs += 1
            feed.took(entry, run(entry.scenario))
    return runs


def entry_of(scenario: dict) -> Entry:
    return Entry(name="f", scenario=scenario, key=scenario_key(scenario))


def test_the_feed_shrinks_a_map_to_the_cells_its_failure_needs(problem, finding):
    grid = problem.environment(problem.parse(finding)).grid
    ys, xs = np.nonzero(grid[1:-1, 1:-1])
    needed = {(int(xs[3]) + 1, int(ys[3]) + 1), (int(xs[-2]) + 1, int(ys[-2]) + 1), (0, 10)}  # two wall cells, one border
    said: list[str] = []
    feed = ShrinkFeed(problem, entry_of(finding), {}, 1, said.append)
    runs = drive(feed, judge(problem, needed))
    assert feed.step == "done" and feed.signature == ("collision", "collision")
    shrunk = problem.environment(problem.parse(feed.minimal)).grid
    assert {(int(x), int(y)) for y, x in zip(*np.nonzero(shrunk))} == needed
    assert feed.minimal["elements"] == finding["elements"]  # the genome stays
    assert runs == feed.count < 250 and any("parts:" in s for s in said) and any("cells:" in s for s in said)


def test_a_different_failure_does_not_count_and_a_scenario_that_passes_is_not_shrunk(problem, finding):
    needed = {(0, 0)}
    other = judge(problem, set(), kind="tight_turn")  # every map fails, but by its turns
    first = judge(problem, needed)

    def mixed(scenario):  # the scenario itself collides; without (0, 0) it fails otherwise
        out = first(scenario)
        return out if out.failed else other(scenario)
    feed = ShrinkFeed(problem, entry_of(finding), {}, 1, lambda s: None)
    drive(feed, mixed)
    shrunk = problem.environment(problem.parse(feed.minimal)).grid
    assert shrunk[0, 0] and shrunk.sum() == 1
    said: list[str] = []
    feed = ShrinkFeed(problem, entry_of(finding), {}, 3, said.append)
    assert drive(feed, lambda s: Outcome({}, False)) == 3  # tried 3 times, then nothing to shrink
    assert feed.minimal is None and feed.step == "done" and "nothing to shrink" in said[-1]


def test_tries_catch_a_failure_that_comes_and_goes(problem, finding):
    needed = {(0, 0), (49, 49)}
    feed = ShrinkFeed(problem, entry_of(finding), {}, 2, lambda s: None)
    drive(feed, judge(problem, needed, flaky_every=2))  # fails on every second run that holds both
    shrunk = problem.environment(problem.parse(feed.minimal)).grid
    assert shrunk[0, 0] and shrunk[49, 49] and shrunk.sum() == 2


def test_signature_is_the_kind_and_the_oracle():
    assert signature(Outcome({}, False)) is None
    assert signature(Outcome({}, True, "sut_crashed", "x")) == ("sut_crashed", "")
    assert signature(Outcome({}, True, "requirement", "x", metrics={"plan_oracle": "tight_turn"})) == \
        ("requirement", "tight_turn")


def cli(*args: str, cwd: Path) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ambiegen_ros.cli", "shrink", *args], cwd=cwd,
                          capture_output=True, text=True, timeout=120)


def test_shrink_bad_input_is_one_line_and_starts_nothing(tmp_path):
    suite = tmp_path / "two.json"
    base = json.loads(FINDING.read_text())["suite"][0]["scenario"]
    other = {**base, "metadata": {CLEARED: [[0, 0]]}}
    suite.write_text(json.dumps({"suite": [{"name": "a", "scenario": base}, {"name": "b", "scenario": other}]}))
    common = ["--stack", "nd", "--config", CONFIG]
    taken = tmp_path / "taken.jsonl"
    taken.write_text("")
    for args, words in (([str(suite), *common, "--results", str(tmp_path / "r.jsonl")], "name one of"),
                        ([str(suite), *common, "--results", str(tmp_path / "r.jsonl"), "--scenario", "zz"],
                         "no scenario called 'zz'"),
                        ([str(suite), *common, "--results", str(taken), "--scenario", "a"], "exists"),
                        ([str(suite), *common, "--results", str(tmp_path / "r.jsonl"), "--tries", "0"], "--tries")):
        proc = cli(*args, cwd=tmp_path)
        assert proc.returncode == 2, proc.stderr
        assert words in proc.stderr and len(proc.stderr.strip().splitlines()) == 1, proc.stderr
    assert not (tmp_path / "r.jsonl").exists() and taken.read_text() == ""
