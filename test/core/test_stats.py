"""The paper's statistics on samples small enough to check by hand."""
from __future__ import annotations

import math

import pytest

from ambiegen_ros.core.stats import (cliffs_delta, compare, greater_exact, magnitude, mann_whitney, smallest_p,
                                     spearman)


def test_cliffs_delta_hand_counts():
    # every a below every b: P(a > b) = 0, P(a < b) = 1
    assert cliffs_delta([1, 2, 3], [4, 5, 6]) == -1.0
    assert cliffs_delta([4, 5, 6], [1, 2, 3]) == 1.0
    # interleaved: a > b in 3 of 9 pairs (3>2, 5>2, 5>4), a < b in 6 -> (3 - 6) / 9
    assert cliffs_delta([1, 3, 5], [2, 4, 6]) == pytest.approx(-1 / 3)
    # a tie counts for neither side: 1<2, 1<3, 2=2, 2<3 -> (0 - 3) / 4
    assert cliffs_delta([1, 2], [2, 3]) == pytest.approx(-0.75)
    assert cliffs_delta([7, 7], [7, 7, 7]) == 0.0


def test_cliffs_delta_ignores_missing_values():
    assert cliffs_delta([1, None, float("nan")], [2]) == -1.0
    assert math.isnan(cliffs_delta([], [1, 2]))


@pytest.mark.parametrize("delta, label", [
    (0.0, "negligible"), (0.146, "negligible"), (0.147, "small"), (-0.2, "small"), (0.329, "small"),
    (0.33, "medium"), (-0.473, "medium"), (0.474, "large"), (-1.0, "large"), (float("nan"), "n/a"),
])
def test_magnitude_uses_the_papers_thresholds(delta, label):
    assert magnitude(delta) == label


def test_mann_whitney_exact_two_sided_p_values():
    # n = m = 3, no ties: 20 equally likely rankings. Complete separation: U = 0, P(U <= 0) = 1/20.
    assert mann_whitney([1, 2, 3], [4, 5, 6]) == pytest.approx(2 / 20)
    # U of a = 3 (pairs with a > b); counts of U = 0..3 are 1, 1, 2, 3 -> P(U <= 3) = 7/20, two-sided 14/20
    assert mann_whitney([1, 3, 5], [2, 4, 6]) == pytest.approx(14 / 20)
    # n = m = 4, complete separation: 2 / C(8, 4) = 2 / 70
    assert mann_whitney([10, 11, 12, 13], [1, 2, 3, 4]) == pytest.approx(2 / 70)


@pytest.mark.parametrize("n_a, n_b, floor", [
    (1, 1, 2 / 2), (2, 2, 2 / 6), (3, 3, 2 / 20), (3, 5, 2 / 56), (4, 4, 2 / 70), (5, 5, 2 / 252), (2, 7, 2 / 36),
])
def test_smallest_p_is_what_fully_separated_samples_give(n_a, n_b, floor):
    # 2 / C(n_a + n_b, n_a) by hand; no arrangement is more extreme than "every a above every b"
    a, b = [100.0 + k for k in range(n_a)], [float(k) for k in range(n_b)]
    assert smallest_p(n_a, n_b) == pytest.approx(floor)
    assert smallest_p(n_a, n_b) == pytest.approx(mann_whitney(a, b))


def test_mann_whitney_identical_constant_samples_show_no_difference():
    assert mann_whitney([3.0, 3.0, 3.0], [3.0, 3.0]) == 1.0
    assert math.isnan(mann_whitney([], [1.0]))


def test_compare_row_has_the_stats_json_fields():
    row = compare("best_f1", "ga", [4, 5, 6], "random", [1, 2, 3])
    assert row == {"metric": "best_f1", "a": "ga", "b": "random", "n_a": 3, "n_b": 3,
                   "p_value": pytest.approx(0.1), "cliffs_delta": 1.0, "magnitude": "large"}


def test_spearman_by_hand():
    # ranks differ by 1 at two places: rho = 1 - 6 * 2 / (4 * 15) = 0.8
    rho, p, n = spearman([1, 2, 3, 4], [1, 3, 2, 4])
    assert (rho, n) == (pytest.approx(0.8), 4)
    assert 0 < p < 1
    assert spearman([1, 2, 3], [30, 20, 10])[0] == pytest.approx(-1.0)
    assert math.isnan(spearman([1, 2, 3], [5, 5, 5])[0])  # constant side: undefined, not 0
    assert spearman([1, 2, None, 4, 5], [2, 4, 1, 8, 10])[2] == 4  # pairs with a missing value are dropped


def test_greater_exact_counts_every_split_with_ties():
    # 2, 1, 2 against 0, 0, 0: a holds the three largest in 1 of C(6, 3) = 20 splits
    assert greater_exact([2, 1, 2], [0, 0, 0]) == (9.0, pytest.approx(0.05))
    # one value apart: a holds the 1 in half the splits; U = 3 wins + 6 ties / 2
    assert greater_exact([1, 0, 0], [0, 0, 0]) == (6.0, pytest.approx(0.5))
    # nothing apart: no evidence at all
    assert greater_exact([0, 0, 0], [0, 0, 0]) == (4.5, pytest.approx(1.0))
    assert greater_exact([0, 0, 0], [2, 1, 2])[1] == pytest.approx(1.0)
    assert all(math.isnan(v) for v in greater_exact([], [1, 2]))


def test_greater_exact_agrees_with_scipy_without_ties():
    from scipy.stats import mannwhitneyu

    for a, b in (([1, 3, 5], [2, 4, 6]), ([4, 5, 6, 9], [1, 2, 3]), ([1, 2, 8], [3, 4, 5, 6, 7])):
        want = mannwhitneyu(a, b, alternative="greater", method="exact")
        assert greater_exact(a, b) == (float(want.statistic), pytest.approx(want.pvalue))
        assert greater_exact(a, b, limit=1)[1] == pytest.approx(mannwhitneyu(a, b, alternative="greater").pvalue)
