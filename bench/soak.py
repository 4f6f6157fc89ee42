"""Soak: a long in-the-loop thermostat campaign under load (issue 10, part 4).

One ``ambiegen_ros.campaign.Campaign`` (recorder + K thermostat sim workers + generator as
subprocesses, every F1 from the sim workers) runs for N evaluations while this process samples
the resident memory (VmRSS) of every node every ``--sample`` seconds through the campaign's
progress hook. Afterwards the MCAP log, read back with the ``mcap`` reader, gives the counts
(``ros.runlog.summarize``) and the time of every result, hence throughput over time.

Checks (``soak_checks``; the CI-sized run in ``test/ros/test_soak.py`` applies ``invariant_checks``,
the first two: what must hold on any machine. Rates are figures of this bench, never a test's):
* nothing lost: every scenario the generator published has a result record in the log, and the
  log holds as many scenarios as the generator says it published and as the budget asked for;
* memory flat: after the warm-up (until the first ``WARMUP`` share of the results), the mean RSS of
  the last quarter is less than 10 % above the first quarter's, for every node;
* throughput flat: results/s of the last quarter within a tolerance of the first quarter's, and
  so is the CPU time all nodes spend per result (what the nodes cost, whatever else the shared
  machine runs meanwhile; results/s also moves with the other jobs on it).

    .venv/bin/python bench/soak.py [--evaluations 200000] [--workers 4] [--domain 1] [--no-write]
"""
from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT) not in sys.path:
    sys.path.insert(0, str(ROOT))

import numpy as np  # noqa: E402

from ambiegen_ros.campaign import Campaign, CampaignSpec  # noqa: E402
from ambiegen_ros.ros import topics  # noqa: E402
from ambiegen_ros.ros.types import get_registry  # noqa: E402

PROBLEM = "thermostat"
WARMUP = 0.10  # share of the results before memory and rates count (start-up, first-batch compiles, however long)
RSS_GROWTH_LIMIT = 0.10  # last quarter's mean RSS over the first quarter's, per node
THROUGHPUT_TOLERANCE = 0.25  # the bench's bound on |last quarter rate / first quarter rate - 1|


def cpu_seconds(pid: int) -> float | None:
    """User + system CPU time of a live process so far, None once it has gone."""
    try:
        with open(f"/proc/{pid}/stat") as fh:
            fields = fh.read().rsplit(")", 1)[1].split()
    except (FileNotFoundError, ProcessLookupError):
        return None
    return (int(fields[11]) + int(fields[12])) / os.sysconf("SC_CLK_TCK")  # utime, stime


def rss_kib(pid: int) -> int | None:
    """Resident set size of a live process (VmRSS), None once it has gone."""
    try:
        with open(f"/proc/{pid}/status") as fh:
            for line in fh:
                if line.startswith("VmRSS:"):
                    return int(line.split()[1])
    except (FileNotFoundError, ProcessLookupError):
        return None
    return None


@dataclass
class NodeSampler:
    """A ``Campaign.run`` progress hook: every ``period`` s, the RSS and CPU time of each running node."""

    period: float
    samples: dict[str, list[tuple[float, int, float]]] = field(default_factory=dict)  # node -> [(unix time, KiB, CPU s)]
    _last: float = float("-inf")

    def __call__(self, campaign: Campaign, elapsed: float) -> None:
        now = time.monotonic()
        if now - self._last < self.period:
            return
        self._last = now
        stamp = time.time()  # the recorder stamps log times with the same clock
        for name, proc in campaign.procs.items():
            kib, cpu = rss_kib(proc.pid), cpu_seconds(proc.pid)
            if proc.poll() is None and kib is not None and cpu is not None:
                self.samples.setdefault(name, []).append((stamp, kib, cpu))


def log_timeline(mcap: Path) -> dict:
    """Log times (s) of the first scenario and of every result, and the generator's last status."""
    from mcap.reader import make_reader

    scenario_topic, first_scenario, result_times, status = topics.scenarios(PROBLEM), None, [], None
    with open(mcap, "rb") as fh:
        for _, channel, message in make_reader(fh).iter_messages(
            topics=[scenario_topic, topics.RESULTS, topics.STATUS], log_time_order=True
        ):
            if channel.topic == topics.RESULTS:
                result_times.append(message.log_time)
            elif channel.topic == scenario_topic:
                first_scenario = message.log_time if first_scenario is None else first_scenario
            else:
                status = message.data
    last_status = get_registry().deserialize(status, topics.STATUS_TYPE) if status is not None else None
    return {
        "first_scenario": None if first_scenario is None else first_scenario / 1e9,
        "results": np.asarray(result_times, dtype=np.int64) / 1e9,
        "status": last_status,
    }


def steady_start(results: np.ndarray) -> float:
    """When the warm-up ends: the time of the result that completes the first ``WARMUP`` share."""
    return float(np.sort(results)[int(WARMUP * (len(results) - 1))])


def _quarters(steady: float, end: float) -> list[tuple[float, float]]:
    """The four quarters of [steady, end] (after the warm-up), as (from, to) times."""
    edges = np.linspace(steady, end, 5)
    return list(zip(edges[:-1], edges[1:]))


def _inside(t: np.ndarray, a: float, b: float, end: float) -> np.ndarray:
    """Times in [a, b), or in [a, b] for the last quarter (it ends with the last result)."""
    return (t >= a) & ((t < b) | ((b == end) & (t == end)))


def throughput(results: np.ndarray, start: float, steady: float, end: float, window: float) -> dict:
    """Results/s per ``window`` over [start, end] and per quarter of the post-warm-up span."""
    edges = np.arange(start, end + window, window)
    counts, _ = np.histogram(results, bins=edges)
    widths = np.minimum(edges[1:], end) - edges[:-1]
    keep = widths > window / 2  # a sliver of a last window says nothing about the rate
    rates = counts[keep] / widths[keep]
    quarter_rates = [float(np.count_nonzero(_inside(results, a, b, end)) / (b - a)) for a, b in _quarters(steady, end)]
    return {
        "window_s": window,
        "per_window": [round(float(r), 1) for r in rates],
        "overall": round(len(results) / (end - start), 1),
        "quarters": [round(r, 1) for r in quarter_rates],
        "last_over_first": round(quarter_rates[3] / quarter_rates[0], 3) if quarter_rates[0] else float("nan"),
        "min_window": round(float(rates.min()), 1) if len(rates) else 0.0,
        "max_window": round(float(rates.max()), 1) if len(rates) else 0.0,
    }


def cpu_per_result(samples: dict[str, list[tuple[float, int, float]]], results: np.ndarray, steady: float, end: float) -> dict:
    """CPU ms all nodes together spent per result, per quarter after warm-up: unlike results/s,
    this does not change when other jobs take the machine's cores, so it shows the nodes slowing down."""
    per_quarter = []
    for a, b in _quarters(steady, end):
        spent = sum(
            float(np.interp(b, [r[0] for r in rows], [r[2] for r in rows]) - np.interp(a, [r[0] for r in rows], [r[2] for r in rows]))
            for rows in samples.values()
        )
        done = np.count_nonzero(_inside(results, a, b, end))
        per_quarter.append(1000 * spent / done if done else float("nan"))
    return {
        "quarters_ms": [round(float(q), 3) for q in per_quarter],
        "last_over_first": round(float(per_quarter[3] / per_quarter[0]), 3) if per_quarter[0] else float("nan"),
    }


def memory(samples: dict[str, list[tuple[float, int, float]]], steady: float, end: float) -> dict:
    """Per node: RSS (MiB) at start, peak, quarter means after warm-up and last/first growth."""
    out = {}
    for name, rows in samples.items():
        t = np.array([r[0] for r in rows])
        mib = np.array([r[1] for r in rows]) / 1024
        means, counts = [], []
        for a, b in _quarters(steady, end):
            inside = _inside(t, a, b, end)
            counts.append(int(inside.sum()))
            means.append(float(mib[inside].mean()) if inside.any() else float("nan"))
        out[name] = {
            "samples": len(rows),
            "first_mib": round(float(mib[0]), 1),
            "peak_mib": round(float(mib.max()), 1),
            "last_mib": round(float(mib[-1]), 1),
            "quarter_mean_mib": [round(m, 2) for m in means],
            "quarter_samples": counts,
            "growth": round(means[3] / means[0] - 1, 4) if means[0] and not np.isnan(means[0] + means[3]) else float("nan"),
        }
    return out


def run_soak(
    out: Path, evaluations: int, workers: int, domain: int, sample_period: float, window: float,
    seed: int = 1, sim_model: str = "surrogate", max_in_flight: int = 64, timeout: float = 7200.0,
) -> dict:
    """Run the campaign, sample memory, and return the figures (counts, throughput, memory)."""
    spec = CampaignSpec(
        problem=PROBLEM, mode="in_the_loop", evaluations=evaluations, workers=workers, seed=seed,
        out=out, domain_id=domain, timeout=timeout, sim_model=sim_model,
        generator_params={"max_in_flight": max_in_flight},
    )
    campaign = Campaign(spec)
    sampler = NodeSampler(sample_period)
    started = time.perf_counter()
    summary = campaign.run(sampler)
    wall = time.perf_counter() - started
    if "log_error" in summary:
        raise RuntimeError(f"campaign log unreadable: {summary['log_error']}")
    timeline = log_timeline(campaign.mcap)
    results, status = timeline["results"], timeline["status"]
    if timeline["first_scenario"] is None or not len(results):
        raise RuntimeError(f"no scenarios or results in {campaign.mcap} (logs in {campaign.out / 'logs'})")
    start, steady, end = timeline["first_scenario"], steady_start(results), float(results.max())
    published = int(status.scenarios_published) if status is not None else -1
    return {
        "run_id": summary["run_id"],
        "algorithm": spec.algorithm,
        "workers": workers,
        "sim_model": sim_model,
        "max_in_flight_per_worker": max_in_flight,
        "seed": seed,
        "exit_codes": summary["exit_codes"],
        "wall_s": round(wall, 1),
        "execution_span_s": round(end - start, 1),
        "messages": {
            "evaluations_asked": evaluations,
            "generator_evaluations": int(status.evaluations) if status is not None else -1,
            "generator_published": published,
            "generator_settled": int(status.results_received) if status is not None else -1,
            "log_scenarios": summary["scenarios_published"],
            "log_not_sent": summary.get("not_sent", 0),  # invalid by the problem: logged, never sent
            "log_scenario_messages": summary["scenario_messages"],
            "log_results": summary["results_received"],
            "duplicate_results": summary["duplicate_results"],
            "timeouts": summary["timeouts"],
            "errors": summary["errors"],
            "unresolved": len(summary["unresolved"]),
            "lost": max(published, summary["scenarios_published"]) - summary["results_received"],
        },
        "warmup_s": round(steady - start, 1),
        "throughput": throughput(results, start, steady, end, window),
        "cpu_per_result": cpu_per_result(sampler.samples, results, steady, end),
        "rss": memory(sampler.samples, steady, end),
        "rss_sample_period_s": sample_period,
        "warmup_share": WARMUP,
    }


def invariant_checks(figures: dict) -> list[str]:
    """What is wrong with a soak run whatever the machine's speed (empty: nothing lost, memory flat)."""
    problems = []
    m = figures["messages"]
    if any(code != 0 for code in figures["exit_codes"].values()):
        problems.append(f"a node exited with an error: {figures['exit_codes']}")
    if m["lost"] or m["unresolved"]:
        problems.append(f"{m['lost']} lost, {m['unresolved']} unresolved: {m}")
    if not (m["generator_published"] == m["log_scenarios"] == m["log_results"]
            and m["evaluations_asked"] == m["log_scenarios"] + m["log_not_sent"]):
        problems.append(f"messages in vs recorded differ: {m}")
    for name, node in figures["rss"].items():
        if min(node["quarter_samples"]) < 2:
            problems.append(f"{name}: too few RSS samples per quarter {node['quarter_samples']}")
        elif not node["growth"] < RSS_GROWTH_LIMIT:
            problems.append(
                f"{name}: RSS grew {node['growth']:.1%} from the first to the last quarter "
                f"(means {node['quarter_mean_mib']} MiB; limit {RSS_GROWTH_LIMIT:.0%})"
            )
    return problems


def soak_checks(figures: dict, throughput_tolerance: float = THROUGHPUT_TOLERANCE) -> list[str]:
    """The invariants, plus the bench's own: throughput and CPU per result flat on this machine."""
    problems = invariant_checks(figures)
    cpu = figures["cpu_per_result"]["last_over_first"]
    if not abs(cpu - 1) <= throughput_tolerance:
        problems.append(
            f"CPU per result not flat: last quarter / first quarter = {cpu} "
            f"(quarters {figures['cpu_per_result']['quarters_ms']} ms; tolerance {throughput_tolerance:.0%})"
        )
    ratio = figures["throughput"]["last_over_first"]
    if not abs(ratio - 1) <= throughput_tolerance:
        problems.append(
            f"throughput not flat: last quarter / first quarter = {ratio} "
            f"(quarters {figures['throughput']['quarters']} results/s; tolerance {throughput_tolerance:.0%})"
        )
    return problems


def print_summary(figures: dict) -> None:
    m, tp = figures["messages"], figures["throughput"]
    print(f"{m['evaluations_asked']} evaluations, {figures['workers']} workers: wall {figures['wall_s']} s, "
          f"execution {figures['execution_span_s']} s")
    print(f"messages: generator published {m['generator_published']}, log scenarios {m['log_scenarios']}, "
          f"log results {m['log_results']}, lost {m['lost']}, duplicates {m['duplicate_results']}, timeouts {m['timeouts']}")
    print(f"throughput: {tp['overall']} results/s overall; quarters {tp['quarters']}; last/first {tp['last_over_first']}; "
          f"{tp['window_s']:g} s windows {tp['min_window']}..{tp['max_window']}")
    cpu = figures["cpu_per_result"]
    print(f"CPU per result (all nodes): quarters {cpu['quarters_ms']} ms; last/first {cpu['last_over_first']}")
    for name, node in figures["rss"].items():
        print(f"RSS {name:20s} first {node['first_mib']:7.1f} MiB, quarters {node['quarter_mean_mib']}, "
              f"peak {node['peak_mib']:7.1f}, growth {node['growth']:+.1%} ({node['samples']} samples)")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--evaluations", type=int, default=200_000)
    ap.add_argument("--workers", type=int, default=4)
    ap.add_argument("--domain", type=int, default=1, help="ROS_DOMAIN_ID of the campaign (keep others off it)")
    ap.add_argument("--sample", type=float, default=10.0, help="seconds between RSS samples")
    ap.add_argument("--window", type=float, default=10.0, help="seconds per throughput window")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--sim-model", default="surrogate", choices=("surrogate", "full"),
                    help="what the workers run (full: ~0.1 s per thermostat scenario here, too slow for 200k)")
    ap.add_argument("--max-in-flight", type=int, default=64, help="scenarios in flight per worker")
    ap.add_argument("--keep", metavar="DIR", help="keep the campaign (MCAP, logs) in this new directory")
    ap.add_argument("--no-write", action="store_true", help="print only, do not write bench/results/soak.json")
    args = ap.parse_args(argv)
    if args.evaluations < 1 or args.workers < 1:
        ap.error("--evaluations and --workers must be >= 1")
    if args.keep and Path(args.keep).exists():
        ap.error(f"--keep {args.keep}: exists; give a new directory")
    os.chdir(ROOT)  # node subprocesses (`python -m ...`) import this tree
    with tempfile.TemporaryDirectory() as tmp:
        out = Path(args.keep) if args.keep else Path(tmp)
        figures = run_soak(
            out, args.evaluations, args.workers, args.domain, args.sample, args.window, args.seed,
            args.sim_model, args.max_in_flight,
        )
    figures["checks_failed"] = soak_checks(figures)
    figures["how"] = (
        f"one in_the_loop {PROBLEM} campaign (ambiegen_ros.campaign.Campaign, nsga2, {args.workers} {args.sim_model} "
        f"sim workers, {args.max_in_flight} scenarios in flight each); "
        f"VmRSS of every node process every {args.sample:g} s; counts from the MCAP (ros.runlog.summarize) and the "
        f"generator's last status; throughput = results per {args.window:g} s of log time; CPU per result = user+system "
        "CPU time of all node processes (/proc/<pid>/stat) per result; after a warm-up (until the first "
        f"{WARMUP:.0%} of the results are in), the rest of the run (to the last result) is cut in quarters and the last "
        "quarter's mean RSS, rate and CPU per result are compared with the first quarter's"
    )
    print_summary(figures)
    for problem in figures["checks_failed"]:
        print(f"CHECK FAILED: {problem}")
    if not args.no_write:
        from _common import write_result

        print(f"wrote {write_result('soak', figures)}")
    return 1 if figures["checks_failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
