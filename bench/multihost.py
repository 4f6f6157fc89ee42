"""A campaign across hosts (network namespaces): throughput, exactly-once, fault detection and reassignment.

Host A runs ``ambiegen campaign --workers 0 --remote-workers 4 --discovery-range subnet`` (an
in-the-loop thermostat campaign), hosts B and C two surrogate sim workers each, all on one bridge
with multicast on (test/helpers/netns.py; needs root). Three kinds of run:

* ``clean``: no fault. Every scenario must be sent once and answered once.
* ``faults``: mid-run host C's cable is pulled for 6 s, then a worker on B is SIGKILLed. Figures:
  how long until the generator declared each worker lost (detection) and re-sent its stranded
  scenarios to another worker (reassignment), and when the last of them was answered.
* ``discovery_cut``: host C's cable is pulled for 6 s the moment the generator's node exists, and
  the generator starts as soon as B's two workers are seen (the issue's "link down during
  discovery", where host A started with its own worker); figures: how long after the cable is
  back C's workers are answering scenarios, and how many they got.

Usage: sudo .venv/bin/python bench/multihost.py [--evaluations 5000] [--repeat 2] [--backend dds] [--out DIR]
Prints the figures and writes bench/results/multihost.json.
"""
from __future__ import annotations

import argparse
import re
import statistics
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
for p in (ROOT, ROOT / "test" / "helpers", ROOT / "bench"):
    if str(p) not in sys.path:
        sys.path.insert(0, str(p))

import netns  # noqa: E402
from _common import write_result  # noqa: E402

WORKERS = {"b1": "b", "b2": "b", "c1": "c", "c2": "c"}
EVENT = re.compile(r"\[(?:WARN|INFO)\] \[(\d+\.\d+)\] \[generator\]: worker (\S+) (lost|is back|did not answer)")


def per_worker(dispatch: dict) -> dict[str, int]:
    counts: dict[str, int] = {}
    for results in dispatch["results"].values():
        counts[results[0][1]] = counts.get(results[0][1], 0) + 1
    return dict(sorted(counts.items()))


def execution_window(dispatch: dict) -> tuple[float, float]:
    sends = [s[0] for ss in dispatch["sends"].values() for s in ss]
    results = [r[0] for rs in dispatch["results"].values() for r in rs]
    return min(sends), max(results)


def basics(run: dict) -> dict:
    s, d = run["summary"], run.get("dispatch", {"sends": {}, "results": {}})
    first, last = execution_window(d) if d["sends"] else (0.0, 0.0)
    return {
        "ok": run["returncode"] == 0 and s.get("timeouts") == 0 and s.get("unresolved") == [],
        "evaluations": s.get("evaluations"),
        "results": s.get("results_received"),
        "timeouts": s.get("timeouts"),
        "duplicate_results": s.get("duplicate_results"),
        "sent_more_than_once": sum(1 for v in d["sends"].values() if len(v) > 1),
        "execution_s": round(last - first, 2),
        "evaluations_per_s": round(len(d["results"]) / (last - first), 1) if last > first else None,
        "by_worker": per_worker(d),
        "campaign_s": s.get("elapsed_s"),
    }


def clean(net, out: Path, domain: int, evaluations: int, backend: str) -> dict:
    run = netns.campaign_across_hosts(net, out, domain, evaluations, WORKERS, backend=backend)
    figures = basics(run)
    d = run["dispatch"]
    figures["exactly_once"] = all(len(v) == 1 for v in d["sends"].values()) and all(
        len(v) == 1 for v in d["results"].values()) and len(d["results"]) == evaluations
    return figures


def faults(net, out: Path, domain: int, evaluations: int, backend: str) -> dict:
    run = netns.campaign_across_hosts(
        net, out, domain, evaluations, WORKERS, backend=backend,
        faults=[(2.0, "down", "c"), (8.0, "up", "c"), (11.0, "kill", "b2")],
    )
    figures = basics(run)
    (down, _, _), (up, _, _), (killed, _, _) = run["faults"]
    events = [(float(t), w, k) for t, w, k in EVENT.findall(run["generator_log"])]
    for worker, at in (("c1", down), ("c2", down), ("b2", killed)):
        lost = [t for t, w, k in events if w == worker and k == "lost" and t > at]
        entry = {"detected_s": round(lost[0] - at, 2) if lost else None,
                 **netns.fault_timings(run["dispatch"], worker, at)}
        if worker.startswith("c"):
            back = [t for t, w, k in events if w == worker and k == "is back" and t > up]
            sends = [t for ss in run["dispatch"]["sends"].values() for t, w, _ in ss if w == worker and t > up]
            entry["back_s"] = round(back[0] - up, 2) if back else None
            entry["work_again_s"] = round(min(sends) - up, 2) if sends else None
        figures[worker] = entry
    return figures


def discovery_cut(net, out: Path, domain: int, evaluations: int, backend: str) -> dict:
    """C's cable pulled for 6 s as soon as the generator's node exists; it starts with B's workers."""
    import threading

    log = out / "run" / "logs" / "generator.log"
    cut: dict[str, float] = {}

    def pull() -> None:
        deadline = time.monotonic() + 300
        while time.monotonic() < deadline and "] [generator]: run " not in (log.read_text(errors="replace") if log.exists() else ""):
            time.sleep(0.02)
        cut["down"] = time.time()
        net.set_link("c", False)
        time.sleep(6.0)
        net.set_link("c", True)
        cut["up"] = time.time()

    puller = threading.Thread(target=pull, daemon=True)
    puller.start()
    run = netns.campaign_across_hosts(net, out, domain, evaluations, WORKERS, backend=backend, wait_for=2)
    puller.join(timeout=30)
    figures = basics(run)
    figures["generator_started_after_cut_s"] = round(run["began"] - cut.get("down", run["began"]), 2)
    sends = run["dispatch"]["sends"]
    for worker in ("c1", "c2"):
        first_answered = min((r[0] for rs in run["dispatch"]["results"].values() for r in rs if r[1] == worker),
                             default=None)
        figures[worker] = {
            "sent": sum(1 for ss in sends.values() for _, w, _ in ss if w == worker),
            "first_answer_after_link_up_s": round(first_answered - cut["up"], 2) if first_answered and "up" in cut else None,
        }
    return figures


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--evaluations", type=int, default=5000)
    ap.add_argument("--repeat", type=int, default=2, help="runs of each kind")
    ap.add_argument("--backend", default="dds", choices=("dds", "rclpy"))
    ap.add_argument("--kinds", default="clean,faults,discovery_cut", help="which runs, comma-separated")
    ap.add_argument("--out", type=Path, help="keep every run's logs and MCAP here (default: a temporary folder)")
    args = ap.parse_args()
    reason = netns.unavailable_reason()
    if reason:
        print(f"cannot run: {reason}", file=sys.stderr)
        return 2
    figures: dict = {"evaluations": args.evaluations, "backend": args.backend, "workers": WORKERS, "runs": {}}
    with tempfile.TemporaryDirectory(prefix="multihost-") as tmp:
        tmp = args.out or tmp
        for kind, fn in (("clean", clean), ("faults", faults), ("discovery_cut", discovery_cut)):
            if kind not in args.kinds.split(","):
                continue
            for k in range(args.repeat):
                net = netns.TestNetwork(("a", "b", "c")).create()
                try:
                    result = fn(net, Path(tmp) / f"{kind}{k}", 79, args.evaluations, args.backend)
                finally:
                    net.destroy()
                figures["runs"].setdefault(kind, []).append(result)
                print(kind, k, result, flush=True)
    faulty = figures["runs"].get("faults", [])
    detections = [r[w]["detected_s"] for r in faulty for w in ("c1", "c2", "b2")
                  if r[w]["detected_s"] is not None]
    resends = [r[w]["first_resend_s"] for r in faulty for w in ("c1", "c2", "b2")
               if r[w]["first_resend_s"] is not None]
    figures["detection_s_median"] = statistics.median(detections) if detections else None
    figures["reassignment_s_median"] = statistics.median(resends) if resends else None
    figures["all_ok"] = all(r["ok"] for runs in figures["runs"].values() for r in runs)
    path = write_result("multihost", figures)
    print(f"detection {figures['detection_s_median']} s, reassignment {figures['reassignment_s_median']} s "
          f"(medians); all runs complete without timeouts: {figures['all_ok']}; wrote {path}")
    return 0 if figures["all_ok"] else 1


if __name__ == "__main__":
    sys.exit(main())
