"""How fast do the real nodes go over DDS? (thermostat sim, Cyclone DDS backend unless told otherwise)

(a) Round trips scenario -> ``thermostat_sim`` -> result, with the real sim node in its own
    process: this process publishes ``ThermostatScenario`` messages (built with ``conversions``
    like the generator does) and keeps N of them in flight, sending the next as soon as a result
    comes back. Reports round trips/s and p50/p99 latency (publish -> result received) per N, and
    checks that every scenario got exactly one result.
(b) An ``in_the_loop`` campaign (generator + sim workers + recorder as subprocesses): scenarios/s
    end to end, from the first scenario to the last result in the MCAP log.
(c) What a campaign costs over the in-process search: ``ambiegen search`` vs ``ambiegen campaign``
    wall time with the same settings (surrogate mode).

    .venv/bin/python bench/campaign.py [--quick] [--domain 71] [--no-write]
"""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.ros import conversions, topics  # noqa: E402
from ambiegen_ros.ros.conversions import ScenarioMeta  # noqa: E402
from ambiegen_ros.ros.qos import STREAM  # noqa: E402
from ambiegen_ros.ros.transport import create_node  # noqa: E402

PROBLEM = "thermostat"
AMBIEGEN = [sys.executable, "-m", "ambiegen_ros"]


def _env(domain: int) -> dict[str, str]:
    return dict(os.environ, ROS_DOMAIN_ID=str(domain), PYTHONUNBUFFERED="1")


def _pct(values: list[float], q: float) -> float:
    return float(np.percentile(np.asarray(values), q)) if values else float("nan")


# --- (a) round trips through one real sim node ------------------------------------------------
class Driver:
    """Publishes thermostat scenarios and collects their results, N in flight."""

    def __init__(self, pool_size: int = 500, seed: int = 1):
        self.problem = get_problem(PROBLEM)
        self.node = create_node("bench_campaign_driver")
        n = self.node
        self.typename = topics.SCENARIO_TYPES[PROBLEM]
        self.pub = n.create_publisher(self.typename, topics.scenarios(PROBLEM), STREAM)
        n.create_subscription(topics.RESULT_TYPE, topics.RESULTS, self._on_result, STREAM)
        rng = np.random.default_rng(seed)
        X = self.problem.codec.join(*self.problem.sample(pool_size, rng))
        self.pool = [self.problem.codec.from_row(r) for r in X]
        self.run_id = ""
        self.sent: dict[int, float] = {}
        self.latency: list[float] = []
        self.kinds: dict[int, int] = {}
        self.duplicates = 0
        self.next_id = 0
        self.total = 0
        self.last_receive = 0.0
        self.stop_sending = float("inf")

    def _send(self) -> None:
        i = self.next_id
        self.next_id += 1
        meta = ScenarioMeta(self.run_id, i, 0, 0, 0.0)
        msg = conversions.scenario_message(self.node.new_message, self.node.now_ns(), self.problem, self.pool[i % len(self.pool)], meta)
        self.sent[i] = time.perf_counter()
        self.pub.publish(msg)

    def _on_result(self, msg) -> None:
        if msg.run_id != self.run_id:
            return
        t0 = self.sent.pop(int(msg.scenario_id), None)
        if t0 is None:
            self.duplicates += 1
            return
        self.last_receive = time.perf_counter()
        self.latency.append(self.last_receive - t0)
        self.kinds[int(msg.failure_kind)] = self.kinds.get(int(msg.failure_kind), 0) + 1
        if self.next_id < self.total and time.perf_counter() < self.stop_sending:
            self._send()

    def warm_up(self, timeout: float = 30.0) -> None:
        """Until the sim node is matched both ways and has answered once."""
        if not self.node.wait_for_subscribers(self.pub, 1, timeout):
            raise RuntimeError("the sim node never subscribed to the scenarios")
        self.run_id, self.total, self.next_id = "warmup", 10**9, 0
        deadline = time.monotonic() + timeout
        while not self.latency:
            if time.monotonic() > deadline:
                raise RuntimeError("no result from the sim node")
            self._send()
            self.node.spin_until(lambda: bool(self.latency), 0.3)
        self.node.spin_once(0.2)

    def run(self, n: int, in_flight: int, seconds: float, timeout: float = 60.0) -> dict:
        """Up to ``n`` round trips; no new scenario is sent after ``seconds``."""
        self.run_id = f"bench-{in_flight}-{time.monotonic_ns()}"
        self.sent, self.latency, self.kinds, self.duplicates = {}, [], {}, 0
        self.next_id, self.total = 0, n
        start = time.perf_counter()
        self.stop_sending = start + seconds
        for _ in range(min(in_flight, n)):
            self._send()
        self.node.spin_until(lambda: len(self.latency) >= self.next_id, seconds + timeout)
        self.node.spin_once(0.1)  # a late duplicate would show up here
        got, n = len(self.latency), self.next_id
        lat_us = [x * 1e6 for x in self.latency]
        return {
            "in_flight": in_flight,
            "round_trips": got,
            "lost": n - got,
            "duplicates": self.duplicates,
            "round_trips_per_s": round(got / (self.last_receive - start), 1) if got else 0.0,
            "latency_us_p50": round(_pct(lat_us, 50), 1),
            "latency_us_p99": round(_pct(lat_us, 99), 1),
            "latency_us_mean": round(statistics.fmean(lat_us), 1) if lat_us else float("nan"),
            "failure_kinds": {str(k): v for k, v in sorted(self.kinds.items())},
        }


def bench_roundtrip(domain: int, n: int, levels: list[int], seconds: float) -> dict:
    os.environ["ROS_DOMAIN_ID"] = str(domain)
    worker = subprocess.Popen(
        [sys.executable, "-m", "sim_nodes.thermostat_sim", "--ros-args", "-p", "worker_id:=bench_worker", "-p", "model:=surrogate"],
        cwd=ROOT, env=_env(domain), stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    driver = Driver()
    try:
        driver.warm_up()
        cases = [driver.run(n, level, seconds) for level in levels]
    finally:
        driver.node.shutdown()
        worker.send_signal(2)
        try:
            worker.wait(10)
        except subprocess.TimeoutExpired:
            worker.kill()
    best = max(cases, key=lambda c: c["round_trips_per_s"])
    return {
        "how": "this process publishes ThermostatScenario messages (conversions.scenario_message, "
        "distinct scenario ids, 500 sampled schedules reused) to one thermostat_sim node process "
        "and sends the next as soon as a result arrives, keeping N in flight; latency = publish to "
        f"result received (perf_counter); rate = results / (last result - first publish); each case "
        f"stops at {n} round trips or after {seconds:g} s",
        "cases": cases,
        "best_round_trips_per_s": best["round_trips_per_s"],
        "target_round_trips_per_s": 1000,
    }


# --- (b) an in_the_loop campaign -------------------------------------------------------------
def _log_rate(mcap: Path, run_id: str) -> dict:
    """Results of ``run_id`` per second of log time, first scenario to last result."""
    from ambiegen_ros.ros.runlog import iter_messages

    scen_topic, first, last, results = topics.scenarios(PROBLEM), None, None, 0
    for topic, _type, log_time, msg in iter_messages(mcap, {scen_topic, topics.RESULTS}):
        if topic == scen_topic and first is None and msg.meta.run_id == run_id:
            first = log_time
        elif topic == topics.RESULTS and msg.run_id == run_id:
            results += 1
            last = log_time
    span = (last - first) / 1e9 if first and last else float("nan")
    return {"results_in_log": results, "execution_span_s": round(span, 3), "scenarios_per_s": round(results / span, 1)}


def bench_in_the_loop(domain: int, seconds: float, population: int, workers: int, max_in_flight: int) -> dict:
    from ambiegen_ros.campaign import Campaign, CampaignSpec

    with tempfile.TemporaryDirectory() as tmp:
        spec = CampaignSpec(
            problem=PROBLEM, algorithm="ga", mode="in_the_loop", time_budget=seconds, population=population,
            offspring=population, workers=workers, seed=1, domain_id=domain, out=Path(tmp), timeout=600,
            generator_params={"max_in_flight": max_in_flight}, sim_model="surrogate",
        )
        start = time.perf_counter()
        summary = Campaign(spec).run()
        wall = time.perf_counter() - start
        rate = _log_rate(Path(summary["mcap"]), summary["run_id"])
    return {
        "time_budget_s": seconds,
        "evaluations": summary.get("evaluations"),
        "population": population,
        "workers": workers,
        "max_in_flight_per_worker": max_in_flight,
        "exit_codes": summary["exit_codes"],
        "wall_s": round(wall, 2),
        "unresolved": len(summary.get("unresolved", [])),
        "timeouts": summary.get("timeouts"),
        **rate,
    }


# --- (c) campaign overhead over the in-process search ---------------------------------------
def bench_overhead(domain: int, cases: list[tuple[str, str, int]]) -> dict:
    out = []
    for problem, algorithm, evaluations in cases:
        with tempfile.TemporaryDirectory() as tmp:
            common = ["--problem", problem, "--algorithm", algorithm, "--evaluations", str(evaluations), "--seed", "3"]
            t = time.perf_counter()
            s = subprocess.run(AMBIEGEN + ["search", *common, "--no-plots", "-q", "--out", f"{tmp}/search"], cwd=ROOT,
                               env=_env(domain), capture_output=True, text=True, timeout=600)
            t_search = time.perf_counter() - t
            t = time.perf_counter()
            c = subprocess.run(AMBIEGEN + ["campaign", *common, "--sim-model", "surrogate", "--domain-id", str(domain), "--out", f"{tmp}/campaign"],
                               cwd=ROOT, env=_env(domain), capture_output=True, text=True, timeout=600)
            t_campaign = time.perf_counter() - t
            summary = json.loads((Path(tmp) / "campaign" / "summary.json").read_text())
        out.append({
            "problem": problem,
            "algorithm": algorithm,
            "evaluations": evaluations,
            "search_exit": s.returncode,
            "campaign_exit": c.returncode,
            "search_wall_s": round(t_search, 2),
            "campaign_wall_s": round(t_campaign, 2),
            "overhead_s": round(t_campaign - t_search, 2),
            "ratio": round(t_campaign / t_search, 2),
            "suite_scenarios_executed": summary.get("results_received"),
        })
    return {
        "how": "wall time of the CLI processes (`ambiegen search` vs `ambiegen campaign`, same problem, "
        "algorithm, budget and seed; search without plots; campaign in surrogate mode, one sim worker); the campaign adds process "
        "start-up, DDS discovery, executing the final suite on the sim node and finalising the MCAP",
        "cases": out,
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--domain", type=int, default=71, help="first of three ROS_DOMAIN_IDs used (keep others off them; at most 99: higher ids collide with ephemeral ports)")
    ap.add_argument("--quick", action="store_true", help="smaller runs (a smoke test)")
    ap.add_argument("--no-write", action="store_true", help="print only, do not write bench/results")
    args = ap.parse_args(argv)
    os.chdir(ROOT)  # node subprocesses (`python -m ...`) import this tree
    n = 1000 if args.quick else 5000
    figures = {
        "backend": os.environ.get("AMBIEGEN_TRANSPORT", "auto"),
        "roundtrip": bench_roundtrip(args.domain, n, [1, 16, 64, 256], 3.0 if args.quick else 8.0),
        "in_the_loop": {
            "how": f"an in_the_loop campaign (ambiegen_ros.campaign.Campaign: generator + sim workers + recorder "
            f"as subprocesses; {PROBLEM}, ga, population = offspring = 500); rate = results in the MCAP / "
            "(last result - first scenario) by log time",
            "cases": [
                bench_in_the_loop(args.domain + 1, 4.0 if args.quick else 10.0, 500, workers, mif)
                for workers, mif in ((1, 8), (1, 64), (2, 64))
            ],
        },
        "overhead": bench_overhead(
            args.domain + 2,
            [("thermostat", "ga", 1000 if args.quick else 5000), ("robot", "nsga2", 500 if args.quick else 2000)],
        ),
    }
    print(json.dumps(figures, indent=2))
    if not args.no_write:
        from _common import write_result

        print(f"wrote {write_result('campaign', figures)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
