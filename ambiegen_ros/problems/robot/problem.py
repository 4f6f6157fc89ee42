"""The robot case study behind the ``Problem`` interface: ``RobotProblem`` (attribute layouts per
profile, sampling, batch evaluation, one scenario's environment) and ``RobotMap``, the environment
a scenario becomes (the map, the poses, the planned route; a hazards scenario's unmapped obstacles).

The top of the package: it puts the grids, the planners and the route objectives together; issue
48's hazards scenarios (``problems.robot_hazards``) are imported only when a config asks for them.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Sequence

import numpy as np

from ...core.attributes import Categorical, IntRange, ScenarioError
from ...core.problem import Budget, Evaluation, Problem
from ...core.scenario import Scenario
from .config import HAZARD_OBJECTIVES, INFLATION_RULE, NO_PATH, RobotConfig
from .grids import build_grids, inflate
from .planners import astar, batch_path_lengths
from .route import fold_above, narrow_route_metres


@dataclass
class RobotMap:
    """'TC to environment' for the robot: the occupancy map plus the planned A* route.

    ``grid`` is the raw occupancy (walls + border, ``[y, x]``, cell (0, 0)'s corner at (0, 0) m);
    points in metres are cell centres. ``path`` is empty and ``path_length`` 0 without a route.
    """

    grid: np.ndarray
    resolution: float
    start: tuple[int, int]
    goal: tuple[int, int]
    start_m: tuple[float, float]
    goal_m: tuple[float, float]
    path: list[tuple[int, int]] = field(default_factory=list)
    path_length: float = 0.0
    reachable: bool = False
    # hazards scenarios (issue 48): the poses' yaw [rad] (None: the paper's map, facing the route) and
    # what is in the world but not in ``grid`` (``sims.obstacles.Obstacles.to_dict`` form)
    start_yaw: float | None = None
    goal_yaw: float | None = None
    unmapped: dict = field(default_factory=dict)
    # vias (a planner's ComputePathThroughPoses): cells in the order flown through, and their yaw [rad]
    vias: list[tuple[int, int]] = field(default_factory=list)
    via_yaws: list[float] = field(default_factory=list)

    def to_metres(self, cell: Sequence[int]) -> tuple[float, float]:
        return ((cell[0] + 0.5) * self.resolution, (cell[1] + 0.5) * self.resolution)

    @property
    def path_m(self) -> list[tuple[float, float]]:
        return [self.to_metres(c) for c in self.path]

    @property
    def via_poses(self) -> list[tuple[float, float, float]]:
        """The vias as (x, y, yaw) in metres, each cell's centre as for the start and goal."""
        return [(*self.to_metres(c), yaw) for c, yaw in zip(self.vias, self.via_yaws)]


CLEARED = "cleared_cells"  # a scenario's metadata key: map cells made free (a shrunk finding's)


def cleared_cells(metadata: dict, map_size: int) -> np.ndarray | None:
    """The cells a scenario's ``metadata["cleared_cells"]`` frees, as (K, 2) ``[x, y]``; None without.

    The paper's genome cannot remove a wall (wall i lies on row i + 1), so a failing scenario shrunk
    to a minimal map (``ambiegen shrink``) keeps its genome and lists the wall and border cells it
    freed; every map made of it (the message, the world, the pictures) has them free."""
    value = (metadata or {}).get(CLEARED)
    if value is None:
        return None
    bad = ScenarioError(f"metadata.{CLEARED}", "must be a list of [x, y] cells of the map",
                        f"integers 0..{map_size - 1}")
    try:
        cells = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise bad from None
    if cells.size == 0:
        return np.zeros((0, 2), dtype=np.int64)
    if cells.ndim != 2 or cells.shape[1] != 2 or not np.all(np.isfinite(cells)) \
            or not np.all(cells == np.rint(cells)) or not np.all((cells >= 0) & (cells < map_size)):
        raise bad
    return cells.astype(np.int64)


# Attribute domains and lengths per profile. The replication code's generator draws one element
# per level 1..49 (1 + (map_size - 2)) with positions 1..49; it scores any number of levels (a
# missing level is an empty row), so shorter scenarios, like the refined profile's 48, are accepted.
_TYPE = Categorical("type", ("horizontal", "vertical"))
_SIZE = IntRange("size", 5, 15, 1, tolerance=2, unit="m")
REFINED_LAYOUT = ((_TYPE, _SIZE, IntRange("position", 1, 48, 1, tolerance=2, unit="m")), 48, 48)
REPLICATION_LAYOUT = ((_TYPE, _SIZE, IntRange("position", 1, 49, 1, tolerance=2, unit="m")), 1, 49)


class RobotProblem(Problem):
    """Walls in a room; the longer the shortest route, the harder the map for the robot.

    The class attributes are the refined layout; an instance takes its profile's from ``layout()``.
    """

    name = "robot"
    attributes, m_min, m_max = REFINED_LAYOUT
    f1_label = "A* path length [m]"
    paper_budget = Budget(100, 50, 20000)
    Config = RobotConfig
    # refined: a diagonal step needs both orthogonal neighbours free, so a path keeps half a cell
    # (0.5 m) from every wall, more than the reference's clearance route needs (0.36 m; 40 of 40
    # sampled refined maps have one); the replication planner squeezes between walls touching at a corner
    certified_search = {"profile": "refined"}

    def __init__(self, config=None, **overrides):
        # Build the Config once from all given values, so profile-dependent defaults resolve for
        # the profile asked for (Config() followed by replace(profile=...) would not).
        if config is None:
            config = {}
        if isinstance(config, dict):
            config, overrides = {**config, **overrides}, {}
        elif overrides.get("profile", config.profile) != config.profile:
            config = config.for_profile(overrides.pop("profile"))
        super().__init__(config, **overrides)
        if self.config.objective == "narrow":
            self.f1_label = "narrow route [m]"
        elif self.config.objective == "threat":
            self.f1_label = "hazards' threat (obstacle on route + person meeting + goal turn, by narrowness)"
        elif self.config.objective == "block":
            self.f1_label = "a person shutting the way when the robot comes (closure x time left / 30 s)"
        walls = 48 if self.hazards else self.m_max  # hazards: 48 wall rows, then the start, goal and hazards
        rows = walls + (2 if self.profile == "refined" else 1)  # replication: levels up to the top border
        if self.config.map_size != rows:
            raise ScenarioError("config.map_size", f"{self.config.map_size} does not match one row per element",
                                str(rows))

    def layout(self):
        if self.config.scenario == "hazards":
            from ..robot_hazards import ATTRIBUTES, FIRST_HAZARD

            return ATTRIBUTES, FIRST_HAZARD, FIRST_HAZARD + int(self.config.max_hazards) + int(self.config.max_vias)
        return REFINED_LAYOUT if self.profile == "refined" else REPLICATION_LAYOUT

    @property
    def hazards(self) -> bool:
        """A hazards scenario (issue 48: ``problems.robot_hazards``), not the paper's map of walls."""
        return self.config.scenario == "hazards"

    def canonical(self, G: np.ndarray, lengths: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        if self.hazards:
            from ..robot_hazards import canonical

            return canonical(G, lengths)
        return G, lengths

    def search_operators(self, settings: Any) -> dict[str, Any]:
        if self.hazards:  # walls stay walls, the start stays the start: a mutation within each kind
            from ..robot_hazards_operators import HazardMutation

            return {"mutation": HazardMutation(prob=settings.mutation_rate)}
        return {}

    def loop_f1(self, outcome: Any) -> float:
        """``loop_objective: pace``: a pass's seconds per metre of its clearance route; a failure
        scores its time limit's pace, above any pass of the map. The time alone climbs towards long
        routes (and NavFn's known cap); so does the time over the time limit, whose 300 s floor
        makes it the time on most maps (Spearman 0.95 with the route on a GA run of DWB). The pace
        of MPPI's near misses was 2.75-5.05 s/m against 2.19-3.57 for plain passes, and of a DWB
        failure 7.9 (docs/external_sut.md, "In the loop"). ``time_share`` stays, so that the bags
        of the campaign that measured it replay. A planner's answer (``--stack planner``) has no
        time: ``plan_f1`` scores it, whatever ``loop_objective`` says."""
        m = outcome.metrics
        if "plan_oracle" in m:  # a planner's answer (goal_mode plan): no time, no route driven
            return plan_f1(outcome.failed, m.get("plan_clearance_m"))
        if self.config.loop_objective == "time":
            return super().loop_f1(outcome)
        try:
            spent = float(m["time_limit"] if outcome.failed else m["time"])
            route = m.get("route_length_m") or m.get("route_length")  # a stack's judge | our full model
            per = float(m["time_limit"] if self.config.loop_objective == "time_share" else route or 0.0)
            value = spent / per
        except (KeyError, TypeError, ValueError, ZeroDivisionError):
            return 0.0  # no route or no time on record: nothing to climb
        return value if math.isfinite(value) and value > 0 else 0.0

    # --- sampling ----------------------------------------------------------------------
    def sample(self, n: int, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
        """Fixed length m_max (48 | 49); type by a 2-state Markov chain (or uniform), size/position uniform.

        With P(stay) = 0.5 (both profiles) the chain draws every type independently, as the
        replication code's generator does.
        """
        if self.hazards:
            from ..robot_hazards import N_WALLS, sample

            walls = self._sample_walls(n, N_WALLS, REFINED_LAYOUT[0], rng)
            return sample(walls, self.config, rng)
        G = self._sample_walls(n, self.m_max, self.attributes, rng)
        return G, np.full(n, self.m_max, dtype=int)

    def _sample_walls(self, n: int, m: int, attributes, rng: np.random.Generator) -> np.ndarray:
        G = np.zeros((n, m, len(attributes)))
        if self.config.sampling == "markov":
            first = rng.integers(0, 2, size=(n, 1))
            switch = rng.random((n, m - 1)) >= self.config.type_p_stay
            G[:, :, 0] = (first + np.concatenate([np.zeros((n, 1), int), np.cumsum(switch, axis=1)], axis=1)) % 2
        else:
            G[:, :, 0] = attributes[0].sample(rng, (n, m))
        G[:, :, 1] = attributes[1].sample(rng, (n, m))
        G[:, :, 2] = attributes[2].sample(rng, (n, m))
        return G

    # --- fitness -------------------------------------------------------------------------
    def planning_grids(self, G: np.ndarray, lengths: np.ndarray,
                       cleared: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """Raw occupancy and the radius-inflated grid the planners use (the mapped walls only),
        with ``cleared`` cells ((K, 2) x, y: ``cleared_cells``) made free in every grid first."""
        if self.hazards:
            from ..robot_hazards import N_WALLS

            G, lengths = np.asarray(G)[:, :N_WALLS, :3], np.full(len(G), N_WALLS)
        grids = build_grids(G, lengths, self.config)
        if cleared is not None and len(cleared):
            grids[:, cleared[:, 1], cleared[:, 0]] = False
        planning = inflate(grids, self.config.robot_radius, self.config.resolution, INFLATION_RULE[self.profile])
        if self.profile == "replication":  # its planner never checks the start: the robot leaves it
            sx, sy = self.config.start
            planning[:, sy, sx] = False
        return grids, planning

    def evaluate(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        G = np.asarray(G, dtype=float)
        lengths = np.asarray(lengths, dtype=int).reshape(-1)
        if self.hazards:
            return self._evaluate_hazards(G, lengths)
        grids, planning = self.planning_grids(G, lengths)
        cells = batch_path_lengths(planning, self.config.start, self.config.goal, self.config.diagonal,
                                   engine=self.config.engine)
        in_domain = self.codec.in_domain(G, lengths)
        valid = np.isfinite(cells) & in_domain
        length = np.where(valid, cells * self.config.resolution, 0.0)
        f1 = fold_above(length, self.config.route_cap)
        metrics = {"path_length": length}
        if self.config.objective == "narrow":
            # past the cap a map keeps the same share of its narrow metres as of its folded length
            narrow = np.array([narrow_route_metres(grids[i], planning[i], self.config) if ok else 0.0
                               for i, ok in enumerate(valid.tolist())])
            f1 = narrow * np.divide(f1, length, out=np.zeros_like(f1), where=length > 0)
            metrics["narrow_m"] = narrow
        reasons = [None if ok else (NO_PATH if dom else self.codec.domain_reason(G[i], int(lengths[i])))
                   for i, (ok, dom) in enumerate(zip(valid.tolist(), in_domain.tolist()))]
        wall_cells = grids[:, 1:-1, 1:-1].sum(axis=(1, 2))
        return Evaluation(f1, valid, reasons, {**metrics, "wall_cells": wall_cells})

    # --- environment ---------------------------------------------------------------------
    def parse(self, data: dict[str, Any]) -> Scenario:
        scenario = self.codec.validate(data)
        cleared_cells(scenario.metadata, self.config.map_size)  # one clear line now, not at the map's making
        return scenario

    def map_parts(self, scenario: Scenario) -> list[tuple[str, np.ndarray]]:
        """The scenario's map as the parts a shrink takes away: each wall's cells (``wall <i>``), then
        each side of the border, as (K, 2) ``[x, y]``; cells already cleared are left out, a cell of
        two walls is in both, and an empty part is dropped."""
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        walls = min(int(lengths[0]), G.shape[1])
        if self.hazards:
            from ..robot_hazards import N_WALLS

            walls = N_WALLS
        G = np.asarray(G[0, :walls, :3], dtype=float)
        alone = np.repeat(G[None], max(walls, 1), axis=0)  # batch i: wall i alone (the others of no kind)
        for i in range(walls):
            alone[i, np.arange(walls) != i, 0] = -1
        grids = build_grids(alone, np.full(len(alone), walls), self.config)
        n = self.config.map_size
        border = np.zeros((n, n), dtype=bool)
        border[0, :] = border[-1, :] = border[:, 0] = border[:, -1] = True
        cleared = cleared_cells(scenario.metadata, n)
        present = np.ones((n, n), dtype=bool)
        if cleared is not None and len(cleared):
            present[cleared[:, 1], cleared[:, 0]] = False
        sides = {"border south": np.s_[0, :], "border north": np.s_[-1, :], "border west": np.s_[1:-1, 0],
                 "border east": np.s_[1:-1, -1]}
        masks = [(f"wall {i}", grids[i] & ~border) for i in range(walls)]
        for name, side in sides.items():
            mask = np.zeros((n, n), dtype=bool)
            mask[side] = True
            masks.append((name, mask))
        return [(name, np.argwhere(mask & present)[:, ::-1]) for name, mask in masks if (mask & present).any()]

    def environment(self, scenario: Scenario) -> RobotMap:
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        cleared = cleared_cells(scenario.metadata, self.config.map_size)
        if self.hazards:
            return self._hazard_environment(G[0], int(lengths[0]), cleared)
        grids, planning = self.planning_grids(G, lengths, cleared)
        length, path = astar(planning[0], self.config.start, self.config.goal, self.config.diagonal)
        res = self.config.resolution
        out = RobotMap(grids[0], res, self.config.start, self.config.goal, (0.0, 0.0), (0.0, 0.0))
        out.start_m, out.goal_m = out.to_metres(self.config.start), out.to_metres(self.config.goal)
        if math.isfinite(length):
            out.path, out.path_length, out.reachable = path, length * res, True
        return out

    # --- hazards scenarios (issue 48; ``problems.robot_hazards``) ------------------------------
    def _evaluate_hazards(self, G: np.ndarray, lengths: np.ndarray) -> Evaluation:
        """The kinds in their places, a route on the mapped walls (F1: its length, the paper's
        objective), hazards clear of the start and goal, people with room to walk. Metrics count
        the hazards by kind. With vias every leg (start -> via 1 -> ... -> goal) needs a route on
        the planning grid (``robot_radius``: permissive in the planner configs), else the scenario
        is invalid and never sent; F1 is then the legs' length together, and hazards still sit on
        the start -> goal route."""
        from .. import robot_hazards as hz

        cfg = self.config
        settings = hz.HazardSettings.of(cfg)
        grids, planning = self.planning_grids(G, lengths)
        in_domain = self.codec.in_domain(G, lengths)
        P = len(G)
        f1, valid, route_m = np.zeros(P), np.zeros(P, dtype=bool), np.zeros(P)
        reasons: list[str | None] = [None] * P
        counts = {name: np.zeros(P) for name in ("boxes", "posts", "people")}
        for i in range(P):
            m = int(lengths[i])
            reason = None if in_domain[i] else self.codec.domain_reason(G[i], m)
            reason = reason or hz.kind_reason(G[i], m, cfg)
            if reason is None:
                layout = hz.decode(G[i], m, settings)
                length, path = astar(planning[i], layout.start, layout.goal, cfg.diagonal)
                legs, reason = legs_length(planning[i], layout, cfg.diagonal) if layout.vias else (length, None)
                if not math.isfinite(length):
                    reason = NO_PATH
                elif reason is None:
                    route = hz.PlacementRoute((np.asarray(path, dtype=float) + 0.5) * cfg.resolution)
                    posts, boxes, people = hz.obstacles_on(route, layout, settings, grids[i], cfg.resolution)
                    reason = hz.placement_reason(layout, posts, boxes, people, settings, cfg.resolution)
                    counts["boxes"][i], counts["posts"][i], counts["people"][i] = len(boxes), len(posts), len(people)
                    f1[i] = route_m[i] = legs * cfg.resolution
                    if cfg.objective in HAZARD_OBJECTIVES and reason is None:
                        f1[i] = hz.features(route, layout, posts, boxes, people, grids[i], cfg.resolution,
                                            cfg.threat_speed)[cfg.objective]
            if reason is None:
                valid[i] = True
            else:
                reasons[i], f1[i] = reason, 0.0
        metrics = {"path_length": np.where(valid, route_m, 0.0), **counts}
        if cfg.objective in HAZARD_OBJECTIVES:
            metrics[cfg.objective] = f1.copy()
        return Evaluation(f1, valid, reasons, metrics)

    def _hazard_environment(self, cells: np.ndarray, length: int, cleared: np.ndarray | None = None) -> "RobotMap":
        """The mapped walls, the poses, the route hazards sit on (``path``) and the unmapped
        obstacles (``unmapped``)."""
        from .. import robot_hazards as hz

        cfg = self.config
        settings = hz.HazardSettings.of(cfg)
        grids, planning = self.planning_grids(cells[None], np.array([length]), cleared)
        layout = hz.decode(cells, length, settings)
        res = cfg.resolution
        out = RobotMap(grids[0], res, layout.start, layout.goal, (0.0, 0.0), (0.0, 0.0),
                       start_yaw=layout.start_yaw, goal_yaw=layout.goal_yaw, vias=layout.vias, via_yaws=layout.via_yaws)
        out.start_m, out.goal_m = out.to_metres(layout.start), out.to_metres(layout.goal)
        route_len, path = astar(planning[0], layout.start, layout.goal, cfg.diagonal)
        if math.isfinite(route_len):
            out.path, out.path_length, out.reachable = path, route_len * res, True
            route = hz.PlacementRoute((np.asarray(path, dtype=float) + 0.5) * res)
            posts, boxes, people = hz.obstacles_on(route, layout, settings, grids[0], res)
            out.unmapped = {"posts": posts.tolist(), "boxes": boxes.tolist(), "people": people}
        return out

    def via_poses(self, scenario: Scenario) -> list[tuple[float, float, float]]:
        """A scenario's vias as (x, y, yaw) in metres, in the order flown through: each cell's centre,
        as the scenario message's start and goal (``RobotMap.via_poses`` without making the map);
        [] where the config has no vias. The message carries map, start and goal only: a planner's
        judge reads the vias here, from the scenario its ``meta.scenario_json`` holds."""
        if not self.hazards or not self.config.max_vias:
            return []
        from .. import robot_hazards as hz

        G, lengths = self.codec.split(self.codec.to_row(scenario))
        res, cells = self.config.resolution, G[0]
        return [(float((cells[i, hz.POSITION] + 0.5) * res), float((cells[i, hz.ROW] + 0.5) * res),
                 math.radians(float(cells[i, hz.HEADING]))) for i in hz.via_rows(cells, int(lengths[0]))]

    def hazard_features(self, scenario: Scenario, speed: float | None = None) -> dict[str, float]:
        """``robot_hazards.features`` of one hazards scenario (what its hazards do to the route), with
        the robot at ``speed`` (m/s; default: the config's ``threat_speed``)."""
        from .. import robot_hazards as hz

        env = self.environment(scenario)
        if not env.reachable:
            return {}
        G, lengths = self.codec.split(self.codec.to_row(scenario))
        layout = hz.decode(G[0], int(lengths[0]), hz.HazardSettings.of(self.config))
        u = env.unmapped
        return hz.features(hz.PlacementRoute(np.asarray(env.path_m)), layout, np.asarray(u["posts"]).reshape(-1, 3),
                           np.asarray(u["boxes"]).reshape(-1, 4), u["people"], env.grid, env.resolution,
                           self.config.threat_speed if speed is None else speed)


def legs_length(planning: np.ndarray, layout: Any, diagonal: str) -> tuple[float, str | None]:
    """The A* length (cells) of start -> via 1 -> ... -> goal, leg by leg, and why not (the first
    leg without a route) or None."""
    ends = [layout.start, *layout.vias, layout.goal]
    names = ["the start"] + [f"via {k + 1}" for k in range(len(layout.vias))] + ["the goal"]
    total = 0.0
    for k, (a, b) in enumerate(zip(ends, ends[1:])):
        length, _ = astar(planning, a, b, diagonal)
        if not math.isfinite(length):
            return math.inf, f"no path from {names[k]} to {names[k + 1]}"
        total += length
    return total, None


PLAN_CLEARANCE_SCALE_M = 0.2  # a path this close to a lethal cell's centre scores 1/e of a touching one


def plan_f1(failed: bool, clearance_m: Any) -> float:
    """F1 of a planner's answer in the loop: a finding (an oracle of ``sims.plans`` flagged it) 2,
    above any path that held; a path that held exp(-clearance / 0.2 m) in (0, 1], climbing towards
    paths that pass close to lethal cells (where a footprint or a smoother's shortcut collides); a
    path far from every wall, or none, 0."""
    if failed:
        return 2.0
    try:
        value = math.exp(-float(clearance_m) / PLAN_CLEARANCE_SCALE_M)
    except (TypeError, ValueError):
        return 0.0
    return value if math.isfinite(value) else 0.0
