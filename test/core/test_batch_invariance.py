"""A scenario's surrogate result must not depend on what it is evaluated with.

Sim workers evaluate whatever arrived in the last few milliseconds as one batch, so the same
scenario is scored alone, with 15 others or with 200 depending on timing. If its F1 changed in
the last bits with the batch (a scalar path for small batches, a sum regrouped by padding, ...),
the search would break ties differently and a seed would stop reproducing a campaign (issue 7,
section 3). So ``problem.evaluate`` must give every row the same bits in any batch: alone, in the
whole batch, in random chunks, in another order.
"""
from __future__ import annotations

import numpy as np
import pytest

from ambiegen_ros.problems import PROBLEM_NAMES, PROFILES, get_problem

N = {"thermostat": 60, "robot": 24, "vehicle": 40}  # above the thermostat's small-batch size (16)
CASES = [(name, profile, {}) for name in PROBLEM_NAMES for profile in PROFILES]
# the vehicle's fallback without numba (a slow car loop: fewer roads)
CASES += [("vehicle", profile, {"engine": "numpy"}) for profile in PROFILES]


def scenarios(problem, n: int) -> np.ndarray:
    """Sampled rows, some mutated (restrictions broken now and then), some shortened, one outside
    its domain: one batch of mixed lengths and verdicts."""
    rng = np.random.default_rng(7)
    X = problem.sample_rows(n, rng)
    codec = problem.codec
    G, lengths = codec.split(X.copy())
    for i in range(0, n, 3):  # re-draw one cell inside its domain: breaks restrictions now and then
        m = int(lengths[i])
        j = int(rng.integers(0, len(codec.attributes)))
        G[i, int(rng.integers(0, m)), j] = codec.attributes[j].sample(rng, 1)[0]
    for i in range(1, n, 5):  # shorter scenarios: other padded widths in the batch
        lengths[i] = max(codec.m_min, int(lengths[i]) // 2)
        G[i, lengths[i]:] = 0.0
    G[n // 2, 0, 0] = codec.attributes[0].high + 100  # at least one invalid row, whatever the model
    return codec.join(G, lengths)


def columns(ev) -> dict[str, np.ndarray]:
    cols = {"f1": np.asarray(ev.f1, dtype=float), "valid": np.asarray(ev.valid)}
    cols.update({f"metric {k}": np.asarray(v) for k, v in ev.metrics.items()})
    return cols


def assert_same_bits(expected: dict, got: dict, what: str) -> None:
    assert expected.keys() == got.keys(), what
    for key, a in expected.items():
        b = got[key]
        if a.dtype.kind == "f":
            same = a.view(np.uint64) == b.astype(float).view(np.uint64)
        else:
            same = a == b
        if not same.all():
            i = int(np.flatnonzero(~same)[0])
            pytest.fail(f"{what}: {key} of row {i} is {b[i]!r}, alone {a[i]!r} ({int((~same).sum())} rows differ)")


@pytest.mark.parametrize("name,profile,options", CASES, ids=[f"{n}-{p}{'-numpy' if o else ''}" for n, p, o in CASES])
def test_evaluate_gives_each_row_the_same_bits_in_any_batch(name, profile, options):
    problem = get_problem(name, {"profile": profile, **options})
    X = scenarios(problem, 20 if options else N[name])
    alone = [problem.evaluate_rows(X[i : i + 1]) for i in range(len(X))]
    expected = {k: np.concatenate([columns(ev)[k] for ev in alone]) for k in columns(alone[0])}
    assert expected["valid"].any() and not expected["valid"].all(), "the batch should mix valid and invalid rows"
    reasons = [ev.reasons[0] for ev in alone]

    whole = problem.evaluate_rows(X)
    assert_same_bits(expected, columns(whole), "whole batch vs one by one")
    assert whole.reasons == reasons

    rng = np.random.default_rng(11)
    order = rng.permutation(len(X))
    shuffled = problem.evaluate_rows(X[order])
    assert_same_bits({k: v[order] for k, v in expected.items()}, columns(shuffled), "shuffled batch vs one by one")

    cuts = np.sort(rng.choice(np.arange(1, len(X)), size=4, replace=False))
    parts = [problem.evaluate_rows(X[a:b]) for a, b in zip([0, *cuts], [*cuts, len(X)])]
    chunked = {k: np.concatenate([columns(ev)[k] for ev in parts]) for k in expected}
    assert_same_bits(expected, chunked, f"chunks cut at {cuts.tolist()} vs one by one")
