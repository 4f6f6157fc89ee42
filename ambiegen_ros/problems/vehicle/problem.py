"""``VehicleProblem``: sampling, evaluation and one road's environment, tying road, rules and car."""
from __future__ import annotations

import dataclasses
from typing import ClassVar

import numpy as np

from ...core.accel import SMALL_BATCH
from ...core.attributes import Categorical, IntRange
from ...core.problem import Budget, Evaluation, Problem
from ...core.scenario import Scenario
from .car import simulate
from .kernels import kernels_loaded
from .config import ANGLE, LENGTH, REPLICATION_M_MAX, STRAIGHT, TYPE, Road, VehicleConfig
from .replication_car import simulate_replication
from .replication_road import _cross_section_inside, replication_nodes, replication_points, replication_sections
from .road import build_spines, element_points, interpolate
from .validity import _first_half, check_roads, competition_rules


class VehicleProblem(Problem):
    """Roads of straight and arc segments; F1 = max deviation of the surrogate car (paper 5.3)."""

    name: ClassVar[str] = "vehicle"
    attributes = (
        Categorical("type", ("straight", "left", "right")),
        IntRange("length", 5, 50, 1, tolerance=5, unit="m"),
        IntRange("angle", 5, 85, 5, tolerance=5, unit="deg"),
    )
    m_min: ClassVar[int] = 1
    m_max: ClassVar[int] = 20
    f1_label: ClassVar[str] = "max deviation from lane centre [m]"
    paper_budget: ClassVar[Budget] = Budget(500, 500, 100000)
    Config: ClassVar[type] = VehicleConfig
    # refined: its generator's roads keep the competition rules (with the rules as the replication
    # surrogate's constraints, 9 of 2,000 sampled roads are valid); "certified": ``drivers``
    certified_search: ClassVar[dict] = {"profile": "refined", "objective": "certified"}

    def __init__(self, config=None, **overrides):
        super().__init__(config, **overrides)
        if self.config.objective == "certified":
            self.f1_label = "certified-failure score: brisk driver's offset, less the cautious one's near miss [m]"

    def layout(self):
        """Same domains in both profiles (angle 5 is the filler of straights in the reference data,
        and the replication code accepts 5 degree turns); replication roads may have up to
        ``REPLICATION_M_MAX`` elements (its generator grows a road until it leaves the map)."""
        if self.profile == "replication":
            return self.attributes, self.m_min, REPLICATION_M_MAX
        return super().layout()

    @property
    def replication(self) -> bool:
        return self.profile == "replication"

    def canonical(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """A straight ignores its angle and a turn its length: both set to their domain's low."""
        G = np.array(G, dtype=float)
        used = np.arange(G.shape[1])[None, :] < np.asarray(lengths)[:, None]
        straight = G[:, :, TYPE] == STRAIGHT
        G[:, :, ANGLE] = np.where(straight & used, self.attributes[ANGLE].low, G[:, :, ANGLE])
        G[:, :, LENGTH] = np.where(~straight & used, self.attributes[LENGTH].low, G[:, :, LENGTH])
        return G, lengths

    def search_operators(self, settings) -> dict:
        """Read by ``core.search``. Replication: duplicates are compared road by road (a genome's
        elements past the map cut are ignored, as the replication code drops them), else clones of
        one road fill the population and the search stops (issue 17, ``docs/vehicle_search.md``).
        Refined roads use every element: the generic operators. pymoo is imported only here."""
        if not self.replication:
            return {}
        from .operators import RoadDuplicateElimination

        return {"eliminate_duplicates": RoadDuplicateElimination(self)}

    # --- sampling ------------------------------------------------------------------------------------
    def _types(self, n: int, m: int, rng: np.random.Generator) -> np.ndarray:
        """Segment types: a Markov chain from ``first_type`` (or uniform)."""
        cfg = self.config
        t_attr = self.attributes[TYPE]
        if cfg.sampling == "uniform":
            return t_attr.sample(rng, (n, m))
        cum_s = np.cumsum(cfg.p_from_straight)
        cum_t = np.cumsum(cfg.p_from_turn)
        u = rng.random((n, m))
        types = np.empty((n, m), dtype=int)
        types[:, 0] = t_attr.values.index(cfg.first_type)
        for i in range(1, m):
            cum = np.where((types[:, i - 1] == STRAIGHT)[:, None], cum_s, cum_t)
            types[:, i] = np.minimum((u[:, i, None] >= cum[:, :2]).sum(axis=1), 2)
        return types

    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Markov-chain (or uniform) segment types, uniform lengths and angles (from
        ``sample_angle_min``). Refined: each road grows until the next element would put a spine
        point outside the map margin, or ``m_max``. Replication (its generator): the first element
        is a straight of ``first_length``; the road grows until the builder's cross-section has left
        the map (that element is kept), or ``m_max``."""
        cfg = self.config
        m = self.m_max
        G = np.zeros((n, m, 3))
        _, l_attr, a_attr = self.attributes
        angle_attr = IntRange(a_attr.name, cfg.sample_angle_min, a_attr.high, a_attr.step)
        G[:, :, TYPE] = self._types(n, m, rng)
        G[:, :, LENGTH] = l_attr.sample(rng, (n, m))
        G[:, :, ANGLE] = angle_attr.sample(rng, (n, m))
        if cfg.first_length:
            G[:, 0, LENGTH] = cfg.first_length
        if self.replication:
            ends, _ = replication_sections(G, cfg)
            outside = ~_cross_section_inside(ends, cfg)
            lengths = np.where(outside.any(axis=1), np.argmax(outside, axis=1) + 1, m)
        else:
            pts, mask = element_points(G, cfg)
            lo, hi = cfg.margin, cfg.map_size - cfg.margin
            inside = np.all(((pts >= lo) & (pts <= hi)).all(axis=-1) | ~mask, axis=2)  # (n, m)
            lengths = np.where(inside.all(axis=1), m, np.argmin(inside, axis=1))
        lengths = np.maximum(lengths, self.m_min)
        G[np.arange(m)[None, :] >= lengths[:, None]] = 0.0
        return G, lengths

    # --- restrictions and surrogate ------------------------------------------------------------------
    def roads(self, G: np.ndarray, lengths: np.ndarray, cfg: VehicleConfig | None = None):
        """Spines (replication: the road points kept) and the nodes the surrogate scores, of a
        batch (flat arrays + counts); ``check_roads(nodes, counts, config)`` judges them."""
        cfg = cfg or self.config
        if self.replication:
            points, n_points, _ = replication_points(G, lengths, cfg)
            return (points, n_points) + replication_nodes(points, n_points, cfg)
        spine, n_spine = build_spines(G, lengths, cfg)
        nodes, n_nodes = interpolate(spine, n_spine, cfg)
        return spine, n_spine, nodes, n_nodes

    def _config_for(self, n_roads: int):
        """A few roads take the numpy engine unless numba is loaded already: the same bits (tested),
        without numba's import (about 0.3 s, more than a few roads cost)."""
        if self.config.engine == "auto" and n_roads <= SMALL_BATCH and not kernels_loaded():
            return dataclasses.replace(self.config, engine="numpy")
        return self.config

    def evaluate(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        G = np.asarray(G, dtype=float)
        lengths = np.asarray(lengths, dtype=int)
        P = len(lengths)
        f1 = np.zeros(P)
        max_deviation = np.zeros(P)
        valid = np.zeros(P, bool)
        reasons: list[str | None] = [None] * P
        road_length = np.zeros(P)
        metrics = {}
        domain_ok = self.codec.in_domain(G, lengths)
        for i in np.flatnonzero(~domain_ok):
            reasons[i] = self.codec.domain_reason(G[i], int(lengths[i]))
        ok = np.flatnonzero(domain_ok)
        cfg = self._config_for(len(ok))
        if self.replication:
            used = np.zeros(P, dtype=np.int64)
            path_simple = np.ones(P, bool)
            metrics = {"elements_used": used, "car_path_simple": path_simple}
        if len(ok):
            if self.replication:
                points, n_points, used[ok] = replication_points(G[ok], lengths[ok], cfg)
                nodes, n_nodes = replication_nodes(points, n_points, cfg)
            else:
                _, _, nodes, n_nodes = self.roads(G[ok], lengths[ok], cfg)
            v, why, length, min_radius = check_roads(nodes, n_nodes, cfg)
            road_length[ok] = length
            if cfg.objective == "certified":  # the reference's own rules decide validity (issue 26)
                cut = used[ok] < lengths[ok] if self.replication else None
                v, why = self._reference_rules(nodes, n_nodes, v, why, min_radius, cut)
            valid[ok] = v
            for i, reason in zip(ok, why):
                reasons[i] = reason
            if cfg.objective == "certified":
                metrics.update(self._certified(nodes, n_nodes, v, ok, f1, P))
            elif v.any():
                road = np.repeat(np.arange(len(ok)), n_nodes)
                sel = v[road]
                if self.replication:
                    maxd, simple = simulate_replication(nodes[sel], n_nodes[v], cfg)
                    max_deviation[ok[v]] = maxd
                    path_simple[ok[v]] = simple
                    f1[ok[v]] = np.where(simple, maxd, 0.0)
                else:
                    f1[ok[v]] = simulate(nodes[sel], n_nodes[v], length[v], cfg)
                    max_deviation = f1.copy()
        return Evaluation(
            f1=f1,
            valid=valid,
            reasons=reasons,
            metrics={"max_deviation": max_deviation, "road_length": road_length, **metrics},
        )

    def _reference_rules(self, nodes, n_nodes, valid, reasons, min_radius, cut):
        """The full model's static reference check (``sims.reference.vehicle.before``) on the roads the
        problem's own rules pass: the competition rules on the road as driven; a replication road
        that the builder cut at the map edge is never driven."""
        cfg = self.config
        valid, reasons = valid.copy(), list(reasons)
        offs = np.concatenate([[0], np.cumsum(n_nodes)[:-1]])
        for i in np.flatnonzero(valid):
            if cut is not None and cut[i]:
                valid[i], reasons[i] = False, "road leaves the map: the road builder cut it"
                continue
            road = nodes[offs[i]: offs[i] + n_nodes[i]]
            ok, why = competition_rules(road, cfg.lane_width, cfg.map_size, cfg.margin, cfg.min_radius,
                                        radius=float(min_radius[i]) if self.replication else None)
            if not ok:
                valid[i], reasons[i] = False, why
        return valid, reasons

    def _certified(self, nodes, n_nodes, valid, ok, f1, P) -> dict:
        """F1 of the "certified" objective (``drivers``) for the valid roads, written into ``f1``;
        returns the metrics: both drivers' largest offsets and where the brisk one left the lane."""
        from .drivers import BRISK, CAUTIOUS, certified_score, drive_margins, right_lanes

        brisk, cautious, arc = np.zeros(P), np.zeros(P), np.full(P, np.nan)
        if valid.any():
            road = np.repeat(np.arange(len(n_nodes)), n_nodes)
            sel_nodes, sel_counts = nodes[valid[road]], np.asarray(n_nodes)[valid]
            lane = self.config.lane_width
            lanes = right_lanes(sel_nodes, sel_counts, lane)  # one lane per road for both drivers
            b, a = drive_margins(sel_nodes, sel_counts, lane, BRISK, lanes)
            c, _ = drive_margins(sel_nodes, sel_counts, lane, CAUTIOUS, lanes)
            idx = ok[valid]
            brisk[idx], cautious[idx], arc[idx] = b, c, a
            f1[idx] = np.maximum(certified_score(b, c), 0.0)
        return {"brisk_offset": brisk, "cautious_offset": cautious, "failure_arc": arc}

    def environment(self, scenario: Scenario, start_offset: float = 0.0) -> Road:
        """Build, check and drive one road (even if invalid: ``valid``/``reason`` say so).

        ``start_offset`` shifts the car's start sideways (> 0 = left); 0 for the surrogate's F1.
        """
        cfg = self.config
        row = self.codec.to_row(scenario)
        G, lengths = self.codec.split(row)
        spine, _, nodes, n_nodes = self.roads(G, lengths)
        valid, reasons, length, min_radius = check_roads(nodes, n_nodes, cfg)
        path_simple = True
        if not self.replication:
            maxd, traces = simulate(nodes, n_nodes, length, cfg, offsets=[start_offset], record=True)
            path, deviations, max_deviation = traces[0][:, :2], traces[0][:, 2], float(maxd[0])
        elif _first_half(n_nodes)[0] >= 2 and n_nodes[0] - _first_half(n_nodes)[0] >= 2:
            maxd, simple, traces = simulate_replication(nodes, n_nodes, cfg, offsets=[start_offset], record=True)
            path, deviations, _ = traces[0]
            max_deviation, path_simple = float(maxd[0]), bool(simple[0])
        else:  # too short for the replication car
            path, deviations, max_deviation = np.zeros((0, 2)), np.zeros(0), 0.0
        return Road(
            spine=spine,
            nodes=nodes,
            length=float(length[0]),
            valid=bool(valid[0]),
            reason=reasons[0],
            min_radius=float(min_radius[0]),
            path=path,
            deviations=deviations,
            max_deviation=max_deviation,
            lane_width=cfg.lane_width,
            map_size=cfg.map_size,
            margin=cfg.margin,
            car_path_simple=path_simple,
        )
