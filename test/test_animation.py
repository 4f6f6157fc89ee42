"""`ambiegen show RUN.mcap --scenario ID -o failure.gif`: a failure you can watch, from a real robot bag.

The bag is recorded once for the module, for real: ``robot_world`` (lockstep), ``nd_driver`` with
the failing setting of ``bench/nd_stack.py`` (``safety_dist`` 0.3 m), ``sut_adapter`` and the
recorder with a stack campaign's topics (``campaign.STACK_TOPICS``), every node a subprocess on
the module's own ROS domain; this test publishes two certified maps on which that robot stalls
after 8 and 25 simulated seconds (a default ``--stack nd`` campaign of a few evaluations finds no
failure to draw). The GIF is then read back with Pillow: frame count and size, a robot that
moves, and the failure marker on the last frame only. Every wait ends on an event; its bound is a
safety net, never the thing tested.
"""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

from ambiegen_ros.campaign import STACK_TOPICS
from ambiegen_ros.problems import get_problem
from ambiegen_ros.sims.full_model import full_model_executor
from nd_maps import FAILING_SAFETY_DIST, certified_maps
from sut_graph import Driver, Procs

REPO = Path(__file__).resolve().parents[1]
LOCKSTEP = {"lockstep": True, "time_scale": 0.0, "scan_rate": 10.0, "sim.dt": 0.1, "cmd_vel_stamped": True,
            "paired_start": True}
MAPS = (1, 2)  # of certified_maps(seed 11): ND with safety_dist 0.3 stalls on both, after 8.1 s and 24.7 s

pytestmark = pytest.mark.skipif(os.environ.get("AMBIEGEN_TRANSPORT", "auto") == "rclpy",
                                reason="the driver node runs on the DDS backend")


def record_robot_bag(out: Path, domain: int, maps: tuple[int, ...] = MAPS) -> Path:
    """A robot bag of ``maps`` driven by the failing ND robot, recorded by the recorder node; its path."""
    from ambiegen_ros.ros.transport import create_node

    problem = get_problem("robot", {"profile": "refined"})
    full = full_model_executor(problem, safety_dist=FAILING_SAFETY_DIST, run_invalid=True)
    drawn = certified_maps(problem, full, max(maps) + 1)
    mcap = out / "robot_bag.mcap"
    procs = Procs(domain, out / "logs")
    with pytest.MonkeyPatch.context() as mp:
        mp.setenv("ROS_DOMAIN_ID", str(domain))
        mp.delenv("AMBIEGEN_TRANSPORT", raising=False)
        node = create_node("animation_test_driver", argv=[])
        try:
            procs.start("recorder", "ambiegen_ros.nodes.recorder", output=str(mcap),
                        extra_topics=",".join(STACK_TOPICS))
            procs.start("world", "sim_nodes.robot_world", **LOCKSTEP)
            procs.start("nd", "sim_nodes.nd_driver", cmd_vel_stamped=True, paired_start=True, **{"sim.safety_dist": FAILING_SAFETY_DIST})
            procs.start("adapter", "sim_nodes.sut_adapter", problem="robot", worker_id="sut", profile="refined",
                        stall_topic="/nd_driver/stall", plan_topic="/plan", settle_time=0.1, run_invalid=True)
            driver = Driver(node, problem)
            driver.wait_matched(count=2)  # the adapter and the recorder
            node.spin_until(lambda: False, 2.5)  # the recorder looks for the robot's topics once a second
            driver.send("anim", [drawn[k] for k in maps])
            got = driver.wait("anim", len(maps), 300)
            assert all(got), procs.logs()
        finally:
            node.shutdown()
            procs.stop_all()  # SIGINT: the recorder writes the MCAP's summary
    assert mcap.exists(), procs.logs()
    return mcap


@pytest.fixture(scope="module")
def bag(tmp_path_factory, module_domains) -> Path:
    return record_robot_bag(tmp_path_factory.mktemp("robot_bag"), module_domains())


def ambiegen(*args: str) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-m", "ambiegen_ros", *args], cwd=REPO, capture_output=True, text=True,
                          timeout=300)


def frames(path: Path) -> list[np.ndarray]:
    with Image.open(path) as gif:
        out = []
        for k in range(gif.n_frames):
            gif.seek(k)
            out.append(np.asarray(gif.convert("RGB"), dtype=np.int16))
    return out


def red_pixels(frame: np.ndarray) -> int:
    """Pixels of the failure marker's colour on the map (the left 70 %; the legend's entry is right of it):
    nothing else in the picture is pure red."""
    r, g, b = (frame[:, : int(frame.shape[1] * 0.7), c] for c in range(3))
    return int(np.count_nonzero((r > 200) & (g < 60) & (b < 60)))


def test_the_bag_holds_both_failures_with_their_streams(bag):
    from ambiegen_ros.ros.robot_bag import read_index, read_run

    index = read_index(bag)
    assert list(index.entries) == [0, 1]
    for sid, entry in index.entries.items():
        assert entry.outcome is not None and entry.outcome.failure_kind == "stall", entry.outcome
        run = read_run(index, sid)
        assert len(run.poses) > 50 and run.scans and run.plans
        assert run.markers == []  # maps without hazards: nothing on /ambiegen/world/markers to draw
        assert np.hypot(*(run.poses[0, 1:3] - run.start)) < 0.5  # at the scenario's start, not the last run's end
        assert np.all(np.diff(run.poses[:, 0]) >= 0)
        assert run.t_verdict is not None and run.t_verdict <= run.poses[-1, 0] + 0.5
    first, second = read_run(index, 0), read_run(index, 1)
    assert first.entry.end_ns <= second.entry.start_ns  # one stretch of the log each


def test_show_animates_a_failure_from_the_bag(bag, tmp_path):
    out = tmp_path / "failure.gif"
    run = ambiegen("show", str(bag), "--scenario", "1", "-o", str(out), "--fps", "5", "--speed", "2")
    assert run.returncode == 0, run.stderr
    assert str(out) in run.stdout and "FAIL(stall)" in run.stdout and "log time" in run.stdout
    shots = frames(out)
    # 24.7 s + the world's last steps, one frame per 0.4 simulated s, and the verdict held at the end
    # (identical frames are merged by the GIF encoder, so the count is a range)
    assert 40 <= len(shots) <= 100, len(shots)
    assert {shot.shape for shot in shots} == {(448, 592, 3)}
    assert np.abs(shots[len(shots) // 2] - shots[0]).sum() > 0  # the robot moves across frames
    assert sum(np.abs(b - a).any() for a, b in zip(shots[1:-2], shots[2:-1])) > len(shots) // 2
    assert red_pixels(shots[-1]) > 50  # the failure marker on the last frame ...
    assert red_pixels(shots[0]) == red_pixels(shots[len(shots) // 2]) == 0  # ... and not before the verdict


def test_show_lists_the_scenarios_of_a_bag_and_asks_for_one(bag):
    run = ambiegen("show", str(bag))
    assert run.returncode == 2
    lines = run.stdout.splitlines()
    assert len(lines) == 2 and all("FAIL(stall)" in line and "log time" in line for line in lines)
    assert run.stderr.count("\n") == 1 and "--scenario ID" in run.stderr


def test_show_refuses_bad_input_in_one_line(bag, tmp_path):
    existing = tmp_path / "taken.gif"
    existing.write_bytes(b"not ours")
    cases = {
        "no scenario 7": ["show", str(bag), "--scenario", "7", "-o", str(tmp_path / "x.gif")],
        "refusing to overwrite": ["show", str(bag), "--scenario", "1", "-o", str(existing)],
        "not a readable MCAP": ["show", str(existing.with_suffix(".mcap")), "--scenario", "0"],
        ".gif or .mp4": ["show", str(bag), "--scenario", "1", "-o", str(tmp_path / "x.png")],
    }
    existing.with_suffix(".mcap").write_bytes(b"no MCAP here")
    for words, args in cases.items():
        run = ambiegen(*args)
        assert run.returncode == 2 and run.stderr.count("\n") == 1 and words in run.stderr, (words, run.stderr)
    assert existing.read_bytes() == b"not ours"
    assert not (tmp_path / "x.gif").exists()


def test_show_says_what_a_bag_lacks(tmp_path):
    """A log without robot scenarios, and a robot run recorded without the robot's topics."""
    from ambiegen_ros.ros import conversions, topics
    from ambiegen_ros.ros.conversions import ScenarioMeta
    from ambiegen_ros.ros.mcap_log import McapLog
    from ambiegen_ros.ros.qos import STREAM
    from ambiegen_ros.ros.types import get_registry

    registry = get_registry()
    problem = get_problem("robot")
    scenario = problem.codec.from_rows(problem.sample_rows(1, np.random.default_rng(0)))[0]
    msg = conversions.scenario_message(registry.new, 1, problem, scenario, ScenarioMeta("run", 0))
    with McapLog(tmp_path / "empty.mcap") as log:
        log.add_channel(topics.STATUS, topics.STATUS_TYPE, STREAM)
    with McapLog(tmp_path / "no_odom.mcap") as log:
        channel = log.add_channel(topics.scenarios("robot"), topics.SCENARIO_TYPES["robot"], STREAM)
        log.write(channel, registry.serialize(msg, topics.SCENARIO_TYPES["robot"]), 1)
    for name, words in (("empty", "not a robot bag"), ("no_odom", "no /odom in the bag")):
        run = ambiegen("show", str(tmp_path / f"{name}.mcap"), "--scenario", "0", "-o", str(tmp_path / f"{name}.gif"))
        assert run.returncode == 2 and run.stderr.count("\n") == 1 and words in run.stderr, (name, run.stderr)


def test_the_foxglove_layout_shows_a_robot_bags_topics():
    """config/foxglove/robot_bag_layout.json: a layout as Foxglove exports it (panels by id, a split
    tree of those ids) whose 3D panel shows the recorded robot topics in the map frame, the world's
    unmapped obstacles and people (issue 48) among them."""
    import json

    layout = json.loads((REPO / "config" / "foxglove" / "robot_bag_layout.json").read_text())
    panels = layout["configById"]

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node["first"]) + leaves(node["second"])

    assert sorted(leaves(layout["layout"])) == sorted(panels)
    (three_d,) = [cfg for name, cfg in panels.items() if name.startswith("3D!")]
    assert three_d["followTf"] == "map"
    shown = {topic for topic, cfg in three_d["topics"].items() if cfg["visible"]}
    assert {"/map", "/scan", "/plan", "/odom", "/ambiegen/world/markers"} <= shown <= set(STACK_TOPICS)
    paths = [cfg.get("topicPath", "") for cfg in panels.values()]
    paths += [p["value"] for cfg in panels.values() for p in cfg.get("paths", [])]
    assert any(path.startswith("/ambiegen/results") for path in paths)
    assert "scenario_id" in layout["globalVariables"]


def as_batch(bag: Path, out: Path) -> Path:
    """The real bag rewritten as a ``bench/nav2_maps.py`` batch logs one: every scenario its own run
    (``batch-<id>``) as scenario 0; every other message copied byte for byte."""
    from mcap.reader import make_reader
    from mcap.writer import Writer

    from ambiegen_ros.ros import topics
    from ambiegen_ros.ros.types import get_registry

    registry = get_registry()
    renamed = {topics.scenarios("robot"), topics.RESULTS}
    with open(bag, "rb") as src, open(out, "wb") as dst:
        writer = Writer(dst)
        writer.start()
        schemas: dict[int, int] = {}
        channels: dict[int, int] = {}
        for schema, channel, message in make_reader(src).iter_messages(log_time_order=True):
            if schema.id not in schemas:
                schemas[schema.id] = writer.register_schema(schema.name, schema.encoding, schema.data)
            if channel.id not in channels:
                channels[channel.id] = writer.register_channel(channel.topic, channel.message_encoding,
                                                               schemas[schema.id], dict(channel.metadata))
            data = message.data
            if channel.topic in renamed:
                msg = registry.deserialize(data, schema.name)
                meta = msg.meta if channel.topic != topics.RESULTS else msg
                meta.run_id, meta.scenario_id = f"batch-{int(meta.scenario_id)}", 0
                data = registry.serialize(msg, schema.name)
            writer.add_message(channels[channel.id], message.log_time, data, message.publish_time)
        writer.finish()
    return out


def test_a_bag_of_several_runs_is_read_run_by_run(bag, tmp_path):
    """A batch bag (a run per map, each map its scenario 0): every run indexed with its own stretch
    of the log, listed with its run id, picked with --run; an id that several runs hold is refused."""
    from ambiegen_ros.ros.robot_bag import read_index, read_run

    batch = as_batch(bag, tmp_path / "batch.mcap")
    index = read_index(batch)
    assert list(index.runs) == ["batch-0", "batch-1"] and index.run_id == "batch-0"
    whole = read_index(bag)
    for k in (0, 1):
        shown = index.select(f"batch-{k}")
        assert list(shown.entries) == [0]
        entry, original = shown.entries[0], whole.entries[k]
        assert (entry.start_ns, entry.end_ns, entry.outcome.failure_kind) == \
            (original.start_ns, original.end_ns, original.outcome.failure_kind)
        assert np.array_equal(read_run(shown, 0).poses, read_run(whole, k).poses)
    assert read_index(batch, "batch-1").entries[0].end_ns == whole.entries[1].end_ns

    listed = ambiegen("show", str(batch))
    lines = listed.stdout.splitlines()
    assert listed.returncode == 2 and [line.split()[:2] for line in lines] == [["batch-0", "0"], ["batch-1", "0"]]
    assert listed.stderr.count("\n") == 1 and "2 runs" in listed.stderr and "--run RUN" in listed.stderr
    for args, words in ((["--scenario", "0"], "is in 2 runs"), (["--run", "nope", "--scenario", "0"], "no run 'nope'")):
        refused = ambiegen("show", str(batch), *args, "-o", str(tmp_path / "x.gif"))
        assert refused.returncode == 2 and refused.stderr.count("\n") == 1 and words in refused.stderr, refused.stderr
    assert not (tmp_path / "x.gif").exists()
    drawn = ambiegen("show", str(batch), "--run", "batch-1", "--scenario", "0", "--fps", "2", "--speed", "4")
    out = tmp_path / "batch_batch-1_scenario_0.gif"  # the default name says which run
    assert drawn.returncode == 0 and str(out) in drawn.stdout and "FAIL(stall)" in drawn.stdout, drawn.stderr
    assert red_pixels(frames(out)[-1]) > 50


def test_near_miss_bench_reads_every_run_of_a_batch_bag(bag, tmp_path, monkeypatch):
    """``bench/nav2_near_misses.py`` on a batch bag: a row per map, each naming its run."""
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    from nav2_near_misses import bag_rows

    rows = bag_rows(as_batch(bag, tmp_path / "batch.mcap"))
    assert [(r["run"], r["scenario"], r["failed"]) for r in rows] == [("batch-0", 0, True), ("batch-1", 0, True)]
    assert "run" not in bag_rows(bag)[0]  # one run: rows as before


def test_near_miss_comparison_counts_each_bag_once(monkeypatch):
    """``--compare``: stalls per map of one label against another; a bag read twice counts once."""
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    from nav2_near_misses import compare

    def row(label, bag, stalls, maps, turned=0):
        return {"label": label, "bag": bag, "maps": [
            {"stalled": k < stalls, "arrival_turn_deg": 150.0 if k < turned else None} for k in range(maps)]}

    rows = [row("search", "s1.mcap", 1, 10), row("search", "s1.mcap", 6, 10, turned=7),  # read again: newest wins
            row("search", "s2.mcap", 4, 10), row("random", "r1.mcap", 0, 20), row("random", "r2.mcap", 1, 20)]
    result = compare(rows, "search", "random")
    assert result["search"] == {"bags": 2, "maps": 20, "stalls": 10, "stalls_per_bag": [6, 4], "arrival_turn_over_100": 7}
    assert result["random"]["stalls"] == 1 and result["random"]["maps"] == 40
    assert result["fisher_p_greater"] < 0.001  # 10 of 20 against 1 of 40
    assert compare(rows, "random", "search")["fisher_p_greater"] > 0.99
    with pytest.raises(SystemExit, match="no rows labelled 'nope'"):
        compare(rows, "search", "nope")


def test_closest_call_with_a_person_is_measured_while_the_robot_drives(monkeypatch):
    """``person_gap``: people placed from 1 Hz markers at 50 Hz poses give the gap a dense, exact
    placement gives; a person who walks into the robot once it stands is not its closest call."""
    from types import SimpleNamespace

    from ambiegen_ros.sims.obstacles import Obstacles
    from ambiegen_ros.sims.robot_world import PIONEER2DX

    monkeypatch.syspath_prepend(str(REPO / "bench"))
    from nav2_near_misses import person_gap

    t = np.arange(0.0, 20.0 + 1e-9, 0.02)
    x = np.minimum(0.5 * t, 8.0)  # drives along y = 0 at 0.5 m/s, stands at x = 8 from t = 16
    poses = np.column_stack([t, x, np.zeros_like(t), np.zeros_like(t)])

    def people(at):  # a walker crossing towards the route, and one who walks into the standing robot
        crossing = (5.0, 2.8 - 0.2 * at, 0.3)
        late = (8.0, 2.2 - 0.5 * max(at - 16.0, 0.0), 0.3)  # 0.2 m from the body's side at t = 20
        return np.array([crossing, late])

    markers = [(float(s), {"people": people(float(s))}) for s in range(21)]
    run = SimpleNamespace(poses=poses, markers=markers)
    got = person_gap(run)
    driving = t < 16.0
    dense = [Obstacles(posts=people(a)[:1]).body_clearance(b, 0.0, 0.0, PIONEER2DX, 0.0)[0]
             for a, b in zip(t[driving], x[driving])]
    k = int(np.argmin(dense))
    assert got["person_gap_m"] == pytest.approx(dense[k], abs=2e-3) and 0.0 < got["person_gap_m"] < 0.6
    assert got["person_gap_t"] == pytest.approx(t[k], abs=0.05) and got["robot_speed_mps"] == pytest.approx(0.5)
    assert Obstacles(posts=people(20.0)[1:]).body_clearance(8.0, 0.0, 0.0, PIONEER2DX, 0.0)[0] < got["person_gap_m"]
    assert person_gap(SimpleNamespace(poses=poses, markers=[(0.0, {"people": np.zeros((0, 3))})])) is None


def test_nav2_search_report_tests_each_side_against_random_from_three_runs(tmp_path, monkeypatch, capsys):
    """``bench/nav2_search.py --report``: the exact one-sided test from 3 runs a side, marked a hint
    under 10, on distinct new failures and on near misses (where every run recorded them); a side
    with fewer runs gets no test."""
    monkeypatch.syspath_prepend(str(REPO / "bench"))
    import nav2_search

    def row(controller, algorithm, distinct):
        return {"controller": controller, "algorithm": algorithm, "mode": "in_the_loop", "config": "c.yaml",
                "nav2_hours": 1.0, "distinct_new_failures": distinct, "known_failures": 0}

    rows = [row("dwb", "random", 0) for _ in range(3)] + [row("dwb", "nsga2", d) for d in (2, 1, 2)]
    for r, misses in zip(rows, (4, 5, 6, 9, 7, 8)):
        r["near_misses"] = misses
    rows += [row("mppi", "random", 0), row("mppi", "random", 0), row("mppi", "nsga2", 3), row("mppi", "nsga2", 3)]
    # runs on hazards scenarios are compared with random hazards runs only (bench/nav2_search.scenario_space)
    hazards = [{**row("mppi", "random", 0), "config": "config/robot_hazards.yaml"} for _ in range(3)]
    hazards += [{**row("mppi", "nsga2", d), "config": "config/robot_hazards_threat.yaml"} for d in (1, 2, 3)]
    hazards[-1]["nav2_hours"] = 0.5  # a run whose hour of sending held half a Nav2 hour
    rows += hazards
    # another robot's runs (issue 69) are a side of their own: never compared with the Pioneer's
    rows += [{**row("mppi", "nsga2", 0), "config": "config/robot_hazards_threat.yaml", "robot": "turtlebot4"}
             for _ in range(3)]
    monkeypatch.setattr(nav2_search, "OUT", tmp_path / "nav2_search.jsonl")
    nav2_search.OUT.write_text("".join(json.dumps(r) + "\n" for r in rows))
    assert nav2_search.report() == 0
    out = capsys.readouterr().out
    dwb, rest = out.split("## mppi, pioneer2dx, hazards scenarios")
    hazards_part, rest = rest.split("## mppi, pioneer2dx, walls scenarios")
    mppi, tb4 = rest.split("## mppi, turtlebot4, hazards scenarios")
    assert "nsga2 (in_the_loop, config/robot_hazards_threat.yaml): 3 runs" in tb4 and "> random" not in tb4
    assert ("nsga2 (in_the_loop, c.yaml) > random in distinct new failures, 3 against 3 runs: one-sided Mann-Whitney "
            "U = 9, exact p = 0.050") in dwb
    assert "> random in near misses, 3 against 3 runs: one-sided Mann-Whitney U = 9, exact p = 0.050" in dwb
    assert "random in near misses" not in hazards_part  # not recorded there: no test
    assert "(a hint: under 10 runs a side)" in dwb
    assert "> random" not in mppi  # 2 runs a side: no test
    assert ("config/robot_hazards_threat.yaml) > random in distinct new failures, 3 against 3 runs: one-sided "
            "Mann-Whitney U = 9") in hazards_part
    assert "distinct new failures [1, 2, 3] (per Nav2 hour [1.0, 2.0, 6.0])" in hazards_part
    assert "1 under one Nav2 hour" in hazards_part and "under one Nav2 hour" not in dwb
