"""Dynamic Window Approach (DWA) robot controller, vectorised with numpy over the candidate window.

Fox, Burgard & Thrun (1997), "The dynamic window approach to collision avoidance": each control
step, the velocities the base can reach within one step under its acceleration limits (the
*dynamic window*) are sampled, each is rolled out at constant velocity over a short horizon, and the
admissible one with the lowest cost is commanded.

* Differential drive: the window is a grid over (v, omega) around the current command,
  ``|v - v0| <= max_accel * dt`` and ``|omega - omega0| <= max_ang_accel * dt``, within
  ``[0, max_speed] x [-max_turn_rate, max_turn_rate]``; rollouts are circular arcs.
* Holonomic: the window is the set of world-frame velocities (v_x, v_y) with ``|v| <= max_speed`` and
  ``|v - v0| <= max_accel * dt`` (the env's limits, :func:`navzoo.agents.robot.command_velocity`),
  sampled on two polar grids (the speed disc and the acceleration disc); rollouts are straight.

Cost of a candidate (lower is better; weights in :class:`DWAParams`):

* **goal**: minus the progress toward a *carrot*, the farthest point of the robot's A* path (from
  its point nearest to the robot) within ``lookahead`` metres along the path that is in line of
  sight, normalised by ``max_speed * horizon`` (closest approach over the rollout, so a rollout
  that passes through the goal scores fully);
* **heading** (differential drive): angle between the final heading and the direction to the carrot;
* **velocity**: ``1 - speed / max_speed`` (prefer fast);
* **obstacles**: ``exp(-clearance / obstacle_scale)`` with the smallest clearance over the rollout,
  the exact distance to the scene's wall segments within reach (``env.segments``; the occupancy
  distance field is off by up to a grid cell, which is a lot next to a pillar). A rollout that
  comes within ``obstacle_margin`` of an obstacle is *inadmissible* unless the robot could still
  brake to a stop before that point (``v * dt + v^2 / (2 max_accel)``), as in the original DWA;
* **people**: every other live agent (people and other robots) is predicted at constant velocity
  and, with ``people_may_stop``, also standing still (the nearer counts);
  ``exp(-gap / people_scale)`` of the smallest predicted gap (edge to edge), plus
  ``collision * (1 - t_c / horizon)`` when a gap closes below ``people_margin`` at time ``t_c``.

The chosen command always lies inside the dynamic window, so the env's rate limiter
(:func:`navzoo.agents.robot.command_velocity`) passes it unchanged.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import TYPE_CHECKING, Any

import numpy as np

from navzoo.agents.policy import act_per_robot, perceived_others

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = ["DWAParams", "DWAPolicy", "dwa_window", "obstacle_speed_filter", "static_clearance"]


@dataclass(frozen=True)
class DWAParams:
    """DWA parameters.

    Attributes:
        horizon: rollout length (s).
        rollout_dt: time between rollout samples (s); collisions are checked at these times.
        n_v: linear-speed samples across the window (differential drive).
        n_omega: angular-speed samples across the window (differential drive); omega = 0 is added
            when it lies in the window.
        n_speeds: speed rings of the holonomic polar grids.
        n_headings: directions of the holonomic polar grids.
        lookahead: carrot distance along the A* path (m).
        w_goal: weight of the progress toward the carrot.
        w_heading: weight of the final heading error (differential drive).
        w_velocity: weight of the speed term.
        w_obstacle: weight of the obstacle-clearance term.
        w_people: weight of the people-proximity term.
        w_collision: weight of a predicted collision with a person or robot.
        obstacle_margin: clearance to obstacles (beyond the robot's radius) that counts as a hit (m).
        obstacle_scale: decay length of the obstacle term (m).
        people_margin: predicted gap to a person that counts as a collision (m).
        people_scale: decay length of the people term (m).
        allow_reverse: differential drive: also sample backward speeds (down to -max_speed / 2).
        people_may_stop: predict every person both at constant velocity and standing still, and
            score the nearer of the two (people stop or turn in front of pillars and each other).
    """

    horizon: float = 2.0
    rollout_dt: float = 0.1
    n_v: int = 9
    n_omega: int = 21
    n_speeds: int = 6
    n_headings: int = 24
    lookahead: float = 2.0
    w_goal: float = 1.0
    w_heading: float = 0.2
    w_velocity: float = 0.1
    w_obstacle: float = 0.3
    w_people: float = 0.6
    w_collision: float = 5.0
    obstacle_margin: float = 0.1
    obstacle_scale: float = 0.2
    people_margin: float = 0.1
    people_scale: float = 0.3
    allow_reverse: bool = False
    people_may_stop: bool = True

    def __post_init__(self) -> None:
        for f in fields(self):
            value = getattr(self, f.name)
            if f.name in ("allow_reverse", "people_may_stop"):
                if not isinstance(value, bool):
                    raise ValueError(f"DWAParams.{f.name} must be a bool, got {value!r}")
                continue
            if f.name.startswith("n_"):
                if isinstance(value, bool) or not isinstance(value, int) or value < 2:
                    raise ValueError(f"DWAParams.{f.name} must be an integer >= 2, got {value!r}")
                continue
            if not (isinstance(value, (int, float)) and math.isfinite(value)):
                raise ValueError(f"DWAParams.{f.name} must be a finite number, got {value!r}")
            positive = f.name in ("horizon", "rollout_dt", "lookahead", "obstacle_scale", "people_scale")
            if (positive and value <= 0) or value < 0:
                raise ValueError(f"DWAParams.{f.name} must be {'> 0' if positive else '>= 0'}, got {value!r}")


def dwa_window(cmd0: np.ndarray, spec: Any, dt: float, params: DWAParams) -> tuple[np.ndarray, np.ndarray]:
    """Candidate commands of R robots: ``(cand (R, C, 2), valid (R, C))`` in the command's units.

    Differential drive: (v, omega) on an ``n_v x (n_omega + 1)`` grid over the dynamic window (all
    valid). Holonomic: world-frame (v_x, v_y) from a polar grid over the speed disc and one over the
    acceleration disc around ``cmd0``, plus the full-brake command; ``valid`` marks those inside both
    discs (``cmd0`` itself is always valid).
    """
    cmd0 = np.asarray(cmd0, dtype=np.float64).reshape(-1, 2)
    r = cmd0.shape[0]
    if spec.kinematics == "diff_drive":
        dv, dw = spec.max_accel * dt, spec.max_ang_accel * dt
        v_min = -0.5 * spec.max_speed if params.allow_reverse else 0.0
        v0, w0 = cmd0[:, 0], cmd0[:, 1]
        # Window intersected with the limits; if the intersection is empty (a command outside the
        # limits), the reachable value closest to them.
        v_lo = np.clip(np.maximum(v_min, v0 - dv), v0 - dv, v0 + dv)
        v_hi = np.clip(np.minimum(spec.max_speed, v0 + dv), v0 - dv, v0 + dv)
        w_lo = np.clip(np.maximum(-spec.max_turn_rate, w0 - dw), w0 - dw, w0 + dw)
        w_hi = np.clip(np.minimum(spec.max_turn_rate, w0 + dw), w0 - dw, w0 + dw)
        s_v = np.linspace(0.0, 1.0, params.n_v)
        s_w = np.linspace(0.0, 1.0, params.n_omega)
        vs = v_lo[:, None] + (v_hi - v_lo)[:, None] * s_v  # (R, n_v)
        ws = w_lo[:, None] + (w_hi - w_lo)[:, None] * s_w  # (R, n_omega)
        ws = np.concatenate([ws, np.clip(0.0, w_lo, w_hi)[:, None]], axis=1)  # straight ahead
        cand = np.stack(np.broadcast_arrays(vs[:, :, None], ws[:, None, :]), axis=-1).reshape(r, -1, 2)
        return cand, np.ones(cand.shape[:2], dtype=bool)
    vmax, da = spec.max_speed, spec.max_accel * dt
    ang = np.linspace(0.0, 2 * np.pi, params.n_headings, endpoint=False)
    unit = np.stack([np.cos(ang), np.sin(ang)], axis=1)  # (A, 2)
    rings = np.linspace(0.0, 1.0, params.n_speeds)[1:]
    disc = (rings[:, None, None] * unit[None]).reshape(-1, 2)  # (S*A, 2) unit-disc samples
    speed_disc = np.broadcast_to(vmax * disc, (r, disc.shape[0], 2))
    accel_disc = cmd0[:, None, :] + min(da, 2 * vmax) * disc[None]
    n0 = np.linalg.norm(cmd0, axis=1, keepdims=True)
    brake = cmd0 - np.minimum(n0, da) * cmd0 / np.maximum(n0, 1e-12)
    cand = np.concatenate([cmd0[:, None], brake[:, None], np.zeros((r, 1, 2)), speed_disc, accel_disc], axis=1)
    tol = 1e-9 * max(1.0, vmax)
    valid = (np.linalg.norm(cand, axis=2) <= vmax + tol) & (np.linalg.norm(cand - cmd0[:, None], axis=2) <= da + tol)
    valid[:, 0] = True
    return cand, valid


def _rollout(pos: np.ndarray, yaw: np.ndarray, cand: np.ndarray, t: np.ndarray, diff_drive: bool) -> tuple[np.ndarray, np.ndarray]:
    """Positions (R, C, K, 2) and headings (R, C, K) of constant-command rollouts at times t (K,)."""
    x0, y0 = pos[:, 0, None, None], pos[:, 1, None, None]
    if not diff_drive:
        traj = pos[:, None, None, :] + cand[:, :, None, :] * t[None, None, :, None]
        heading = np.arctan2(cand[..., 1], cand[..., 0])[..., None] * np.ones_like(t)
        return traj, heading
    v, w = cand[..., 0, None], cand[..., 1, None]  # (R, C, 1)
    th0 = yaw[:, None, None]
    th = th0 + w * t
    straight = np.abs(w) < 1e-6
    w_safe = np.where(straight, 1.0, w)
    x = np.where(straight, x0 + v * t * np.cos(th0), x0 + v / w_safe * (np.sin(th) - np.sin(th0)))
    y = np.where(straight, y0 + v * t * np.sin(th0), y0 - v / w_safe * (np.cos(th) - np.cos(th0)))
    return np.stack([x, y], axis=-1), th


class DWAPolicy:
    """DWA robot controller (privileged: reads the state arrays of the env; see the module docstring).

    Args:
        params: :class:`DWAParams`.
        kinematics: ``None`` (use the env's robot), ``"diff_drive"`` or ``"holonomic"``; a fixed
            kinematics that does not match the env's robot raises ``ValueError``.
    """

    name = "dwa"

    def __init__(self, params: DWAParams | None = None, kinematics: str | None = None) -> None:
        if kinematics not in (None, "diff_drive", "holonomic"):
            raise ValueError(f"kinematics must be None, 'diff_drive' or 'holonomic', got {kinematics!r}")
        self.params = params or DWAParams()
        self.kinematics = kinematics
        self.last: dict[str, np.ndarray] = {}  # diagnostics of the last act(): candidates, costs
        self._plans: dict[int, np.ndarray] = {}  # robot index -> its own re-planned A* path
        self._env_id: int | None = None

    def reset(self, env: NavEnv) -> None:
        _check_kinematics(self.kinematics, env, "dwa")
        self._plans = {}
        self._env_id = id(env)

    # ------------------------------------------------------------------ pieces
    def carrots(self, env: NavEnv, idx: np.ndarray) -> np.ndarray:
        """(R, 2) carrot of each robot: farthest point of its A* path within ``lookahead`` (along the
        path) whose straight segment from the robot keeps ``radius + obstacle_margin`` from walls.

        The path is the env's (``env.paths``) until no point of it is in line of sight (the robot
        went around people and a pillar now hides its path); then A* is re-run from the robot's
        position and that path is followed until the next re-plan or reset.
        """
        out = np.empty((idx.size, 2))
        for k, i in enumerate(idx):
            i = int(i)
            carrot = self._carrot_on(env, i, self._plans.get(i))
            if carrot is None:
                self._plans[i] = env._plan(i, env.pos[i], env.goal[i])
                carrot = self._carrot_on(env, i, self._plans[i], fallback=True)
            out[k] = carrot
        return out

    def _carrot_on(self, env: NavEnv, i: int, plan: np.ndarray | None, fallback: bool = False) -> np.ndarray | None:
        if plan is None:
            path = env.paths[i]
            pts = path[min(env.wp_index[i], len(path) - 1):]
        else:
            pts = plan
        # The env advances waypoints by proximity only; after a detour its next waypoint can lie
        # behind the robot. Continue from the remaining path's point nearest to the robot.
        pts = pts[int(np.argmin(np.linalg.norm(pts - env.pos[i], axis=1))):]
        seg = np.linalg.norm(np.diff(np.vstack([env.pos[i][None], pts]), axis=0), axis=1)
        along = np.cumsum(seg)
        n = max(1, int(np.searchsorted(along, self.params.lookahead, side="right")) + 1)
        cands = pts[: min(n, len(pts))]
        # Line of sight with the DWA's obstacle margin (or the robot's own clearance, if it is
        # already closer), all candidates at once: samples every 5 cm, exact distances to walls.
        d = cands - env.pos[i]
        m = max(2, int(np.ceil(np.linalg.norm(d, axis=1).max() / 0.05)) + 1)
        s = np.linspace(0.0, 1.0, m)
        samples = env.pos[i] + s[None, :, None] * d[:, None, :]
        dist, dist0 = static_clearance(env, np.array([i]), samples[None], along[-1] + 1.0)
        need = min(env.radius[i] + self.params.obstacle_margin, dist0[0]) - 1e-3
        visible = np.flatnonzero(dist[0].min(axis=1) >= need)
        if visible.size:
            return cands[visible[-1]]
        return cands[0] if fallback else None

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        split = act_per_robot(self, observations, env)
        if split is not None:
            return split
        idx = _robot_indices(observations, env)
        if idx.size == 0:
            return {}
        _check_kinematics(self.kinematics, env, "dwa")
        if self._env_id != id(env) or env.steps == 0:  # a new episode without reset(): drop old plans
            self.reset(env)
        prm, spec = self.params, env.config.robot
        dt = env.config.dt
        diff = spec.kinematics == "diff_drive"
        cand, valid = dwa_window(env.cmd[idx], spec, dt, prm)  # (R, C, 2)
        k_steps = max(1, int(math.ceil(prm.horizon / prm.rollout_dt - 1e-9)))
        t = prm.rollout_dt * np.arange(1, k_steps + 1)
        horizon = t[-1]
        traj, heading = _rollout(env.pos[idx], env.yaw[idx], cand, t, diff)  # (R, C, K, 2), (R, C, K)
        speed = np.abs(cand[..., 0]) if diff else np.linalg.norm(cand, axis=2)  # (R, C)
        radius = env.radius[idx]

        # Static obstacles: exact distance to the wall segments within reach; the first hit must lie
        # beyond the braking distance. A robot already inside the margin may move as long as it does
        # not get closer than it is.
        reach = spec.max_speed * horizon + radius + prm.obstacle_margin + 3.0 * prm.obstacle_scale
        exact = float(radius.max()) + prm.obstacle_margin + 3.0 * prm.obstacle_scale
        dist, dist0 = static_clearance(env, idx, traj, reach, exact_within=exact)
        clear = dist - radius[:, None, None] - prm.obstacle_margin  # (R, C, K)
        clear0 = dist0 - radius - prm.obstacle_margin  # (R,)
        hit = clear < np.minimum(0.0, clear0)[:, None, None] - 1e-3
        any_hit = hit.any(axis=2)
        first = np.where(any_hit, hit.argmax(axis=2), k_steps)
        t_free = np.where(first > 0, t[np.maximum(first - 1, 0)], 0.0)  # last sample before the hit
        t_free = np.where(any_hit, t_free, np.inf)
        brake = speed * dt + speed**2 / (2.0 * spec.max_accel)
        admissible = ~any_hit | (speed * np.where(any_hit, t_free, 0.0) >= brake - 1e-9)
        c_obs = np.exp(-np.clip(clear.min(axis=2), 0.0, None) / prm.obstacle_scale)

        # People and other robots at constant velocity.
        seen = perceived_others(env, idx)
        if seen is None:
            others = np.flatnonzero(env.alive & env.present)  # absent (replay: parked) people left out
            o_pos, o_vel, o_rad = env.pos[others], env.vel[others], env.radius[others]
        else:  # perceived people (and ground-truth robots) from a PerceptionWrapper; never the robot itself
            o_pos, o_vel, o_rad = seen
            others = np.full(len(o_pos), -1)
        c_people = np.zeros(cand.shape[:2])
        c_coll = np.zeros(cand.shape[:2])
        if others.size:
            q = o_pos[:, None, :] + o_vel[:, None, :] * t[None, :, None]  # (M, K, 2)
            diff_xy = traj[:, :, None, :, :] - q[None, None]  # (R, C, M, K, 2)
            gap = np.hypot(diff_xy[..., 0], diff_xy[..., 1])
            if prm.people_may_stop:  # a person may also stop where they are: the nearer of the two
                still = traj[:, :, None, :, :] - o_pos[None, None, :, None, :]
                gap = np.minimum(gap, np.hypot(still[..., 0], still[..., 1]))
            gap = gap - radius[:, None, None, None] - o_rad[None, None, :, None]
            gap = np.where((others[None, :] == idx[:, None])[:, None, :, None], np.inf, gap)
            gap = gap.min(axis=2)  # (R, C, K): nearest other at each time
            if np.isfinite(gap).any():
                weight = 1.0 - 0.5 * t / horizon  # nearer in time counts more
                c_people = (np.exp(-np.clip(gap, 0.0, None) / prm.people_scale) * weight).max(axis=2)
                coll = gap < prm.people_margin
                t_c = np.where(coll.any(axis=2), t[coll.argmax(axis=2)], np.inf)
                c_coll = np.where(np.isfinite(t_c), 1.0 - np.minimum(t_c, horizon) / (horizon + prm.rollout_dt), 0.0)

        # Goal: progress toward the carrot (closest approach over the rollout), heading at the end.
        carrot = self.carrots(env, idx)  # (R, 2)
        d0 = np.linalg.norm(carrot - env.pos[idx], axis=1)  # (R,)
        d_roll = np.linalg.norm(traj - carrot[:, None, None, :], axis=3)  # (R, C, K)
        progress = (d0[:, None] - d_roll.min(axis=2)) / (spec.max_speed * horizon)
        c_heading = np.zeros(cand.shape[:2])
        if diff:
            to_carrot = carrot[:, None, :] - traj[:, :, -1, :]
            ang = np.arctan2(to_carrot[..., 1], to_carrot[..., 0]) - heading[..., -1]
            err = np.abs((ang + np.pi) % (2 * np.pi) - np.pi) / np.pi
            c_heading = np.where(np.linalg.norm(to_carrot, axis=2) > 0.2, err, 0.0)
        c_vel = 1.0 - speed / spec.max_speed

        cost = (-prm.w_goal * progress + prm.w_heading * c_heading + prm.w_velocity * c_vel
                + prm.w_obstacle * c_obs + prm.w_people * c_people + prm.w_collision * c_coll)
        # Inadmissible candidates rank after all admissible ones, the later the hit the better.
        late = np.where(np.isfinite(t_free), t_free, horizon) / horizon
        cost = np.where(admissible, cost, 1e6 * (2.0 - late) + cost)
        cost = np.where(valid, cost, np.inf)
        best = np.argmin(cost, axis=1)
        chosen = cand[np.arange(idx.size), best]  # (R, 2)
        self.last = {"candidates": cand, "valid": valid, "cost": cost, "admissible": admissible,
                     "chosen": chosen, "carrot": carrot}
        scale = np.array([spec.max_speed, spec.max_turn_rate]) if diff else np.array([spec.max_speed, spec.max_speed])
        acts = (chosen / scale).astype(np.float32)
        return {env.possible_agents[i]: acts[k] for k, i in enumerate(idx)}


def static_clearance(env: NavEnv, idx: np.ndarray, points: np.ndarray, reach: np.ndarray | float,
                     exact_within: float | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Distance from points to the scene's walls, for robots ``idx`` (exact, segment by segment).

    Args:
        env: the env (its ``segments``: every obstacle edge and the scene's edge).
        idx: (R,) robot indices.
        points: (R, ..., 2) points of each robot (e.g. its rollouts).
        reach: (R,) or scalar: only segments within this distance of the robot are considered;
            points farther than ``reach`` from every such segment may report ``inf``.
        exact_within: if given, only points whose distance-field value (``env.grid.distance_at``,
            off by at most a cell) is within this distance get the exact distance; the others
            report the field's value (a speed-up for points far from any wall).

    Returns:
        ``(dist (R, ...), dist_now (R,))``: the distances of ``points`` and of the robots' positions.
    """
    from navzoo.world.geometry import segment_point_distance

    reach = np.broadcast_to(np.asarray(reach, dtype=np.float64), (idx.size,))
    dist = np.full(points.shape[:-1], np.inf)
    dist0 = np.full(idx.size, np.inf)
    seg = env.segments
    if len(seg) == 0:
        return dist, dist0
    d_robot = segment_point_distance(seg, env.pos[idx])  # (R, M)
    for k in range(idx.size):
        near = d_robot[k] <= reach[k]
        if near.any():
            dist0[k] = d_robot[k, near].min()
            pts = points[k].reshape(-1, 2)
            if exact_within is None:
                dist[k] = segment_point_distance(seg[near], pts).min(axis=1).reshape(points.shape[1:-1])
                continue
            approx = env.grid.distance_at(pts)
            close = approx <= exact_within + 1.5 * env.grid.resolution
            if close.any():
                approx[close] = segment_point_distance(seg[near], pts[close]).min(axis=1)
            dist[k] = approx.reshape(points.shape[1:-1])
    return dist, dist0


def obstacle_speed_filter(env: NavEnv, idx: np.ndarray, actions: np.ndarray, margin: float = 0.05,
                          step: float = 0.05) -> np.ndarray:
    """Scale down the forward speed of differential-drive actions that would hit a wall.

    A controller that plans holonomic velocities (ORCA, social force) and tracks them with a
    differential-drive base drives along its heading, not along the planned velocity, while it
    turns; near a wall or pillar that can close the gap. For each robot, the largest of
    ``v * (1, 0.75, 0.5, 0.25, 0)`` whose arc, held for one step and then braked at ``max_accel``,
    keeps ``margin`` from the walls (or does not get closer, if already inside it) is kept.

    Args:
        env: the env.
        idx: (R,) robot indices.
        actions: (R, 2) normalised (v, omega) actions.
        margin: clearance beyond the robot's radius (m).
        step: time between checked points (s).

    Returns:
        The actions with ``a[:, 0]`` scaled down where needed (float32).
    """
    spec, dt = env.config.robot, env.config.dt
    acts = np.asarray(actions, dtype=np.float64).copy()
    if idx.size == 0 or len(env.segments) == 0:
        return acts.astype(np.float32)
    prev = env.cmd[idx]
    target = acts * np.array([spec.max_speed, spec.max_turn_rate])
    lim = np.array([spec.max_accel, spec.max_ang_accel]) * dt
    cmd = prev + np.clip(target - prev, -lim, lim)  # what the base will actually do
    scales = np.array([1.0, 0.75, 0.5, 0.25, 0.0])
    cand = np.stack([cmd[:, None, 0] * scales, np.broadcast_to(cmd[:, None, 1], (idx.size, scales.size))], axis=-1)
    v = np.abs(cand[..., 0])  # (R, S)
    t_stop = dt + spec.max_speed / (2.0 * spec.max_accel)  # distance v dt + v^2/(2a) <= v * t_stop
    t = step * np.arange(1, int(np.ceil(t_stop / step)) + 1)
    traj, _ = _rollout(env.pos[idx], env.yaw[idx], cand, t, True)  # (R, S, K, 2)
    radius = env.radius[idx]
    reach = spec.max_speed * t_stop + radius + margin + 0.5
    dist, dist0 = static_clearance(env, idx, traj, reach)
    clear = dist - radius[:, None, None] - margin
    clear0 = dist0 - radius - margin
    # Points beyond each candidate's stopping distance do not count.
    within = t[None, None, :] * np.where(v > 0, 1.0, 0.0)[..., None] <= (dt + v / (2.0 * spec.max_accel))[..., None]
    bad = (within & (clear < np.minimum(0.0, clear0)[:, None, None] - 1e-3)).any(axis=2)  # (R, S)
    bad[:, -1] = False  # stopping is always allowed
    first_ok = np.argmax(~bad, axis=1)
    keep = scales[first_ok]
    reduce = keep < 1.0
    # Ask for the scaled speed (rate limits still apply in the env).
    acts[reduce, 0] = cand[reduce, first_ok[reduce], 0] / spec.max_speed
    return acts.astype(np.float32)


def _robot_indices(observations: dict[str, Any], env: NavEnv) -> np.ndarray:
    live = set(env.agents)
    return np.array([env._index[a] for a in observations if a.startswith("robot_") and a in live], dtype=int)


def _check_kinematics(kinematics: str | None, env: NavEnv, name: str) -> None:
    actual = env.config.robot.kinematics
    if kinematics is not None and kinematics != actual:
        raise ValueError(f"policy {name!r} is for {kinematics!r} robots but this env's robot is {actual!r}; "
                         f"use the matching variant or kinematics=None to follow the env")
