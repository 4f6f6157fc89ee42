"""Why a vehicle GA run gets stuck (issue 17): a stuck seed and a good one, side by side.

Usage: python bench/vehicle_search_diagnosis.py [--seeds 0,13] [--algorithm ga] [--profile replication]
       [--evaluations 100000] [--operators profile|generic|authors] [--label NAME]

Runs the search as ``ambiegen experiment`` does (paper budget, seed = the run's seed) and watches its
operators from outside (nothing in the search is changed). Per generation it measures:

- diversity of the population (every tenth generation): distinct *roads* (what the car drives:
  the elements kept before the road leaves the map, canonical) and distinct genomes, and the mean
  pairwise Jaccard distance of the roads;
- the share of bred children that duplicate elimination threw away, and mating rounds needed;
- mutation: how often it changed the road at all, and how often a mutated child was invalid
  (F1 = 0) against children of crossover alone;
- how often a child's road equals one of its parents' roads, and how often a road evaluated
  earlier in the run comes back;
- best F1 over evaluations, and the evaluation where it last improved.

Writes bench/results/vehicle_search_diagnosis.json (one entry per label, kept across calls).
"""
from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from _common import RESULTS, write_result  # noqa: E402

from ambiegen_ros.core.diversity import mean_pairwise_diversity  # noqa: E402
from ambiegen_ros.core.search import Search, SearchSettings  # noqa: E402
from ambiegen_ros.problems import get_problem  # noqa: E402
from ambiegen_ros.problems.vehicle.operators import RoadDuplicateElimination, authors_operators  # noqa: E402
from ambiegen_ros.problems.vehicle.replication_road import replication_points  # noqa: E402

NAME = "vehicle_search_diagnosis"
OPERATORS = {
    "profile": None,
    "generic": lambda problem, settings: {},
    "authors": lambda problem, settings: {
        **authors_operators(settings.mutation_rate, settings.crossover_rate),
        "eliminate_duplicates": RoadDuplicateElimination(problem),
    },
}


def road_keys(problem, X: np.ndarray) -> list[bytes]:
    """One key per row for the road the surrogate scores: the canonical elements it keeps."""
    G, lengths = problem.canonical(*problem.codec.split(X))
    if problem.profile == "replication" and len(X):
        _, _, used = replication_points(G, lengths, problem.config)
        lengths = np.minimum(lengths, used)
        G = np.where(np.arange(G.shape[1])[None, :, None] < lengths[:, None, None], G, 0.0)
    return [g.tobytes() + int(n).to_bytes(2, "little") for g, n in zip(G, lengths)]


def canonical_rows(problem, X: np.ndarray) -> np.ndarray:
    return problem.codec.join(*problem.canonical(*problem.codec.split(X)))


def road_diversity(problem, X: np.ndarray, rng: np.random.Generator, sample: int = 200) -> float:
    """Mean pairwise Jaccard distance of (a sample of) the roads, tails past the map cut dropped."""
    if len(X) > sample:
        X = X[rng.choice(len(X), size=sample, replace=False)]
    G, lengths = problem.canonical(*problem.codec.split(X))
    if problem.profile == "replication" and len(X):
        lengths = np.minimum(lengths, replication_points(G, lengths, problem.config)[2])
    return mean_pairwise_diversity(G, lengths, problem.codec.attributes)


class Watch:
    """Wraps the algorithm's crossover, mutation and duplicate elimination to count what they do."""

    def __init__(self, problem, algorithm):
        self.problem = problem
        self.reset()
        mating = algorithm.mating
        self._wrap(mating.crossover, self._after_crossover)
        self._wrap(mating.mutation, self._after_mutation, before=self._before_mutation)
        self._wrap(mating.eliminate_duplicates, self._after_duplicates, before=self._before_duplicates)

    def reset(self) -> None:
        self.bred = self.kept = self.rounds = 0
        self.mutated: dict[bytes, bool] = {}  # child row -> its road changed by mutation
        self.same_as_parent: dict[bytes, bool] = {}  # child row -> road equal to a parent's road
        self._pre: np.ndarray | None = None
        self._dup_in = 0

    @staticmethod
    def _wrap(op, after, before=None) -> None:
        inner = op.do

        def do(*args, **kwargs):
            if before is not None:
                before(*args, **kwargs)
            out = inner(*args, **kwargs)
            after(out, *args, **kwargs)
            return out

        op.do = do

    def _after_crossover(self, off, problem, pop, parents=None, **kwargs) -> None:
        matings = [pop[m] for m in parents] if parents is not None else pop  # pymoo passes the parents
        n_matings = len(matings)
        X = off.get("X")
        child_keys = road_keys(self.problem, X)
        n_parents = len(matings[0]) if n_matings else 0
        parents = [p.get("X") for mating in matings for p in mating]
        flat = road_keys(self.problem, np.stack(parents)) if parents else []
        for index, (row, key) in enumerate(zip(X, child_keys)):
            j = index % n_matings
            self.same_as_parent[row.tobytes()] = key in flat[j * n_parents: (j + 1) * n_parents]

    def _before_mutation(self, problem, pop, *args, **kwargs) -> None:
        self._pre = pop.get("X").copy()

    def _after_mutation(self, off, problem, pop, *args, **kwargs) -> None:
        X = off.get("X")
        changed_row = np.any(X != self._pre, axis=1)
        before, after = road_keys(self.problem, self._pre), road_keys(self.problem, X)
        for i in np.flatnonzero(changed_row):
            self.mutated[X[i].tobytes()] = before[i] != after[i]

    def _before_duplicates(self, pop, *args, **kwargs) -> None:
        self._dup_in = len(pop)

    def _after_duplicates(self, out, pop, *args, **kwargs) -> None:
        if not kwargs.get("return_indices") and len(args) == 2:  # the mating loop's call (pop, off)
            self.bred += self._dup_in
            self.kept += len(out)
            self.rounds += 1


def _share(part: int, whole: int) -> float | None:
    return round(part / whole, 4) if whole else None


def diagnose(problem, settings: SearchSettings) -> dict:
    """One watched run: per-generation rows and a summary."""
    search = Search(problem, settings)
    algorithm = search._algorithm
    watch = Watch(problem, algorithm) if algorithm is not None else None
    rng = np.random.default_rng(0)
    seen: set[bytes] = set()
    generations = []
    best, last_gain_at = 0.0, 0
    totals = dict(bred=0, kept=0, children=0, mutated=0, mutated_same_road=0, mutated_zero=0,
                  cross_only=0, cross_only_zero=0, same_as_parent=0, revisits=0)
    start = time.perf_counter()
    while True:
        if watch is not None:
            watch.reset()
        X = search.ask()
        if X is None:
            break
        evaluation = problem.evaluate_rows(X)
        search.tell(evaluation)
        keys = road_keys(problem, X)
        zero = evaluation.f1 <= 0
        revisits = sum(k in seen for k in keys)
        seen.update(keys)
        row = {"evaluations": search.evaluations, "best_f1": round(search.best_f1, 4),
               "children": len(X), "zero_f1": _share(int(zero.sum()), len(X)),
               "revisits": _share(revisits, len(X))}
        totals["children"] += len(X)
        totals["revisits"] += revisits
        if search.best_f1 > best + 1e-9:
            best, last_gain_at = search.best_f1, search.evaluations
        if watch is not None and len(generations) > 0:
            rows = [x.tobytes() for x in X]
            mut = np.array([r in watch.mutated for r in rows])
            mut_same = np.array([r in watch.mutated and not watch.mutated[r] for r in rows])
            same_parent = np.array([watch.same_as_parent.get(r, False) for r in rows])
            row.update(
                bred=watch.bred, eliminated=_share(watch.bred - watch.kept, watch.bred), rounds=watch.rounds,
                mutated=_share(int(mut.sum()), len(X)),
                mutation_kept_road=_share(int(mut_same.sum()), int(mut.sum())),
                mutated_zero_f1=_share(int((zero & mut).sum()), int(mut.sum())),
                crossover_only_zero_f1=_share(int((zero & ~mut).sum()), int((~mut).sum())),
                crossover_road_of_parent=_share(int(same_parent.sum()), len(X)),
            )
            totals["bred"] += watch.bred
            totals["kept"] += watch.kept
            totals["mutated"] += int(mut.sum())
            totals["mutated_same_road"] += int(mut_same.sum())
            totals["mutated_zero"] += int((zero & mut).sum())
            totals["cross_only"] += int((~mut).sum())
            totals["cross_only_zero"] += int((zero & ~mut).sum())
            totals["same_as_parent"] += int(same_parent.sum())
        pop = algorithm.pop if algorithm is not None else None
        if pop is not None and (len(generations) % 10 == 0 or search.remaining() == 0):
            PX = pop.get("X")
            pkeys = road_keys(problem, PX)
            row.update(
                pop_distinct_roads=len(set(pkeys)),
                pop_distinct_genomes=len({x.tobytes() for x in canonical_rows(problem, PX)}),
                pop_road_diversity=round(road_diversity(problem, PX, rng), 4),
                pop_mean_f1=round(float(pop.get("f1").astype(float).mean()), 4),
            )
        generations.append(row)
    at = {n: max((g["best_f1"] for g in generations if g["evaluations"] <= n), default=0.0)
          for n in (1000, 10000, 25000, 50000, 75000, 100000)}
    summary = {
        "best_f1": round(search.best_f1, 4),
        "wall_s": round(time.perf_counter() - start, 1),
        "best_f1_at": at,
        "last_improvement_at_evaluation": last_gain_at,
        "revisited_roads": _share(totals["revisits"], totals["children"]),
        "distinct_roads_evaluated": len(seen),
    }
    if watch is not None:
        late = [g["pop_distinct_roads"] for g in generations[1:]
                if g["evaluations"] > settings.evaluations // 2 and "pop_distinct_roads" in g]
        summary.update(
            eliminated_as_duplicates=_share(totals["bred"] - totals["kept"], totals["bred"]),
            mutated_children=_share(totals["mutated"], totals["children"]),
            mutation_kept_road=_share(totals["mutated_same_road"], totals["mutated"]),
            mutated_zero_f1=_share(totals["mutated_zero"], totals["mutated"]),
            crossover_only_zero_f1=_share(totals["cross_only_zero"], totals["cross_only"]),
            crossover_road_of_parent=_share(totals["same_as_parent"], totals["children"]),
            pop_distinct_roads_first_last=[g.get("pop_distinct_roads") for g in (generations[0], generations[-1])],
            pop_distinct_genomes_last=generations[-1].get("pop_distinct_genomes"),
            pop_road_diversity_first_last=[g.get("pop_road_diversity") for g in (generations[0], generations[-1])],
            late_half_mean_distinct_roads=round(float(np.mean(late)), 1) if late else None,
        )
    kept = [g for i, g in enumerate(generations) if "pop_distinct_roads" in g or i == len(generations) - 1]
    return {"summary": summary, "generations": kept}  # every tenth generation: the file stays small


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,13")
    ap.add_argument("--algorithm", default="ga")
    ap.add_argument("--profile", default="replication")
    ap.add_argument("--evaluations", type=int, default=100000)
    ap.add_argument("--operators", choices=sorted(OPERATORS), default="profile",
                    help="profile: the problem's (as `ambiegen experiment`); generic: core.operators only "
                         "(before issue 17); authors: the replication code's sampling, crossover, mutation")
    ap.add_argument("--label", default=None, help="entry name in the JSON (default: algorithm-profile[-operators])")
    args = ap.parse_args()
    problem = get_problem("vehicle", {"profile": args.profile})
    if args.operators != "profile":
        chosen = OPERATORS[args.operators]
        problem.search_operators = lambda settings: chosen(problem, settings)
    suffix = "" if args.operators == "profile" else f"-{args.operators}"
    label = args.label or f"{args.algorithm}-{args.profile}{suffix}"
    runs = {}
    for seed in (int(s) for s in args.seeds.split(",")):
        settings = SearchSettings(algorithm=args.algorithm, evaluations=args.evaluations, seed=seed)
        runs[str(seed)] = diagnose(problem, settings)
        s = runs[str(seed)]["summary"]
        print(f"[{label}] seed {seed}: " + ", ".join(f"{k}={v}" for k, v in s.items()), flush=True)
    path = RESULTS / f"{NAME}.json"
    figures = json.loads(path.read_text())["figures"] if path.exists() else {}
    figures[label] = {"algorithm": args.algorithm, "profile": args.profile, "evaluations": args.evaluations,
                      "operators": args.operators,
                      "runs": runs}
    print(write_result(NAME, figures))


if __name__ == "__main__":
    main()
