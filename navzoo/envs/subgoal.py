"""The global-planner half of a learned robot in multi-room scenes: A* subgoals and geodesic progress.

The paper's robot observes its goal as ``(x_g, y_g, d_g, sin theta_g, cos theta_g)`` and is rewarded
for closing the straight-line distance to it. In an open room (CrowdNav) that is all it needs; in a
home with several rooms or a store with aisles the straight line runs through walls, and a policy
that sees only a 4.8 m occupancy crop cannot know which door leads to the goal. navzoo therefore
offers, as an option of :class:`~navzoo.envs.config.NavConfig`, the usual split of indoor navigation
into a global planner and a learned local policy:

* ``robot_subgoal=L``: the robot's goal features point at a *subgoal*, the farthest point of its A*
  path (planned at reset like every agent's, with the same clearance) that is at most ``L`` m away and
  in line of sight; the path is planned again from where the robot is when no point of it is in sight
  (pushed off course by people). Near the goal the subgoal is the goal itself.
* ``robot_progress="geodesic"``: the progress term of the reward, ``3.2 (d_{t-1} - d_t)``, uses the
  shortest-path distance to the goal through the free space (a Dijkstra field over the occupancy
  grid, evaluated continuously between cells) instead of the straight-line distance, so that a
  detour around a wall is not punished.

:class:`RobotGuide` holds both for a set of robots. A policy trained with subgoals keeps its own
guide (:class:`GuidedPolicy`), so it runs in any navzoo env (the benchmark's scenes included)
whatever that env's own ``robot_subgoal`` setting.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = ["GuidedPolicy", "RobotGuide", "geodesic_distance"]

_NEIGHBOURHOOD = 2  # cells on each side searched for the field's value (5 x 5)


def geodesic_distance(field: np.ndarray, grid: OccupancyGrid, xy: np.ndarray) -> float:
    """Shortest-path distance to a goal at point ``xy``, from its Dijkstra ``field`` over ``grid``'s cells.

    ``min_c field[c] + |xy - centre(c)|`` over the free cells ``c`` of a 5 x 5 neighbourhood: continuous
    in ``xy`` (a minimum of continuous functions), equal to the field at cell centres up to the grid's
    discretisation, and finite next to walls where the cell under ``xy`` itself is inflated away.
    ``inf`` where no cell near ``xy`` reaches the goal.
    """
    rc = grid.world_to_cell(np.asarray(xy, dtype=np.float64).reshape(2))
    h, w = field.shape
    r0, r1 = max(int(rc[0]) - _NEIGHBOURHOOD, 0), min(int(rc[0]) + _NEIGHBOURHOOD + 1, h)
    c0, c1 = max(int(rc[1]) - _NEIGHBOURHOOD, 0), min(int(rc[1]) + _NEIGHBOURHOOD + 1, w)
    if r0 >= r1 or c0 >= c1:
        return float("inf")
    sub = field[r0:r1, c0:c1]
    finite = np.isfinite(sub)
    if not finite.any():
        return float("inf")
    rr, cc = np.mgrid[r0:r1, c0:c1]
    centres = grid.cell_to_world(np.stack([rr[finite], cc[finite]], axis=1))
    return float(np.min(sub[finite] + np.linalg.norm(centres - xy, axis=1)))


class RobotGuide:
    """A* paths, line-of-sight subgoals and geodesic goal distances for ``n`` robots in one static world.

    Args:
        grid: the scene's occupancy grid.
        radii: (n,) robot radii (m).
        lookahead: the subgoal is at most this far from the robot (m).
        clearance: extra inflation when planning, as ``NavConfig.path_clearance`` (falls back to the
            bare radius where a passage is too narrow).
        spacing: spacing of path points (m).
        planners: a dict of :class:`AStarPlanner` by radius to share (an env's own), so that each
            inflated grid is built once; default a private one.
    """

    def __init__(self, grid: OccupancyGrid, radii: np.ndarray, lookahead: float, clearance: float = 0.2,
                 spacing: float = 0.5, planners: dict[float, AStarPlanner] | None = None) -> None:
        if not (np.isfinite(lookahead) and lookahead > 0):
            raise ValueError(f"RobotGuide lookahead must be a finite number > 0 (m), got {lookahead!r}")
        self.grid = grid
        self.radii = np.asarray(radii, dtype=np.float64).reshape(-1)
        self.lookahead = float(lookahead)
        self.clearance = float(clearance)
        self.spacing = float(spacing)
        self._planners: dict[float, AStarPlanner] = {} if planners is None else planners
        self.paths: list[np.ndarray] = []
        self.index = np.zeros(0, dtype=int)
        self.goals = np.zeros((0, 2))
        self.replans = np.zeros(0, dtype=int)
        self._fields: list[np.ndarray | None] = []

    def _planner(self, radius: float) -> AStarPlanner:
        if radius not in self._planners:
            self._planners[radius] = AStarPlanner(self.grid, radius)
        return self._planners[radius]

    def _plan(self, i: int, start: np.ndarray, goal: np.ndarray) -> np.ndarray:
        r = float(self.radii[i])
        path = None
        if self.clearance > 0:
            path = self._planner(r + self.clearance).plan(start, goal, spacing=self.spacing)
            if path is None:  # a passage on the way is too narrow for the clearance: keep it where it fits
                path = self._planner(r).plan_graded(start, goal, self.clearance, spacing=self.spacing)
        if path is None:
            path = self._planner(r).plan(start, goal, spacing=self.spacing)
        if path is None or len(path) == 0:
            return np.asarray(goal, dtype=np.float64).reshape(1, 2)
        path = np.asarray(path, dtype=np.float64)
        if np.linalg.norm(path[-1] - goal) > 1e-9:  # end exactly at the goal (A* ends at its snapped cell)
            path = np.concatenate([path, np.asarray(goal, dtype=np.float64).reshape(1, 2)])
        return path

    def reset(self, pos: np.ndarray, goals: np.ndarray) -> None:
        """New episode: plan every robot's path from ``pos`` (n, 2) to ``goals`` (n, 2)."""
        pos = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        goals = np.asarray(goals, dtype=np.float64).reshape(-1, 2)
        if len(pos) != len(self.radii) or len(goals) != len(self.radii):
            raise ValueError(f"RobotGuide.reset: expected {len(self.radii)} positions and goals, got "
                             f"{len(pos)} and {len(goals)}")
        self.goals = goals.copy()
        self.paths = [self._plan(i, pos[i], goals[i]) for i in range(len(pos))]
        self.index = np.zeros(len(pos), dtype=int)
        self.replans = np.zeros(len(pos), dtype=int)
        self._fields = [None] * len(pos)

    def subgoals(self, pos: np.ndarray, which: np.ndarray | None = None) -> np.ndarray:
        """(m, 2) subgoals of robots ``which`` (default all) at positions ``pos`` (m, 2); advances them."""
        pos = np.asarray(pos, dtype=np.float64).reshape(-1, 2)
        which = np.arange(len(self.radii)) if which is None else np.asarray(which, dtype=int).reshape(-1)
        if len(which) != len(pos):
            raise ValueError(f"RobotGuide.subgoals: {len(which)} robots but {len(pos)} positions")
        out = np.empty((len(which), 2))
        for n, i in enumerate(which):
            sub = self._subgoal(int(i), pos[n])
            if sub is None:  # nothing of the path in sight: plan again from here
                self.paths[i] = self._plan(int(i), pos[n], self.goals[i])
                self.index[i] = 0
                self.replans[i] += 1
                sub = self._subgoal(int(i), pos[n])
            out[n] = sub if sub is not None else self.paths[i][min(self.index[i], len(self.paths[i]) - 1)]
        return out

    def _subgoal(self, i: int, p: np.ndarray) -> np.ndarray | None:
        path = self.paths[i]
        k0 = int(self.index[i])
        d = np.linalg.norm(path[k0:] - p, axis=1)
        near = np.flatnonzero(d <= self.lookahead)
        if near.size == 0:
            return None
        r = float(self.radii[i])
        planner = self._planner(r)
        if self.clearance > 0:
            # A sight line must not run nearer to walls than the path it replaces (plus a tenth of the
            # clearance band): a robot driving straight at its subgoal then does not graze the corner of
            # a door that the path goes through in the middle.
            pen = planner.clearance_penalty(self.clearance)
            rc = self.grid.world_to_cell(np.concatenate([p[None], path[k0:k0 + int(near[-1]) + 1]]))
            h, w = pen.shape
            pt_pen = np.maximum.accumulate(pen[np.clip(rc[:, 0], 0, h - 1), np.clip(rc[:, 1], 0, w - 1)])
        for j in near[::-1]:  # farthest along the path first
            if not planner.line_of_sight(p, path[k0 + j]):
                continue
            if self.clearance > 0 and planner.penalty_along(p, path[k0 + j], self.clearance) > pt_pen[j + 1] + 0.1:
                continue
            # Progress along the path is monotone: never look behind the closest visible point again.
            closest = int(np.argmin(d[: j + 1]))
            self.index[i] = k0 + closest
            return path[k0 + j].copy()
        return None

    def geodesic(self, i: int, xy: np.ndarray) -> float:
        """Shortest-path distance (m) from ``xy`` to robot ``i``'s goal through the free space."""
        field = self._fields[i]
        if field is None:
            field = self._planner(float(self.radii[i])).distance_to(self.goals[i])
            self._fields[i] = field
        return geodesic_distance(field, self.grid, np.asarray(xy, dtype=np.float64))


class GuidedPolicy:
    """A robot policy trained with subgoals (``robot_subgoal``), run in any env: it keeps its own
    :class:`RobotGuide` and writes the subgoal into the robots' goal features before acting.

    In an env whose ``config.robot_subgoal`` already equals the policy's lookahead the observations
    are passed through unchanged (they hold the same subgoal).

    Args:
        policy: the wrapped :class:`~navzoo.agents.policy.ObservationPolicy` (e.g. an SB3 policy).
        lookahead: the subgoal distance the policy was trained with (m).
        layout: ``{key: (start, end, shape)}`` of flat observations (for flat envs).
    """

    def __init__(self, policy: Any, lookahead: float, layout: Mapping[str, tuple[int, int, tuple[int, ...]]]) -> None:
        self.policy = policy
        self.lookahead = float(lookahead)
        self.layout = dict(layout)
        self.name = getattr(policy, "name", "guided")
        self.guide: RobotGuide | None = None
        self._env_id: int | None = None

    @property
    def model(self) -> Any:
        """The wrapped policy's network (an SB3 policy for :func:`~navzoo.agents.robot_train.load_policy`)."""
        return self.policy.model

    def controlled(self, observations: Mapping[str, Any], env: NavEnv | None = None) -> list[str]:
        return self.policy.controlled(observations, env)

    def _passthrough(self, env: NavEnv) -> bool:
        own = env.config.robot_subgoal
        return own is not None and abs(float(own) - self.lookahead) < 1e-9

    def reset(self, env: NavEnv) -> None:
        env = getattr(env, "unwrapped", env)  # a wrapper of navzoo.make: the NavEnv under it
        self.policy.reset(env)
        if self._passthrough(env):
            self.guide = None
            return
        R = env.n_robots
        if self.guide is None or self._env_id != id(env) or self.guide.grid is not env.grid:
            # A new world: new planners (their inflated grids are built once and kept for its episodes).
            self.guide = RobotGuide(env.grid, env.radius[:R], self.lookahead, clearance=env.config.path_clearance,
                                    spacing=env.config.path_spacing)
            self._env_id = id(env)
        self.guide.reset(env.pos[:R], env.goal[:R])

    def act(self, observations: Mapping[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        env = getattr(env, "unwrapped", env)
        from navzoo.envs import observations as obs_terms

        if self._passthrough(env):
            return self.policy.act(observations, env)
        if self.guide is None or self._env_id != id(env):
            raise RuntimeError("GuidedPolicy.act() before reset(env) for this env; call reset(env) first")
        names = self.policy.controlled(observations, env)
        if not names:
            return {}
        idx = np.array([env.agent_index(a) for a in names], dtype=int)
        sub = self.guide.subgoals(env.pos[idx], idx)
        feats = obs_terms.goal_features(env.pos[idx], env.yaw[idx], sub).astype(np.float32)
        new = dict(observations)
        gs, ge, _ = self.layout["goal"]
        for n, a in enumerate(names):
            o = observations[a]
            if isinstance(o, Mapping):
                o = dict(o)
                o["goal"] = feats[n]
            else:
                o = np.array(o, dtype=np.float32, copy=True)
                o[gs:ge] = feats[n]
            new[a] = o
        return self.policy.act(new, env)
