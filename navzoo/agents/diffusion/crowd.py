"""The ``diffusion`` crowd: pedestrian paths sampled from the trajectory diffusion model, in the loop.

Every ``replan_s`` seconds (2 s) all pedestrians of a world are planned in one batch:

1. each person's last 8 positions at the model's step (0.4 s, kept by :meth:`DiffusionCrowd.observe`)
   and those of its 16 nearest neighbours within 10 m (people and, when people see them, robots)
   are moved into the person's agent frame with :func:`navzoo.forecast.data.normalize`, exactly as
   the training windows were;
2. the occupancy crop of the scene around the person (8 m, 32 cells, the same frame) conditions the
   model, and the scene's distance field on the same crop feeds the wall guidance;
3. ``n_samples`` futures (12 steps = 4.8 s) are drawn by DDIM (a goal-conditioned model, ``cfg.goal``,
   gets that waypoint as its goal) with "clean" guidance: every step is pulled toward the A* path
   point ``v_pref x t`` ahead (``path_weight``), the end point
   is pulled to the point of the person's A* path that lies ``v_pref x 4.8 s`` ahead (the sparse
   global waypoint), and samples are pushed off other people's current plans and off walls; both path
   points are measured from the nearest path point the person sees, and lie no farther along the path than
   it stays in sight (``path_in_sight``, :func:`_ahead_from_nearest`), unless that is nearer than the person
   walks before its next plan (``hold_floor_s``);
4. of each person's samples the one of lowest guidance cost is kept, in world coordinates.

Kinematic pedestrians take the plan as their preferred velocity (:meth:`preferred_velocities`:
toward the plan's point 0.8 s ahead, at the plan's pace) and the social force model keeps their
bodies off walls and each other between plans (the :class:`navzoo.agents.crowd.CrowdPolicy`
``"diffusion"`` model); :meth:`velocities` walks the plan exactly instead. AMP pedestrians get the
plan as their target trajectory (:meth:`plan_positions`). People who stand still with no history get a walking-in history along their
path, so that the first plan does not start from rest.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from navzoo.agents.diffusion.guidance import (
    agent_collision_cost,
    combine,
    map_collision_cost,
    path_cost,
    smoothness_cost,
    target_cost,
)
from navzoo.agents.diffusion.model import TrajectoryDiffusion
from navzoo.agents.orca import OrcaParams
from navzoo.forecast import data as fdata

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv
    from navzoo.world.occupancy import OccupancyGrid

__all__ = ["DiffusionCrowd", "StallSwitch", "default_model_dir", "model_dir"]

MODEL_DT = 0.4  # s per model step (ETH/UCY protocol)
#: ORCA of the diffusion crowd's kinematic bodies with ``NavConfig.diffusion_walker="orca"``: the plans already keep
#: people apart, so the walker looks 1.5 s ahead for people and 0.5 s for walls (ORCA's defaults, 5 s each, stall the
#: crowd in navzoo's rooms and doors; docs/crowd.md, "An ORCA walker").
ORCA_WALKER = OrcaParams(time_horizon=1.5, time_horizon_obst=0.5)
#: m added to each person's radius inside the ORCA walker: ORCA holds discs exactly touching, which the contact counts
#: (centres closer than two radii, the centre within a radius of a wall) would count as contacts.
ORCA_WALKER_MARGIN = 0.05
MAP_EXTENT = 8.0  # m, side of the occupancy / distance crops
ACCEL_LIMIT = 1.0  # m/s², largest rise of pace along a physics body's target path (plan_positions)
AMP_SPEED_FACTOR = 1.0  # x v_pref: the fastest pace along a physics body's target path
TURN_STEP_DEG = 30.0  # past_goal_turn_deg: the turns tried past a goal, in steps of this many degrees
BODY_MARGIN = 0.0  # m added to each physics body's radius in the people guidance (0.1 measured no better)
SIGHT_CLEARANCE = 0.05  # m from obstacles that a line of sight keeps (the distance field has 0.1 m cells)
SIGHT_STEP = 0.25  # m between the path points tested for sight


class StallSwitch:
    """Who of the diffusion crowd's kinematic bodies walks with social force under the ``"hybrid"`` walker
    (``NavConfig.diffusion_walker="hybrid"``): ORCA carries everybody along their plans, except the people it holds
    still. A person is *stalled* while it wants to move (preferred speed above ``min_pref``) and ORCA gives it less
    than ``stall_frac`` of that speed; after ``patience`` s stalled it walks with social force, which squeezes past
    where ORCA's strict no-overlap rule deadlocks (two flows in a 1 m door), for ``hold`` s from the last time it
    was stalled that long. Defaults chosen on the doorway and the lobby (docs/crowd.md, "A hybrid walker").

    Call :meth:`update` once per control step; calls at the same time as the last one do not advance the timers,
    and an earlier time (a new episode) starts them again.
    """

    def __init__(self, n: int, stall_frac: float = 0.3, min_pref: float = 0.3, patience: float = 1.0,
                 hold: float = 2.0) -> None:
        for name, v in (("stall_frac", stall_frac), ("min_pref", min_pref), ("patience", patience), ("hold", hold)):
            if not (isinstance(v, (int, float)) and np.isfinite(v) and v >= 0):
                raise ValueError(f"StallSwitch.{name} must be a finite number >= 0, got {v!r}")
        self.n = int(n)
        self.stall_frac, self.min_pref, self.patience, self.hold = stall_frac, min_pref, patience, hold
        self.reset()

    def reset(self) -> None:
        self.stalled_s = np.zeros(self.n)  # how long each person has been stalled, s
        self.sfm_until = np.full(self.n, -np.inf)  # social force until this time
        self.last_t: float | None = None
        self.use = np.zeros(self.n, dtype=bool)  # the last answer of update

    def update(self, t: float, dt: float, v_orca: np.ndarray, pref: np.ndarray) -> np.ndarray:
        """(n,) bool: who walks with social force in the step from time ``t`` (the control period ``dt``), given
        ORCA's velocities ``v_orca`` and the preferred velocities ``pref`` ((n, 2) each)."""
        if v_orca.shape != (self.n, 2) or pref.shape != (self.n, 2):
            raise ValueError(f"StallSwitch of {self.n} people got velocities of shapes {v_orca.shape}, {pref.shape}")
        if self.last_t is not None and t < self.last_t:
            self.reset()
        if self.last_t is not None and t == self.last_t:
            return self.use.copy()
        self.last_t = t
        want = np.linalg.norm(pref, axis=1)
        stalled = (want > self.min_pref) & (np.linalg.norm(v_orca, axis=1) < self.stall_frac * want)
        self.stalled_s = np.where(stalled, self.stalled_s + dt, 0.0)
        self.sfm_until[self.stalled_s >= self.patience] = t + self.hold
        self.use = t < self.sfm_until
        return self.use.copy()


def default_model_dir() -> Path:
    """``$NAVZOO_DIFFUSION_MODEL`` when set (as for ``navzoo eval forecast``), else the shipped model
    ``policies/trajectory_diffusion``."""
    import os

    import policies

    env_dir = os.environ.get("NAVZOO_DIFFUSION_MODEL")
    return Path(env_dir) if env_dir else Path(list(policies.__path__)[0]) / "trajectory_diffusion"


def model_dir(model: str | Path | None = None) -> Path:
    """The folder of an exported trajectory diffusion model (``model``, or :func:`default_model_dir` for None);
    FileNotFoundError naming it when it lacks ``model.pt`` or ``config.json``."""
    folder = default_model_dir() if model is None else Path(model)
    if not (folder / "model.pt").is_file() or not (folder / "config.json").is_file():
        raise FileNotFoundError(
            f"no trajectory diffusion model in {folder} (model.pt + config.json); train one with "
            "`navzoo train diffusion` (docs/crowd.md) or pass its directory")
    return folder


def _ahead_on_path(path: np.ndarray, pos: np.ndarray, distance: float | np.ndarray,
                   extend: bool = False) -> np.ndarray:
    """The point ``distance`` metres along ``[pos] + path`` ((2,), or (D, 2) for D distances); if the
    path is shorter, its end, or with ``extend`` the point that far along the line through the
    path's last segment, beyond its end."""
    pts = np.vstack([pos[None], path])
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    d = np.atleast_1d(np.asarray(distance, dtype=float))
    out = np.repeat(pts[-1][None], d.size, axis=0)
    inside = d < cum[-1]
    if inside.any():
        k = np.searchsorted(cum, d[inside], side="right") - 1
        f = (d[inside] - cum[k]) / np.maximum(seg[k], 1e-9)
        out[inside] = pts[k] + f[:, None] * (pts[k + 1] - pts[k])
    nz = np.flatnonzero(seg > 1e-9)
    if extend and nz.size:
        k = nz[-1]
        out[~inside] += (d[~inside] - cum[-1])[:, None] * (pts[k + 1] - pts[k]) / seg[k]
    return out[0] if np.ndim(distance) == 0 else out


def _nearest_on_polyline(pts: np.ndarray, pos: np.ndarray,
                         sight: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None) -> tuple[int, float, np.ndarray]:
    """Segment index, fraction along it and the point of the polyline ``pts`` nearest to ``pos``
    (the farthest along on ties). With ``sight`` (``sight(pos, points (S, 2)) -> (S,) bool``, e.g.
    :func:`_in_sight`), the nearest point that ``pos`` sees: the nearest of all when it sees none."""
    a, ab = pts[:-1], np.diff(pts, axis=0)
    f = np.clip(np.sum((pos - a) * ab, axis=1) / np.maximum(np.sum(ab * ab, axis=1), 1e-12), 0.0, 1.0)
    proj = a + f[:, None] * ab
    d = np.linalg.norm(proj - pos, axis=1)
    if sight is not None:
        seen = np.asarray(sight(pos, proj), dtype=bool)
        if seen.any():
            d = np.where(seen, d, np.inf)
    k = int(np.flatnonzero(d <= d.min() + 1e-9)[-1])
    return k, float(f[k]), proj[k]


def _in_sight(env: NavEnv, clearance: float = SIGHT_CLEARANCE, step: float = 0.05
              ) -> Callable[[np.ndarray, np.ndarray], np.ndarray]:
    """``sight(pos, points (S, 2)) -> (S,) bool``: whether the straight line from ``pos`` to each point keeps
    ``clearance`` from the scene's obstacles (the distance field of ``env.grid``, sampled every ``step`` m)."""

    def sight(pos: np.ndarray, points: np.ndarray) -> np.ndarray:
        points = np.asarray(points, dtype=float).reshape(-1, 2)
        n = max(1, int(np.ceil(np.max(np.linalg.norm(points - pos, axis=1), initial=0.0) / step)))
        f = np.linspace(0.0, 1.0, n + 1)
        line = pos[None, None, :] + f[None, :, None] * (points - pos)[:, None, :]  # (S, n+1, 2)
        return (env.grid.distance_at(line) >= clearance).all(axis=1)

    return sight


def _ahead_from_nearest(path: np.ndarray, start: int, pos: np.ndarray, distance: float | np.ndarray,
                        extend: bool = False,
                        sight: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                        hold_in_sight: bool = True, hold_floor: float = 0.0,
                        floor_in_sight: bool = False, floor_ray: bool = False) -> np.ndarray:
    """The point ``distance`` metres ahead (or the points, for an array of distances) along the A*
    ``path`` from the point of the path nearest to ``pos``, searched from the segment that ends at
    waypoint ``start`` (the env's current one) on; with ``sight`` (:func:`_in_sight`), from the nearest point
    that ``pos`` sees (:func:`_nearest_on_polyline`).

    Plans stray from the path more than the rule-based crowds, so a person often passes a waypoint
    outside the env's waypoint tolerance and its waypoint index stays behind: measuring from the
    current waypoint would then put the target behind the person. A person beside a wall is often nearer
    to a later leg of its path on the wall's other side than to the leg it walks: measured from there, the
    targets pull it into the wall (``sight`` keeps them on its side; docs/crowd_log.md, "Path points in sight").
    With ``sight`` and ``hold_in_sight`` the points also lie no farther along the path than it stays in sight of
    ``pos`` (tested every :data:`SIGHT_STEP` m), or no nearer than ``hold_floor`` m along it: round a corner, the
    next plan goes on. With ``floor_in_sight`` the floor reaches only to a path point that ``pos`` sees again (the
    path past a pillar), the farthest such point up to ``hold_floor`` m; where the path stays hidden (round the
    jamb of a door or a wall's end) the points stay where it leaves sight. With ``floor_ray`` the points past the
    floor's reach go on where the path stays hidden too, but along the line of sight from ``pos`` through the last
    path point in sight (through a door, past a wall's end) instead of along the hidden path, as far as that line
    stays in sight. A person who sees no point of its path gets the points as without ``sight``.
    """
    pts = np.vstack([pos[None], path]) if len(path) == 1 else path
    first = max(0, start - 1) if len(path) > 1 else 0
    if len(pts) - first < 2:
        return _ahead_on_path(path[start:], pos, distance, extend)
    k, _, proj = _nearest_on_polyline(pts[first:], pos, sight)
    rest = pts[first + k + 1:]
    if hold_in_sight and sight is not None and sight(pos, proj[None])[0]:  # no farther than the path stays in sight
        d = np.asarray(distance, dtype=float)
        probe = np.arange(SIGHT_STEP, float(np.max(d, initial=0.0)) + SIGHT_STEP, SIGHT_STEP)
        if probe.size:
            seen = np.asarray(sight(pos, _ahead_on_path(rest, proj, probe, extend).reshape(-1, 2)), dtype=bool)
            if not seen.all():
                first_hidden = int(np.argmin(seen))
                held = probe[first_hidden - 1] if first_hidden > 0 else 0.0
                floor = hold_floor
                if (floor_in_sight or floor_ray) and hold_floor > held:
                    floor_seen = bool(sight(pos, _ahead_on_path(rest, proj, hold_floor, extend)[None])[0])
                    if floor_ray and not floor_seen:
                        return _ray_past_sight(rest, proj, pos, d, held, hold_floor - held, extend, sight)
                    back = probe[(probe <= hold_floor) & seen]
                    floor = hold_floor if floor_seen else (float(back.max()) if back.size else 0.0)
                distance = np.minimum(d, max(held, floor))
    return _ahead_on_path(rest, proj, distance, extend)


def _ray_past_sight(rest: np.ndarray, proj: np.ndarray, pos: np.ndarray, d: np.ndarray, held: float, reach: float,
                    extend: bool, sight: Callable[[np.ndarray, np.ndarray], np.ndarray]) -> np.ndarray:
    """The points ``d`` metres ahead along the path (``rest`` from ``proj``) up to ``held`` metres, where the path
    leaves the sight of ``pos``; past it, on along the straight line from ``pos`` through that point, up to ``reach``
    metres beyond it and no farther than the line stays in sight (tested every :data:`SIGHT_STEP` m)."""
    last = _ahead_on_path(rest, proj, held, extend)
    u = last - pos
    norm = float(np.linalg.norm(u))
    run = 0.0
    if norm > 1e-6 and reach > 0:
        u = u / norm
        probe = np.append(np.arange(SIGHT_STEP, reach, SIGHT_STEP), reach)
        blocked = np.flatnonzero(~np.asarray(sight(pos, last[None] + probe[:, None] * u[None]), dtype=bool))
        k = int(blocked[0]) if blocked.size else probe.size
        run = float(probe[k - 1]) if k > 0 else 0.0
    return _ahead_on_path(rest, proj, np.minimum(d, held), extend) + np.clip(d - held, 0.0, run)[..., None] * u


def _clip_to_free(env: NavEnv, start: np.ndarray, end: np.ndarray, clearance: float, step: float = 0.1) -> np.ndarray:
    """(B, 2) the last point of each segment ``start -> end`` before the first point closer than
    ``clearance`` to an obstacle (``start`` itself when that is already too close)."""
    n = max(1, int(np.ceil(np.max(np.linalg.norm(end - start, axis=1), initial=0.0) / step)))
    f = np.linspace(0.0, 1.0, n + 1)
    pts = start[:, None, :] + f[None, :, None] * (end - start)[:, None, :]  # (B, n+1, 2)
    free = env.grid.distance_at(pts) >= clearance
    free[:, 0] = True
    k = np.where(free.all(axis=1), n, np.argmin(free, axis=1) - 1)  # last free sample before the first blocked
    return pts[np.arange(len(start)), k]


def _freest_extension(env: NavEnv, start: np.ndarray, end: np.ndarray, clearance: float,
                      max_turn_deg: float) -> np.ndarray:
    """(B, 2) like :func:`_clip_to_free`, but the segment ``start -> end`` may turn about ``start`` by up to
    ``max_turn_deg`` either way, in steps of :data:`TURN_STEP_DEG`: the turn that keeps the longest free run
    wins, the smallest turn on ties (within 5 %). An extension past a goal beside furniture then bends along the
    free side instead of ending at once."""
    d = end - start
    best = _clip_to_free(env, start, end, clearance)
    run = np.linalg.norm(best - start, axis=1)
    steps = int(np.floor(max_turn_deg / TURN_STEP_DEG + 1e-9))
    for a in np.deg2rad(TURN_STEP_DEG * np.array([k * sign for k in range(1, steps + 1) for sign in (1, -1)])):
        c, s = np.cos(a), np.sin(a)
        turned = start + np.stack([c * d[:, 0] - s * d[:, 1], s * d[:, 0] + c * d[:, 1]], axis=1)
        cand = _clip_to_free(env, start, turned, clearance)
        r = np.linalg.norm(cand - start, axis=1)
        better = r > 1.05 * run
        best[better], run[better] = cand[better], r[better]
    return best


def ramped_distances(v0: np.ndarray, v_pref: np.ndarray, accel: float, times: np.ndarray) -> np.ndarray:
    """(B, T) distances walked in ``times`` (T,) seconds by people who start at speed ``v0`` (B,) and change it
    toward ``v_pref`` (B,) at ``accel`` m/s² (then hold it); ``accel`` 0 or less: ``v_pref x t`` (no ramp)."""
    v0 = np.asarray(v0, dtype=float)[:, None]
    v = np.asarray(v_pref, dtype=float)[:, None]
    t = np.asarray(times, dtype=float)[None, :]
    if not accel > 0:
        return v * t
    a = np.where(v >= v0, accel, -accel)
    t_r = np.abs(v - v0) / accel  # seconds to reach v_pref
    tt = np.minimum(t, t_r)
    return v0 * tt + 0.5 * a * tt ** 2 + v * np.maximum(t - t_r, 0.0)


def _end_targets(env: NavEnv, people: np.ndarray, horizon_s: float, extend: bool,
                 past_goal_turn_deg: float = 0.0,
                 sight: Callable[[np.ndarray, np.ndarray], np.ndarray] | None = None,
                 hold_in_sight: bool = True, hold_floor_s: float = 0.0, floor_in_sight: bool = False,
                 floor_ray: bool = False, reach: np.ndarray | None = None) -> np.ndarray:
    """(B, 2) world end targets of the plans of agents ``people``: the point of each one's A* path
    ``v_pref x horizon_s`` ahead (or ``reach`` (B,) m ahead, when given) (:func:`_ahead_from_nearest`). With ``extend``, a target that would be held at
    the goal is carried past it instead, along the path's last line (or turned by up to ``past_goal_turn_deg``
    toward the longest free run, :func:`_freest_extension`), and stops where free space ends beyond the goal.

    Only such a carried target is clipped. A target still on the path stays there: clipping it from the goal
    would pull it across the walls between the goal and the path (until 2026-12-02 it did, for about half the
    plans in the home; docs/crowd_log.md, "End targets left on the path").
    """
    ahead = env.v_pref[people] * horizon_s if reach is None else np.asarray(reach, dtype=float)
    target = np.array([_ahead_from_nearest(env.paths[i], env.wp_index[i], env.pos[i], ahead[b],
                                           sight=sight, hold_in_sight=hold_in_sight,
                                           hold_floor=env.v_pref[i] * hold_floor_s, floor_in_sight=floor_in_sight,
                                           floor_ray=floor_ray)
                       for b, i in enumerate(people)]).reshape(-1, 2)
    if not extend or len(people) == 0:
        return target
    ends = np.array([env.paths[i][-1] for i in people])  # the goals
    past = np.linalg.norm(target - ends, axis=1) < 1e-9
    if past.any():
        carried = np.array([_ahead_from_nearest(env.paths[i], env.wp_index[i], env.pos[i], a,
                                                True, sight, hold_in_sight, env.v_pref[i] * hold_floor_s, floor_in_sight,
                                                floor_ray)
                            for i, a in zip(people[past], ahead[past], strict=True)])
        clearance = float(env.config.human_radius) + 0.1
        target[past] = (_freest_extension(env, ends[past], carried, clearance, past_goal_turn_deg)
                        if past_goal_turn_deg > 0 else _clip_to_free(env, ends[past], carried, clearance))
    return target


class DiffusionCrowd:
    """Batched diffusion planner of all pedestrians of one env (see the module doc).

    Args:
        model: a :class:`TrajectoryDiffusion`, a directory of an exported model, or None for the
            shipped one.
        n_samples: futures sampled per person (the best by guidance cost is walked).
        replan_s: seconds between plans.
        guidance_scale: step size of the clean guidance.
        target_weight, agent_weight, map_weight: weights of the guidance costs.
        path_weight: weight of the A* path guidance (every plan step near the path point
            ``v_pref x t`` ahead, so plans go around walls at the person's pace; 0 = end point only).
            20 by ``scripts/crowd_closed_loop.py --path-weight 0,5,10,20`` (docs/crowd.md).
        blend_s: seconds over which a replanned person's plan turns from the old plan into the new one.
        smooth_weight: weight of a smoothness guidance cost (squared second differences of the plan,
            from the last two history points); 0 = off. The ablation in docs/crowd.md ("Where the
            roughness comes from") found no setting that smooths the walk without losing goals.
        agent_buffer: clearance (m) beyond two body radii that the people guidance keeps between plans
            (TRACE's 0.2 m).
        past_goal_turn_deg: a person who walks on to a new goal (``human_at_goal="new_goal"``) has its plan's
            end target carried past the goal along the path's last line once the horizon reaches past the goal,
            up to where free space ends; so beside furniture it ends a few decimetres past the goal. With this
            above 0 the line may turn by up to this many degrees toward the longest free run
            (:func:`_freest_extension`).
        path_in_sight: measure the path guidance and the end target from the nearest path point the person
            sees, and (with ``hold_in_sight``) no farther along the path than it stays in sight
            (:func:`_ahead_from_nearest`); off, from the nearest path point and as far as the pace reaches, walls or
            not (before 2026-12-02).
        hold_in_sight: with ``path_in_sight``, hold the path points where the path leaves the person's sight
            (round a corner, the next plan goes on); off, they reach as far along the path as the pace does.
        hold_floor_s: held points lie no nearer along the path than the person walks in this many seconds at its
            preferred speed (0: right where the path leaves sight, as from 2026-12-02 to 2026-12-03). 2 s, the
            replan interval: nobody reaches a held point before the next plan, so nobody stops at corners and
            pillars (docs/crowd_log.md, "A floor under the held path points").
        floor_in_sight: the floor reaches only to path points the person sees again (past a pillar), not round the
            jamb of a door or a wall's end, where the path stays hidden and the points stay where it leaves sight
            (:func:`_ahead_from_nearest`); off, the floor applies wherever the path goes (the default
            until 2026-12-03). On by default since then: over 16 seeds it reaches more goals than the plain floor,
            most in the home and the lobby (docs/crowd_log.md, "Sixteen seeds").
        floor_ray: where the path stays hidden up to the floor, the floor's points go on along the line of sight
            through the last path point in sight (through a door, past a wall's end), not along the hidden path
            behind the wall; past a pillar, as ``floor_in_sight`` (:func:`_ahead_from_nearest`). Measured behind
            both on six seeds, so off (docs/crowd_log.md, "The floor along the line of sight").
        pace_ramp: with > 0 (m/s²), the path guidance's points (and the end target) are spaced by a pace that
            changes from the person's current speed (its last history step) toward its preferred one at this rate
            (:func:`ramped_distances`), instead of the preferred pace from the first step. 0 = off (the default):
            ramps of 0.3, 0.5 and 1.0 left the walked acceleration as it was (docs/crowd.md, "Where the roughness
            comes from: goals, corners and the walker").
        fallen_in_map: physics pedestrians that lie on the floor are in the map the model sees and in the map
            guidance: the planning grid with their footprints stamped (``NavConfig.human_fallen_obstacles``,
            :mod:`navzoo.envs.fallen`), as the people's A* paths have them; off, the bare scene's grid (a lying body
            is then only a disc at its root, in the people guidance). On, the AMD runs with a fall were level in the
            eight scenes and behind held out (−3.2 ± 2.2 successes per run), so off (docs/crowd_log.md, "The lying
            bodies in the diffusion model's map").
        k_neighbors, neighbor_radius: neighbours given to the model.
        seed: seed of the sampling noise (with the env's step count, so replays are exact).
        device: torch device of the model.
    """

    def __init__(self, model: TrajectoryDiffusion | str | Path | None = None, n_samples: int = 4,
                 replan_s: float = 2.0, guidance_scale: float = 0.05, target_weight: float = 1.0,
                 agent_weight: float = 10.0, map_weight: float = 10.0, k_neighbors: int = 16,
                 neighbor_radius: float = 10.0, seed: int = 0, device: str = "cpu",
                 path_weight: float = 20.0, blend_s: float = 1.2, smooth_weight: float = 0.0,
                 agent_buffer: float = 0.2, past_goal_turn_deg: float = 0.0, path_in_sight: bool = True,
                 hold_in_sight: bool = True, hold_floor_s: float = 2.0, floor_in_sight: bool = True,
                 floor_ray: bool = False, pace_ramp: float = 0.0, fallen_in_map: bool = False) -> None:
        if model is None or isinstance(model, (str, Path)):
            from navzoo.agents.diffusion.trainer import load_model

            model = load_model(model_dir(model), device)
        if int(n_samples) < 1:
            raise ValueError(f"n_samples must be >= 1, got {n_samples!r}")
        if not replan_s > 0:
            raise ValueError(f"replan_s must be > 0, got {replan_s!r}")
        if not blend_s >= 0:
            raise ValueError(f"blend_s must be >= 0, got {blend_s!r}")
        self.model = model.eval()
        self.cfg = model.cfg
        self.n_samples = int(n_samples)
        self.replan_s = float(replan_s)
        self.guidance_scale = float(guidance_scale)
        self.weights = (float(target_weight), float(agent_weight), float(map_weight))
        self.k = int(k_neighbors)
        self.radius = float(neighbor_radius)
        self.seed = int(seed)
        self.device = device
        self.path_weight = float(path_weight)
        self.blend_s = float(blend_s)
        if not smooth_weight >= 0:
            raise ValueError(f"smooth_weight must be >= 0, got {smooth_weight!r}")
        self.smooth_weight = float(smooth_weight)
        if not agent_buffer >= 0:
            raise ValueError(f"agent_buffer must be >= 0, got {agent_buffer!r}")
        self.agent_buffer = float(agent_buffer)
        if not 0 <= past_goal_turn_deg <= 180:
            raise ValueError(f"past_goal_turn_deg must be in [0, 180], got {past_goal_turn_deg!r}")
        self.past_goal_turn_deg = float(past_goal_turn_deg)
        self.path_in_sight = bool(path_in_sight)
        self.hold_in_sight = bool(hold_in_sight)
        if not hold_floor_s >= 0:
            raise ValueError(f"hold_floor_s must be >= 0, got {hold_floor_s!r}")
        self.hold_floor_s = float(hold_floor_s)
        self.floor_in_sight = bool(floor_in_sight)
        self.floor_ray = bool(floor_ray)
        self.fallen_in_map = bool(fallen_in_map)
        if not pace_ramp >= 0:
            raise ValueError(f"pace_ramp must be >= 0, got {pace_ramp!r}")
        self.pace_ramp = float(pace_ramp)
        self.n = 0

    # ------------------------------------------------------------------ state
    def reset(self, env: NavEnv) -> None:
        """Start a new episode: walking-in histories, no plans yet."""
        N = env.n_total
        T = self.cfg.history
        self.n = N
        direction = np.zeros((N, 2))
        for i in range(N):
            ahead = _ahead_on_path(env.paths[i][env.wp_index[i]:], env.pos[i], 1.0) - env.pos[i]
            norm = np.linalg.norm(ahead)
            direction[i] = ahead / norm if norm > 1e-6 else np.array([np.cos(env.yaw[i]), np.sin(env.yaw[i])])
        speed = np.where(env.is_robot, 0.0, env.v_pref)
        back = (np.arange(T)[::-1] * MODEL_DT)[None, :, None]  # T-1 .. 0 steps ago
        self.hist = env.pos[:, None, :] - back * (speed[:, None, None] * direction[:, None, :])
        self.hist_time = env.sim_time
        self.plan: np.ndarray | None = None  # (H, steps + 1, 2) world positions of pedestrians
        self.plan_t0 = np.full(env.n_humans, -np.inf)  # time of each plan's row 0 (its last history point)
        self.batch_time = -np.inf  # time of the last replan of everyone
        self._goals_seen = env.goals_reached[env.n_robots:].copy()
        self.plans_made = 0

    def observe(self, env: NavEnv) -> None:
        """Record positions every model step (call after every env step)."""
        if self.n != env.n_total:
            raise RuntimeError("DiffusionCrowd.observe before reset (or on another env)")
        while env.sim_time + 1e-9 >= self.hist_time + MODEL_DT:
            self.hist = np.concatenate([self.hist[:, 1:], env.pos[:, None, :]], axis=1)
            self.hist_time += MODEL_DT

    # ------------------------------------------------------------------ planning
    def _world_batch(self, env: NavEnv, people: np.ndarray) -> dict[str, Any]:
        R = env.n_robots
        see = env.config.humans_see_robots
        agents = np.flatnonzero(env.alive | ~env.is_robot) if see else np.arange(R, env.n_total)
        B, T, K = people.size, self.cfg.history, self.k
        neigh = np.zeros((B, K, T, 2))
        mask = np.zeros((B, K, T), dtype=bool)
        for b, i in enumerate(people):
            others = agents[agents != i]
            if others.size == 0:
                continue
            d = np.linalg.norm(env.pos[others] - env.pos[i], axis=1)
            near = others[np.argsort(d)][: K][np.sort(d)[: K] < self.radius]
            neigh[b, : near.size] = self.hist[near]
            mask[b, : near.size] = True
        return {"hist": self.hist[people].copy(), "neigh": neigh, "neigh_mask": mask,
                "dt": np.full(B, MODEL_DT), "origin": np.zeros((B, 2)), "rot": np.repeat(np.eye(2)[None], B, axis=0)}

    def _map_grid(self, env: NavEnv) -> OccupancyGrid:
        """The occupancy grid of the model's map input and the map guidance (``fallen_in_map``)."""
        return env.pedestrian_grid if self.fallen_in_map else env.grid

    def plan_now(self, env: NavEnv, who: np.ndarray | None = None) -> np.ndarray:
        """Plan pedestrians now: all of them, or those of ``who`` (indices among the pedestrians, 0..n_humans-1).

        Returns every pedestrian's plan, (H, steps + 1, 2) world positions every 0.4 s from its last
        history point (row 0, at ``plan_t0``). A person who had a plan blends into the new one over
        ``blend_s`` seconds: its displacement from row 0 starts as the old plan's and turns linearly
        into the new sample's, so its velocity does not jump at a replan.
        """
        R, N = env.n_robots, env.n_total
        H = self.cfg.horizon
        if N - R == 0:
            self.plan = np.zeros((0, H + 1, 2))
            return self.plan
        everyone = who is None or self.plan is None or self.plan.shape[0] != N - R
        who = np.arange(N - R) if everyone else np.unique(np.asarray(who, dtype=int))
        if who.size == 0:
            return self.plan
        people = R + who
        world = self._world_batch(env, people)
        local = fdata.normalize(world)
        B = people.size
        heading = np.arctan2(local["rot"][:, 0, 1], local["rot"][:, 0, 0])
        batch = {
            "hist": torch.as_tensor(local["hist"], dtype=torch.float32),
            "neigh": torch.as_tensor(local["neigh"], dtype=torch.float32),
            "neigh_mask": torch.as_tensor(local["neigh_mask"]),
            "dt": torch.full((B,), MODEL_DT),
        }
        if self.cfg.map_cells:
            occ = self._map_grid(env).crop_many(env.pos[people], heading, MAP_EXTENT, self.cfg.map_cells)
            batch["map"] = torch.as_tensor(occ)
            batch["has_map"] = torch.ones(B, dtype=torch.bool)
        # Guidance: the path point v_pref x horizon ahead, others' current plans, the scene's walls.
        horizon_s = H * MODEL_DT
        standing = env.arrived[people] | env.human_fallen[who]
        # People who walk on to a new goal keep their pace through the goal: near it, the target lies
        # beyond it on the path's last line (else every plan would end at the goal, and each replan
        # would slow down further as the goal comes closer); people who stop there aim at it.
        extend = env.config.human_at_goal != "stop"
        sight = _in_sight(env) if self.path_in_sight else None
        steps = np.arange(1, H + 1) * MODEL_DT
        v0 = np.linalg.norm(self.hist[people][:, -1] - self.hist[people][:, -2], axis=1) / MODEL_DT
        along_d = ramped_distances(v0, env.v_pref[people], self.pace_ramp, steps)  # (B, H) m along the path
        target_w = _end_targets(env, people, horizon_s, extend, self.past_goal_turn_deg, sight, self.hold_in_sight,
                                self.hold_floor_s, self.floor_in_sight, self.floor_ray,
                                reach=along_d[:, -1] if self.pace_ramp > 0 else None)
        target = fdata.to_local(target_w[:, None, :], local)[:, 0]
        if self.cfg.goal:  # a goal-conditioned model gets the waypoint as its goal (guidance still pulls)
            batch["goal"] = torch.as_tensor(target, dtype=torch.float32)
            batch["has_goal"] = torch.as_tensor(~standing)
        t_w, a_w, m_w = self.weights
        costs = [target_cost(torch.as_tensor(target, dtype=torch.float32), t_w,
                             valid=torch.as_tensor(~standing))]
        if self.path_weight > 0:  # every step near the A* path at the person's pace (around walls, not through)
            along = np.array([_ahead_from_nearest(env.paths[i], env.wp_index[i], env.pos[i], along_d[b],
                                                  sight=sight, hold_in_sight=self.hold_in_sight,
                                                  hold_floor=env.v_pref[i] * self.hold_floor_s,
                                                  floor_in_sight=self.floor_in_sight, floor_ray=self.floor_ray)
                              for b, i in enumerate(people)])  # (B, H, 2) world, held at the goal
            ref = fdata.to_local(along, local)
            costs.append(path_cost(torch.as_tensor(ref, dtype=torch.float32), self.path_weight,
                                   valid=torch.as_tensor(~standing)))
        # Articulated bodies swing beyond their discs: plan them with room to spare (as amp_humans does).
        margin = BODY_MARGIN if getattr(env, "amp", None) is not None else 0.0
        others_w = self._others_future(env, people)
        if others_w is not None:
            o_pos, o_mask = others_w
            o_local = fdata.to_local(o_pos.reshape(B, -1, 2), local).reshape(o_pos.shape)
            costs.append(agent_collision_cost(torch.as_tensor(o_local, dtype=torch.float32), torch.as_tensor(o_mask),
                                              radius=2 * (float(env.config.human_radius) + margin),
                                              buffer=self.agent_buffer, weight=a_w))
        n_cells = 32
        offs = (np.arange(n_cells) + 0.5 - n_cells / 2) * (MAP_EXTENT / n_cells)
        lx, ly = np.meshgrid(offs, offs)
        pts = np.stack([lx, ly], -1).reshape(1, -1, 2).repeat(B, 0)
        dist = self._map_grid(env).distance_at(fdata.to_world(pts, local)).reshape(B, n_cells, n_cells)
        costs.append(map_collision_cost(torch.as_tensor(dist, dtype=torch.float32), MAP_EXTENT,
                                        radius=float(env.config.human_radius), weight=m_w))
        if self.smooth_weight > 0:  # plans that continue the current velocity and turn gently
            start = fdata.to_local(self.hist[people][:, -2:], local)
            costs.append(smoothness_cost(torch.as_tensor(start, dtype=torch.float32), self.smooth_weight))
        guide = combine(*costs)
        g = torch.Generator().manual_seed(self.seed * 1_000_003 + int(env.steps))
        with torch.no_grad():
            samples = self.model.sample(batch, self.n_samples, generator=g, guidance=guide,
                                        guidance_scale=self.guidance_scale)  # (B, S, H, 2)
        flat = samples.reshape(B * self.n_samples, H, 2)
        idx = torch.arange(B).repeat_interleave(self.n_samples)
        with torch.no_grad():
            cost = guide(flat, idx).reshape(B, self.n_samples)
        best = samples[torch.arange(B), cost.argmin(dim=1)].numpy().astype(np.float64)  # (B, H, 2)
        path = np.concatenate([np.zeros((B, 1, 2)), best], axis=1)
        plan = fdata.to_world(path, local)
        t0 = self.hist_time
        if self.blend_s > 0 and self.plan is not None and self.plan.shape[0] == N - R:
            old = self._plans_at(t0 + np.arange(H + 1) * MODEL_DT)[who]  # (B, H+1, 2)
            had = np.isfinite(self.plan_t0[who])
            w = np.minimum(1.0, np.arange(H + 1) * MODEL_DT / self.blend_s)[None, :, None]
            blended = plan[:, :1] + (1.0 - w) * (old - old[:, :1]) + w * (plan - plan[:, :1])
            plan[had] = blended[had]
        plan[standing] = env.pos[people][standing][:, None, :]  # arrived or fallen people stay
        if everyone:
            self.plan = plan
            self.batch_time = env.sim_time
        else:
            self.plan[who] = plan
        self.plan_t0[who] = t0
        self._goals_seen[who] = env.goals_reached[people]
        self.plans_made += 1
        return self.plan

    def _others_future(self, env: NavEnv, people: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
        """Every other agent's next 12 positions (B, M, H, 2) in the world: people on their current
        plans (constant velocity when there is none), robots at constant velocity."""
        H = self.cfg.horizon
        R = env.n_robots
        see = env.config.humans_see_robots
        agents = np.flatnonzero(env.alive | ~env.is_robot) if see else np.arange(R, env.n_total)
        if agents.size <= 1:
            return None
        steps = (np.arange(1, H + 1) * MODEL_DT)[None, :, None]
        fut = env.pos[agents][:, None, :] + steps * env.vel[agents][:, None, :]
        people_now = agents >= R
        amp = getattr(env, "amp", None)
        if amp is not None and amp.n == env.n_humans:  # physics bodies walk their target paths, not the raw plans
            k = amp.k_prog[:, None] + np.round(steps[0, :, 0] * 30.0).astype(int)[None, :]
            paths = np.take_along_axis(amp.paths, np.minimum(k, amp.path_len - 1)[..., None], axis=1)  # (H, H', 2)
            fut[people_now] = paths[agents[people_now] - R]
        elif self.plan is not None and self.plan.shape[0] == env.n_humans:
            fut[people_now] = self._plans_at(env.sim_time + steps[0, :, 0])[agents[people_now] - R]
        B = people.size
        others = np.repeat(fut[None], B, axis=0)
        mask = agents[None, :] != people[:, None]
        return others, mask

    def _plans_at(self, t: float | np.ndarray) -> np.ndarray:
        """Positions (H, len(t), 2) of every pedestrian's plan at sim times ``t``, linear between plan
        points (0.4 s apart from each plan's ``plan_t0``) and held at the end."""
        K = self.plan.shape[1]
        t = np.atleast_1d(np.asarray(t, dtype=float))
        f = np.clip(t[None, :] - self.plan_t0[:, None], 0.0, (K - 1) * MODEL_DT) / MODEL_DT  # (H, T)
        k0 = np.minimum(np.floor(f).astype(int), K - 2)
        w = (f - k0)[..., None]
        rows = np.arange(self.plan.shape[0])[:, None]
        return self.plan[rows, k0] * (1.0 - w) + self.plan[rows, k0 + 1] * w

    # ------------------------------------------------------------------ outputs
    def points_now(self, env: NavEnv) -> np.ndarray | None:
        """(H, 2) every pedestrian's current plan point (None before the first plan)."""
        if self.plan is None or self.plan.shape[0] != env.n_humans:
            return None
        return self._plans_at(env.sim_time)[:, 0]

    def maybe_plan(self, env: NavEnv, force: bool = False) -> None:
        """Plan everyone when ``replan_s`` has passed since everyone was planned; in between, plan
        only the people who got a new goal (the others keep their plans)."""
        if (force or self.plan is None or self.plan.shape[0] != env.n_humans
                or env.sim_time - self.batch_time >= self.replan_s - 1e-9):
            self.plan_now(env)
            return
        new_goal = np.flatnonzero(env.goals_reached[env.n_robots:] != self._goals_seen)
        if new_goal.size:
            self.plan_now(env, new_goal)

    def preferred_velocities(self, env: NavEnv, lookahead: float = 0.8) -> np.ndarray:
        """World velocities (H, 2) toward each plan's point ``lookahead`` seconds ahead, at the plan's
        pace: the preferred velocity that a local collision-avoidance model then follows."""
        self.maybe_plan(env)
        R = env.n_robots
        ahead = self._plans_at(env.sim_time + lookahead)[:, 0]
        v = (ahead - env.pos[R:]) / lookahead
        speed = np.linalg.norm(v, axis=1, keepdims=True)
        vmax = env.config.human_max_speed
        return np.where(speed > vmax, v / np.maximum(speed, 1e-9) * vmax, v)

    def velocities(self, env: NavEnv) -> np.ndarray:
        """World velocities (H, 2) that take kinematic pedestrians to their plan one step ahead."""
        return self.preferred_velocities(env, lookahead=env.config.dt)

    def plan_positions(self, env: NavEnv, dt: float, steps: int) -> np.ndarray:
        """(H, steps + 1, 2) target paths for physics bodies (AMP), every ``dt`` from now.

        Each body's target starts where the body is: at the point of its fresh plan nearest to it
        (the plan starts at the last history point, up to 0.4 s old), and goes along the plan's path
        at a pace that starts at the body's speed and rises by at most :data:`ACCEL_LIMIT` to the
        plan's mean pace, capped at ``AMP_SPEED_FACTOR x v_pref``. A body cannot follow the sampled
        timing itself: plans can start at walking pace from rest, and their pace jumps between plans.
        """
        self.plan_now(env)
        R = env.n_robots
        t = np.arange(steps + 1) * dt
        plan = self.plan  # (H, K, 2)
        seg = np.linalg.norm(np.diff(plan, axis=1), axis=2)  # (H, K-1)
        cum = np.concatenate([np.zeros((len(plan), 1)), np.cumsum(seg, axis=1)], axis=1)
        pace = np.minimum(cum[:, -1] / (MODEL_DT * seg.shape[1]), AMP_SPEED_FACTOR * env.v_pref[R:])
        v0 = np.minimum(np.linalg.norm(env.vel[R:], axis=1), pace)
        out = np.empty((len(plan), len(t), 2))
        for j in range(len(plan)):
            k, f, _ = _nearest_on_polyline(plan[j], env.pos[R + j])
            s0 = cum[j, k] + f * seg[j, k]
            v = np.minimum(pace[j], v0[j] + ACCEL_LIMIT * t)
            s = s0 + np.concatenate([[0.0], np.cumsum(0.5 * (v[1:] + v[:-1]) * dt)])
            out[j, :, 0] = np.interp(s, cum[j], plan[j, :, 0])
            out[j, :, 1] = np.interp(s, cum[j], plan[j, :, 1])
        return out
