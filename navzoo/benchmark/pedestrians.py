"""Evaluate the physics pedestrians: ``navzoo eval pedestrians [--quick] [--json]``.

Four measurements of the shipped AMP controller (``policies/amp_pedestrian``), as the paper's
"Quantitative Evaluation of Pedestrian Simulation":

* **tracking** of reference clips in closed loop (:mod:`navzoo.agents.amp.tracking`);
* **following**: ``human_model="amp"`` pedestrians in the library scenes (3-15 per scene, one scene
  after the other) for ``seconds`` each, on social-force target trajectories. Every walk from a start
  to a goal is a *trip*; a trip ends at the goal, in a fall (the person is done: falls are counted,
  not reset away) or in a timeout (longer than ``2 x shortest path / preferred speed + 10 s``). A trip
  is a *success* when it reaches its goal with the path error staying below 0.5 m throughout
  (METRICS.md). Rates are shares of ended trips: success, goal reached (with any path error), fall,
  map collision (the body touched a scene obstacle during the trip), agent collision (it touched
  another person or a robot). Trips still under way when the scene's time is up are not counted
  (``trips_running``). Path error: distance of the root from the current target point, averaged over
  all steps of standing pedestrians. :func:`following` also runs other target generators
  (``crowd_model``, e.g. the diffusion crowd) and kinematic bodies (``human_model``), for the
  reliability table of ``navzoo eval crowd`` (:mod:`navzoo.benchmark.crowd_eval`);
* **realism** (:mod:`navzoo.benchmark.realism`) of the poses of the AMP pedestrians of the following
  run and of kinematic pedestrians (walk-cycle replay) run the same way, against the reference clips;
* **throughput** with pedestrians only: agent steps/s (one agent step = one 30 Hz control step of one
  pedestrian, policy inference included) for 1-64 pedestrians.

It also writes a video of an AMP crowd (``--video``). ``--quick`` runs a reduced version with the same
keys in a few minutes. ``--seeds 0,1,2,3`` runs the following protocol once per seed (one seed moves its
success rate by several points) and adds each seed's rates and their spread.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections import deque
from pathlib import Path
from typing import Any

import numpy as np
import pybullet as p

from navzoo.benchmark import realism
from navzoo.envs.nav_env import _path_length

SCENES = ("station", "home", "grocery", "circle_crossing", "square_crossing", "corridor", "doorway", "lobby")
#: Library scenes held out from everything the following protocol's figures were tuned or trained on: none is one
#: of :data:`SCENES` (where every target setting was chosen) or one of the 16 scenes of the AMP controller's scene
#: training. The diffusion model's simulated training windows do come from nine of them (60 s of social-force and
#: ORCA crowds each; ``museum_hall`` was its validation scene). People: 3-15 as :func:`people_per_scene` spreads
#: them, given in order of free floor area (the narrow L corridor 3, the parking garage 15).
HELDOUT_SCENES = (("l_corridor", 3), ("t_junction", 4), ("cluttered_room", 6), ("bottleneck", 7), ("lecture_hall", 8),
                  ("library_stacks", 10), ("office_cubicles", 11), ("museum_hall", 12), ("warehouse_aisles", 14),
                  ("parking_garage", 15))
#: ``--scenes heldout`` (``navzoo eval pedestrians``, ``navzoo eval crowd``): the scenes of :data:`HELDOUT_SCENES`.
HELDOUT = "heldout"
DT = 1.0 / 30.0


def expand_scenes(names: Any) -> tuple[str, ...]:
    """Scene names (a list, or one comma-separated string) with ``heldout`` standing for the scenes of
    :data:`HELDOUT_SCENES`, in their order; unknown names and an empty list are refused, naming the valid scenes.
    Their people, spread 3-15 over the held-out scenes by :func:`people_per_scene`, are HELDOUT_SCENES' own counts."""
    from navzoo.world.library import list_scenes

    items = _name_items(names)
    held = [name for name, _ in HELDOUT_SCENES]
    scenes = tuple(s for item in items if item for s in (held if item == HELDOUT else [item]))
    known = list_scenes()
    bad = [s for s in scenes if s not in known]
    if bad or not scenes:
        what = f"unknown scene(s) {bad!r}" if bad else "no scene given"
        raise ValueError(f"{what}; choose from {', '.join(known)} (or '{HELDOUT}' for the ten held-out scenes)")
    return scenes


def _name_items(names: Any) -> list[str]:
    """A comma-separated string or a list of names, as stripped strings."""
    return [v.strip() for v in names.split(",")] if isinstance(names, str) else [str(v).strip() for v in names]


#: ``protocol`` in a result filter (:func:`scene_names`): the eight scenes of :data:`SCENES`.
PROTOCOL = "protocol"


def scene_names(names: Any) -> tuple[str, ...]:
    """Scene names for filtering result files: as :func:`expand_scenes`, and ``protocol`` also stands for the eight
    scenes of :data:`SCENES`; duplicates kept once, in order."""
    items = [s for item in _name_items(names) for s in (SCENES if item == PROTOCOL else [item])]
    return tuple(dict.fromkeys(expand_scenes(items)))


def people_per_scene(n_scenes: int, lo: int = 3, hi: int = 15) -> list[int]:
    """``lo`` .. ``hi`` pedestrians spread evenly over the scenes."""
    if n_scenes == 1:
        return [lo]
    return [int(round(lo + (hi - lo) * k / (n_scenes - 1))) for k in range(n_scenes)]


def parse_scene_counts(text: str) -> list[tuple[str, int]]:
    """``(scene, people)`` pairs, in order, from a ``--scenes`` option of the form ``"lobby:15,corridor:12"``.

    Items and their two parts are stripped of whitespace. An item without a scene name, without a count, with a
    count that is not a whole number or one below 1 raises :class:`ValueError` naming that item. Scene names are not
    checked against the library here (a scene that does not exist fails when it is built)."""
    out = []
    for item in text.split(","):
        name, _, n = (part.strip() for part in item.strip().partition(":"))
        if not name or not (n.isascii() and n.isdigit()) or int(n) < 1:
            raise ValueError(f"--scenes: {item.strip()!r} is not SCENE:PEOPLE (e.g. lobby:15)")
        out.append((name, int(n)))
    return out


def _make(scene: str, n: int, human_model: str, seconds: float, seed: int, policy_dir: str | None,
          crowd_model: str = "sfm", env_overrides: dict[str, Any] | None = None, steering_trim: float | None = None):
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    env = NavEnv(scene=scene, n_robots=0, n_humans=n, human_model=human_model, dt=DT, crowd_model=crowd_model,
                 time_limit=seconds, **(env_overrides or {}))
    if human_model == "amp":
        from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

        policy: Any = AmpPedestrianPolicy(policy_dir, steering_trim=steering_trim)
    else:
        from navzoo.agents.crowd import CrowdPolicy

        policy = CrowdPolicy(crowd_model)
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
    wrapped.reset(seed=seed)
    return wrapped, env


#: NavConfig fields the following protocol sets itself (:func:`_make`), not open to ``env_overrides``.
PROTOCOL_FIELDS = ("scene", "n_robots", "n_humans", "human_model", "dt", "crowd_model", "time_limit")


def check_env_overrides(overrides: dict[str, Any] | None) -> dict[str, Any]:
    """``overrides`` (NavConfig fields for the following runs) checked before any run: a ValueError names a field
    NavConfig lacks, a field the protocol sets itself (:data:`PROTOCOL_FIELDS`) or a value NavConfig refuses."""
    import dataclasses

    from navzoo.envs.config import NavConfig

    out = dict(overrides or {})
    known = {f.name for f in dataclasses.fields(NavConfig)}
    unknown = sorted(k for k in out if k not in known)
    if unknown:
        raise ValueError(f"unknown NavConfig field(s) {unknown}")
    fixed = sorted(k for k in out if k in PROTOCOL_FIELDS)
    if fixed:
        raise ValueError(f"{fixed} are set by the following protocol itself, not by --set")
    NavConfig(human_model="amp", dt=DT, **out)  # a refused value raises its own ValueError, naming the field
    return out


def body_keypoints(client: int, ids: list[int]) -> np.ndarray:
    """(H, 15, 3) link frame origins (joint centres) of humanoid bodies, read from PyBullet, in the
    order of :data:`navzoo.benchmark.realism.KEYPOINT_NAMES` (works for kinematic and physics bodies)."""
    out = np.empty((len(ids), realism.N_KEYPOINTS, 3))
    links = list(range(realism.N_KEYPOINTS))
    for k, b in enumerate(ids):
        states = p.getLinkStates(b, links, computeForwardKinematics=1, physicsClientId=client)
        out[k] = [s[4] for s in states]
    return out


def kinematic_contacts(env) -> tuple[np.ndarray, np.ndarray]:
    """(H,) bools for kinematic pedestrians, which have no physics contacts: *map contact* when the
    person's centre is closer than its radius to an obstacle edge or the scene bounds
    (``env.segments``, exact point-segment distance); *agent contact* when its centre is closer than
    the sum of the two radii (``env.radius``, 2 x 0.3 m for two people) to another person or a live robot."""
    from navzoo.world.geometry import min_distance_to_segments

    R, N = env.n_robots, env.n_total
    h = np.arange(R, N)
    if h.size == 0:
        return np.zeros(0, dtype=bool), np.zeros(0, dtype=bool)
    map_hit = min_distance_to_segments(env.pos[h], env.segments) < env.radius[h]
    d = np.linalg.norm(env.pos[h][:, None, :] - env.pos[None, :, :], axis=2) - env.radius[h][:, None] - env.radius[None, :]
    d[np.arange(h.size), h] = np.inf  # not oneself
    d[:, ~env.alive] = np.inf  # removed robots
    return map_hit, (d < 0.0).any(axis=1)


def target_points(env) -> np.ndarray | None:
    """(H, 2) the point each pedestrian should be at now, for the path error, or None where there is none.

    AMP pedestrians: the current point of their target trajectory (``env.amp.target_now()``, for every
    crowd model). Kinematic pedestrians of the ``"diffusion"`` crowd: the current point of their
    diffusion plan (``DiffusionCrowd.points_now``: linear between the plan's 0.4 s points, which start
    at the person's ``plan_t0``; the social force between plans makes them deviate from it). Kinematic
    pedestrians of rule-based crowds have no target trajectory besides their own motion: None (not
    applicable).
    """
    if env.amp is not None:
        return env.amp.target_now()
    return env.diffusion.points_now(env) if env.diffusion is not None else None


def remaining_path_length(env, i: int) -> float:
    """Length (m) of agent ``i``'s A* path still ahead: from its position through the waypoints it has not
    reached yet (``env.wp_index``) to the path's end (its goal). A new trip's time limit is measured on it:
    after a goal, on the path just planned; after a timeout, on what is left of the same path (not the
    whole path again, which held the part already walked)."""
    path = env.paths[i]
    return _path_length(path[min(int(env.wp_index[i]), len(path) - 1):], env.pos[i])


class Trips:
    """The trip bookkeeping of the following protocol, for the ``n`` pedestrians of ``env``.

    A trip starts at the episode's start or where the person's previous trip ended. It ends at its goal
    (``"success"`` when the path error stayed below 0.5 m throughout, else ``"off_path"``), in a fall
    (``"fall"``; the person is then done for the rest of the scene) or when it has taken longer than
    ``2 x path / preferred speed + 10 s`` (``"timeout"``). The path of a new trip is the one just planned
    after a goal, or what is left of the same path after a timeout (:func:`remaining_path_length`).

    It also counts *goal trips*, one per goal (``goal_ended`` after each :meth:`update`, and
    :meth:`finish` at the scene's end): a goal trip runs from where the person got its goal to that
    goal, or to a fall. It is a success or off-path trip when it reached the goal within its first
    limit, a fall when the person fell on the way (also after the limit: falls are never hidden), and a
    timeout when it passed the limit, counted once, however long the person then stays stuck. The
    per-limit trips above count a person stuck in a jam once per limit, about every 10-15 s.
    """

    def __init__(self, env, n: int) -> None:
        self.env, self.n, self.R = env, n, env.n_robots
        h = np.arange(self.R, self.R + n)
        self.start = np.zeros(n)  # sim time each current trip started
        self.limit = 2.0 * env.shortest_path_length[h] / env.v_pref[h] + 10.0
        self.done = np.zeros(n, dtype=bool)  # fallen: no more trips
        self.max_err = np.zeros(n)
        self._goals = env.goals_reached[h].copy()
        self.goal_start = np.zeros(n)  # the goal trips: one per goal
        self.goal_limit = self.limit.copy()
        self.goal_max_err = np.zeros(n)
        self.goal_late = np.zeros(n, dtype=bool)  # past its limit, not yet at its goal
        self.goal_ended: list[tuple[int, str]] = []  # the goal trips that ended in the last update

    def update(self, err: np.ndarray | None, fallen: np.ndarray) -> list[tuple[int, str, float, float]]:
        """After an env step: fold this step's path error (None: no target trajectory) of the standing
        people into their trips, end the trips that ended; returns ``(person, outcome, duration_s,
        limit_s)`` of each, with the next trip already started."""
        env, R, n = self.env, self.R, self.n
        t = env.sim_time
        live = ~self.done
        if err is not None:
            self.max_err = np.where(live & ~fallen, np.maximum(self.max_err, err), self.max_err)
            self.goal_max_err = np.where(live & ~fallen, np.maximum(self.goal_max_err, err), self.goal_max_err)
        goals = env.goals_reached[R:R + n]
        outcome = np.full(n, "", dtype=object)
        outcome[fallen & live] = "fall"
        at_goal = (goals > self._goals) & live & (outcome == "")
        outcome[at_goal] = np.where(self.max_err[at_goal] < 0.5, "success", "off_path")
        self._end_goal_trips(t, at_goal, fallen & live)
        outcome[live & (outcome == "") & (t - self.start > self.limit)] = "timeout"
        ended = []
        for j in np.flatnonzero(outcome != ""):
            ended.append((int(j), str(outcome[j]), t - float(self.start[j]), float(self.limit[j])))
            self.max_err[j] = 0.0
            self.start[j] = t
            self.limit[j] = 2.0 * remaining_path_length(env, R + j) / env.v_pref[R + j] + 10.0
            if outcome[j] == "fall":
                self.done[j] = True
        self._goals = goals.copy()
        return ended

    def _end_goal_trips(self, t: float, at_goal: np.ndarray, fell: np.ndarray) -> None:
        """Fold this step into the goal trips (see the class docstring)."""
        self.goal_ended = []
        for j in np.flatnonzero(fell | at_goal):
            if fell[j]:
                out = "fall"
            elif self.goal_late[j] or t - self.goal_start[j] > self.goal_limit[j]:
                out = "timeout"
            else:
                out = "success" if self.goal_max_err[j] < 0.5 else "off_path"
            self.goal_ended.append((int(j), out))
            if not fell[j]:  # the next goal's trip, on the path just planned
                self.goal_start[j] = t
                self.goal_limit[j] = 2.0 * remaining_path_length(self.env, self.R + j) / self.env.v_pref[self.R + j] + 10.0
                self.goal_max_err[j] = 0.0
                self.goal_late[j] = False
        self.goal_late |= ~self.done & ~fell & (t - self.goal_start > self.goal_limit)

    def finish(self) -> list[int]:
        """At the scene's end: the people whose goal trip is past its limit (their trips end as timeouts;
        goal trips still within their limit are not counted, as trips under way)."""
        late = self.goal_late | (~self.done & (self.env.sim_time - self.goal_start > self.goal_limit))
        return [int(j) for j in np.flatnonzero(late & ~self.done)]


def follow_scene(scene: str, n: int, seconds: float = 200.0, seed: int = 0, policy_dir: str | None = None,
                 pose_every: int = 1, max_poses: int = 20_000, crowd_model: str = "sfm",
                 human_model: str = "amp", env_overrides: dict[str, Any] | None = None,
                 steering_trim: float | None = None) -> dict[str, Any]:
    """One scene of :func:`following`: trip outcomes, contact flags, path error sums and poses.

    ``crowd_model`` makes the target trajectories (AMP) or drives the bodies (kinematic);
    ``env_overrides`` are further NavConfig fields (e.g. ``{"human_fallen_obstacles": True}``);
    ``steering_trim`` overrides the AMP policy's (:class:`AmpPedestrianPolicy`). Kinematic
    pedestrians never fall; their contacts are geometric (:func:`kinematic_contacts`) and their path
    error is measured against :func:`target_points` (none for rule-based crowds: ``err_n`` stays 0,
    ``path_error`` is False, and a trip that reaches its goal is a success).

    The run uses one torch thread, however it is called (a worker of a pool or the calling process): the
    policy's and the diffusion model's float sums then do not depend on the thread count, so ``--workers 1``
    and ``--workers N`` give the same trips on one machine. Runs on another kind of CPU can still diverge.
    """
    if human_model not in ("amp", "kinematic"):
        raise ValueError(f"human_model must be 'amp' or 'kinematic', got {human_model!r}")
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread():
        return _follow_scene(scene, n, seconds, seed, policy_dir, pose_every, max_poses, crowd_model, human_model,
                             env_overrides, steering_trim)


def _follow_scene(scene: str, n: int, seconds: float, seed: int, policy_dir: str | None, pose_every: int,
                  max_poses: int, crowd_model: str, human_model: str, env_overrides: dict[str, Any] | None,
                  steering_trim: float | None) -> dict[str, Any]:
    t0 = time.time()
    wrapped, env = _make(scene, n, human_model, seconds, seed, policy_dir, crowd_model, env_overrides, steering_trim)
    amp = env.amp is not None
    body_ids = env.amp.ids if amp else env.humans.ids
    has_target = amp or env.diffusion is not None
    R = env.n_robots
    h = np.arange(R, env.n_total)
    trips = Trips(env, n)
    done = trips.done
    m_flag = np.zeros(n, dtype=bool)
    a_flag = np.zeros(n, dtype=bool)
    ended = {"success": 0, "off_path": 0, "fall": 0, "timeout": 0}
    map_trips = agent_trips = 0
    by_goal = dict.fromkeys(("success", "off_path", "fall", "timeout", "map_trips", "agent_trips"), 0)
    m_goal = np.zeros(n, dtype=bool)  # contacts during each person's goal trip
    a_goal = np.zeros(n, dtype=bool)
    err_sum, err_n = 0.0, 0
    poses: list[np.ndarray] = []
    walk = [env.pos[h].copy()]  # the walked centres, NaN once a body has fallen
    n_poses = steps = 0
    contact_steps = np.zeros(3, dtype=np.int64)  # person-steps in wall contact, in people contact, standing
    falls = FallLog(env) if amp else None
    while not env._needs_reset:
        wrapped.step({})
        steps += 1
        live = ~done
        if amp:
            map_now, agent_now, fallen = env.human_map_contact, env.human_agent_contact, env.human_fallen
        else:
            (map_now, agent_now), fallen = kinematic_contacts(env), np.zeros(n, dtype=bool)
        m_flag |= map_now & live
        a_flag |= agent_now & live
        m_goal |= map_now & live
        a_goal |= agent_now & live
        standing = live & ~fallen
        contact_steps += (int((map_now & standing).sum()), int((agent_now & standing).sum()), int(standing.sum()))
        walk.append(np.where(fallen[:, None], np.nan, env.pos[h]))
        target = target_points(env) if has_target else None
        if falls is not None:
            falls.update(map_now, fallen, target)
        err = None
        if target is not None:
            err = np.linalg.norm(env.pos[h] - target, axis=1)
            err_sum += float(err[standing].sum())
            err_n += int(standing.sum())
        if pose_every and steps % pose_every == 0 and n_poses < max_poses and standing.any():
            kp = body_keypoints(env.client, [body_ids[j] for j in np.flatnonzero(standing)])
            poses.append(realism.normalize_poses(kp))
            n_poses += len(kp)
        for j, outcome, _, _ in trips.update(err, fallen):
            ended[outcome] += 1
            map_trips += int(m_flag[j])
            agent_trips += int(a_flag[j])
            m_flag[j] = a_flag[j] = False
        for j, outcome in trips.goal_ended:
            _count_goal_trip(by_goal, outcome, m_goal, a_goal, j)
    for j in trips.finish():
        _count_goal_trip(by_goal, "timeout", m_goal, a_goal, j)
    if falls is not None:
        falls.finish()
    from navzoo.benchmark.crowd_eval import walked_collisions, walked_kinematics

    walked = np.asarray(walk)
    walk_kin = walked_kinematics(walked, float(env.config.dt))
    walk_hits = walked_collisions(walked)
    wrapped.close()
    label = "" if (crowd_model, human_model) == ("sfm", "amp") else f" [{crowd_model}+{human_model}]"
    print(f"following{label} {scene} ({n} pedestrians, {seconds:.0f} s): {ended} in {time.time() - t0:.0f} s",
          file=sys.stderr, flush=True)
    return {
        "scene": scene, "pedestrians": n, **ended, "map_trips": map_trips, "agent_trips": agent_trips,
        "err_sum": err_sum, "err_n": err_n, "path_error": has_target, "running": int((~done).sum()),
        "by_goal": by_goal, "walk_collisions": list(walk_hits), "contact_steps": [int(c) for c in contact_steps],
        "wall_s": round(time.time() - t0, 1), "fall_events": falls.events if falls is not None else [],
        **({"slow_s": round(falls.slow_s, 1), "moving_s": round(falls.moving_s, 1)} if falls is not None else {}),
        "poses": np.concatenate(poses) if poses else np.zeros((0, realism.POSE_DIM)),
        "walk_kin": walk_kin,
    }


class FallLog:
    """Each fall of a physics pedestrian in a following run, with what came before it (``fall_events`` of the rows
    of :func:`follow_scene`): when and where (``t``, ``id``, ``x``, ``y``: the body's planar root when the fall is
    detected), how long since the body last touched another standing person or a robot (``since_agent_s``), a
    wall or an obstacle (``since_map_s``) and a body that had fallen before (``since_fallen_s``), and how far its
    key bodies were from those of an earlier fallen body (``fallen_m``) and its root from the nearest standing
    person (``person_m``). Times since are ``None`` when it never happened in the run; ``fallen_m`` is ``None``
    when nobody had fallen. :meth:`finish` adds ``slid_m``, how far the root lies at the end of the run from where
    the fall was detected. A fall is detected when the body is already down (``AmpBodies.fallen``), about half a
    second after what tipped it, so a touch ``FALL_CAUSE_S`` before counts (:func:`fall_cause`).

    How the body moved before it fell, over the window ``MOTION_WINDOW_S`` (from 2.0 to 0.5 s before the fall was
    detected; ``None`` for a fall within 0.5 s of the run's start): ``speed_mps``, the mean planar speed of its
    root; ``turn_rad_s``, the mean absolute yaw rate; ``target_speed_mps``, the mean speed of its target point
    (:func:`target_points`, jumps at replans included; ``None`` without targets); and ``lag_m``, how far the target point was from the body
    at the window's end. A body that falls while slow, with a slow target, fell while standing or shuffling, not
    while walking. ``slow_s`` and ``moving_s`` add up the person-seconds of the bodies still up, slower than
    ``SLOW_MPS`` and not, so falls per minute can be set against the time spent in each (``scripts/fall_causes.py``)."""

    def __init__(self, env) -> None:
        self.env = env
        n = env.n_humans
        self.index = {b: j for j, b in enumerate(env.amp.ids)}
        self.last_agent = np.full(n, -np.inf)
        self.last_map = np.full(n, -np.inf)
        self.last_fallen = np.full(n, -np.inf)
        self.prev = np.zeros(n, dtype=bool)
        self.events: list[dict[str, Any]] = []
        self.h = np.arange(env.n_robots, env.n_total)
        dt = float(env.config.dt)
        self.lead = int(round(MOTION_WINDOW_S[1] / dt))  # steps from the window's end to the detection
        # the last steps' (speed (H,), |yaw rate| (H,), position (H, 2), target (H, 2) or None), newest last
        self.motion: deque = deque(maxlen=int(round(MOTION_WINDOW_S[0] / dt)) + 1)
        self.slow_s = self.moving_s = 0.0

    def update(self, map_now: np.ndarray, fallen: np.ndarray, target: np.ndarray | None = None) -> None:
        """After an env step: ``map_now`` (H,) touching a wall or an obstacle, ``fallen`` (H,) down (the env's),
        ``target`` (H, 2) the pedestrians' target points now (:func:`target_points`), or None where there are none."""
        env, t = self.env, float(self.env.sim_time)
        speed = np.linalg.norm(env.vel[self.h], axis=1)
        self.motion.append((speed, np.abs(env.omega[self.h]), env.pos[self.h].copy(),
                            None if target is None else np.asarray(target, dtype=np.float64).copy()))
        up = ~fallen
        n_slow = int((up & (speed < SLOW_MPS)).sum())
        self.slow_s += n_slow * float(env.config.dt)
        self.moving_s += (int(up.sum()) - n_slow) * float(env.config.dt)
        # a fallen body is "a human" to env.amp.contacts(): tell its touches (fallen before this step) from the others
        touched = env.amp.touched
        down = {b for b, k in self.index.items() if self.prev[k]}
        touching_fallen = np.array([bool(bs & down) for bs in touched]) & ~self.prev
        self.last_fallen[touching_fallen] = t
        self.last_agent[[bool(bs - down) for bs in touched]] = t  # a standing person or a robot
        self.last_map[map_now] = t
        new = np.flatnonzero(fallen & ~self.prev)
        if new.size:
            s = env.amp.state()
            root, key = s["root_pos"][:, :2], s["key_pos"][:, :, :2]
            standing = np.flatnonzero(~fallen)
            for j in new:
                before = np.flatnonzero(self.prev)
                fallen_m = (float(np.linalg.norm(key[j][:, None] - key[before].reshape(-1, 2)[None], axis=2).min())
                            if before.size else None)
                others = standing[standing != j]
                person_m = float(np.linalg.norm(root[others] - root[j], axis=1).min()) if others.size else None
                self.events.append({
                    "t": round(t, 2), "id": int(j), "x": round(float(root[j, 0]), 2), "y": round(float(root[j, 1]), 2),
                    **{f"since_{k}_s": (round(t - float(v[j]), 2) if np.isfinite(v[j]) else None)
                       for k, v in (("agent", self.last_agent), ("map", self.last_map), ("fallen", self.last_fallen))},
                    "fallen_m": None if fallen_m is None else round(fallen_m, 3),
                    "person_m": None if person_m is None else round(person_m, 3),
                    **self._motion_before(int(j)),
                })
        self.prev = fallen.copy()

    def _motion_before(self, j: int) -> dict[str, float | None]:
        """Person ``j``'s motion over ``MOTION_WINDOW_S`` before now (the keys of the class docstring)."""
        window = list(self.motion)[:len(self.motion) - self.lead]
        if len(window) < 2:
            return dict.fromkeys(("speed_mps", "turn_rad_s", "target_speed_mps", "lag_m"))
        dt = float(self.env.config.dt)
        targets = [w[3] for w in window]
        if any(x is None for x in targets):
            target_speed = lag = None
        else:
            tj = np.array([x[j] for x in targets])
            target_speed = round(float(np.linalg.norm(np.diff(tj, axis=0), axis=1).mean() / dt), 3)
            lag = round(float(np.linalg.norm(tj[-1] - window[-1][2][j])), 3)
        return {"speed_mps": round(float(np.mean([w[0][j] for w in window])), 3),
                "turn_rad_s": round(float(np.mean([w[1][j] for w in window])), 3),
                "target_speed_mps": target_speed, "lag_m": lag}

    def finish(self) -> None:
        """At the end of the run: how far each fallen body's root lies from where its fall was detected
        (``slid_m``: it slides and rolls on after it is found fallen)."""
        if not self.events:
            return
        root = self.env.amp.state()["root_pos"][:, :2]
        for e in self.events:
            e["slid_m"] = round(float(np.hypot(root[e["id"], 0] - e["x"], root[e["id"], 1] - e["y"])), 2)


FALL_CAUSE_S = 1.5
MOTION_WINDOW_S = (2.0, 0.5)  # s before a fall's detection: the window of FallLog's motion keys
SLOW_MPS = 0.3  # m/s: slower than this a body stands or shuffles (the clips hold 2 % of their frames below it)


def fall_cause(event: dict[str, Any], within: float = FALL_CAUSE_S) -> str:
    """What most likely tipped a fall of :class:`FallLog`: the most recent touch within ``within`` s before
    the fall was detected, ``"fallen body"``, ``"person"`` (a standing person or a robot) or ``"wall"``; else
    ``"none"`` (the body fell on its own: a stumble, a sharp turn)."""
    recent = {name: event[key] for name, key in (("fallen body", "since_fallen_s"), ("person", "since_agent_s"),
                                                   ("wall", "since_map_s"))
              if event.get(key) is not None and event[key] <= within}
    return min(recent, key=recent.get) if recent else "none"


def _count_goal_trip(counts: dict[str, int], outcome: str, m_goal: np.ndarray, a_goal: np.ndarray, j: int) -> None:
    counts[outcome] += 1
    counts["map_trips"] += int(m_goal[j])
    counts["agent_trips"] += int(a_goal[j])
    m_goal[j] = a_goal[j] = False


def _pool_map(fn, jobs: list[tuple], workers: int) -> list[Any]:
    if workers <= 1 or len(jobs) <= 1:
        return [fn(*j) for j in jobs]
    with _pool(workers, len(jobs)) as pool:
        return pool.starmap(fn, jobs)


def _pool(workers: int, n_jobs: int):
    """A spawn pool of ``min(workers, n_jobs)`` single-threaded worker processes."""
    import multiprocessing as mp

    return mp.get_context("spawn").Pool(min(workers, n_jobs), initializer=_one_thread)


def _one_thread() -> None:
    """Worker processes: one torch thread each (W workers x all-cores torch pools oversubscribe)."""
    import torch

    torch.set_num_threads(1)


def following(scenes: tuple[str, ...] = SCENES, seconds: float = 200.0, seed: int = 0,
              policy_dir: str | None = None, workers: int = 1, crowd_model: str = "sfm",
              human_model: str = "amp", pose_every: int = 1,
              people: list[int] | None = None,
              seeds: list[int] | None = None,
              resume: str | Path | None = None,
              walked: bool = False,
              real_kin: dict[str, np.ndarray] | None = None,
              env_overrides: dict[str, Any] | None = None) -> tuple[dict[str, Any], np.ndarray]:
    """Trip outcomes of AMP pedestrians in ``scenes`` (3-15 people, one process per scene with
    ``workers`` > 1); returns (metrics, poses (M, 45) of the standing pedestrians, for realism).

    ``crowd_model`` / ``human_model`` select the target trajectories and the bodies (default: social
    force targets for AMP pedestrians, the paper's SFM+AMP row); see :func:`follow_scene` for what
    changes with kinematic bodies. ``path_error_m`` is None where no scene has a target trajectory
    (kinematic pedestrians of a rule-based crowd). ``pose_every=0`` records no poses. ``people``: the
    number of pedestrians of each scene (default :func:`people_per_scene`).

    ``seeds`` (instead of ``seed``) runs every scene once per seed, all (scene, seed) runs in one pool.
    The rates are then pooled over the trips of all seeds; ``by_seed`` has each seed's own rates and
    ``success_rate_seed_sd`` their spread (sample standard deviation), since one seed moves the success
    rate by several points. Scene rows carry their ``seed``. The poses returned are the first seed's
    (realism is then measured on the same poses as a single-seed run of that seed).

    ``resume``: a JSON-lines file that keeps every finished (scene, seed) run as it ends (its poses in
    ``<resume>.poses/``). Rerun with the same settings, the runs found there are not run again; a file
    of other settings is refused. :func:`evaluate` uses ``<out>.following.jsonl`` and removes it when done.

    ``env_overrides``: further NavConfig fields for every run (:func:`check_env_overrides`; e.g.
    ``{"amp_wall_strength": 0.3}``); a resumed run must have the same.

    ``walked=True`` adds ``metrics["walked"]``: how the people walked, from their centres at every step (a fallen
    body's track ends at its fall), pooled over all runs, in the terms of the crowd realism
    (:mod:`navzoo.benchmark.crowd_eval`): speed, acceleration and jerk means and medians at 0.4 s, with the
    1-Wasserstein distance and Jensen-Shannon divergence to ``real_kin`` (the real samples of
    :func:`navzoo.benchmark.crowd_eval.real_data`) when given, and the person-person collision rate (centres
    closer than 0.4 m, standing people only).
    """
    if crowd_model not in ("sfm", "orca", "orca_rvo2", "diffusion"):
        raise ValueError(f"crowd_model must be 'sfm', 'orca', 'orca_rvo2' or 'diffusion', got {crowd_model!r}")
    if human_model not in ("amp", "kinematic"):
        raise ValueError(f"human_model must be 'amp' or 'kinematic', got {human_model!r}")
    counts = people_per_scene(len(scenes)) if people is None else list(people)
    if len(counts) != len(scenes):
        raise ValueError(f"need one people count per scene, got {len(counts)} for {len(scenes)} scenes")
    run_seeds = [seed] if seeds is None else check_seeds(seeds)
    overrides = check_env_overrides(env_overrides) or None
    jobs = [(sc, n, seconds, sd, policy_dir, pose_every if k == 0 else 0, 20_000, crowd_model, human_model, overrides)
            for k, sd in enumerate(run_seeds) for sc, n in zip(scenes, counts, strict=True)]
    settings = _settings(scenes, counts, seconds, run_seeds, policy_dir, crowd_model, human_model, pose_every)
    if overrides:  # runs without overrides keep the settings line of older files
        settings["env_overrides"] = overrides
    rows = _run_jobs(jobs, workers, resume, settings if seeds is None else settings | {"multi_seed": True})
    if seeds is None:
        metrics = _following_metrics(rows, seconds)
        if walked:
            metrics["walked"] = _walked_metrics(rows, real_kin)
        return metrics, np.concatenate([r["poses"] for r in rows])
    seeds = run_seeds
    for job, row in zip(jobs, rows, strict=True):
        row["seed"] = job[3]
    metrics = _following_metrics(rows, seconds)
    if walked:
        metrics["walked"] = _walked_metrics(rows, real_kin)
    per_seed = [_following_metrics([r for r in rows if r["seed"] == sd], seconds) for sd in seeds]
    metrics["seeds"] = list(seeds)
    metrics["by_seed"] = [{"seed": sd, **{k: m[k] for k in _SEED_KEYS}} for sd, m in zip(seeds, per_seed, strict=True)]
    rates = [m["success_rate"] for m in per_seed]
    metrics["success_rate_seed_sd"] = float(np.std(rates, ddof=1)) if len(rates) > 1 else None
    return metrics, np.concatenate([r["poses"] for r in rows if r["seed"] == seeds[0]])


def _walked_metrics(rows: list[dict[str, Any]], real_kin: dict[str, np.ndarray] | None) -> dict[str, Any]:
    """The walked kinematics and person-person collisions of ``rows`` pooled (see :func:`following`)."""
    from navzoo.benchmark import crowd_eval

    kin = {q: np.concatenate([r["walk_kin"][q] for r in rows]) for q in crowd_eval.QUANTITIES}
    out = crowd_eval._summary(kin, real_kin)
    hit, total = (sum(r["walk_collisions"][i] for r in rows) for i in (0, 1))
    out["collision_rate"] = hit / max(total, 1)
    out["person_steps"] = total
    return out


def _settings(scenes, counts, seconds, seeds, policy_dir, crowd_model, human_model, pose_every) -> dict[str, Any]:
    """What a resumed following run must share with the interrupted one (the AMP policy and the diffusion
    model by the hash of their config files, which hold their weights' sha256 and the steering trim)."""
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir
    from navzoo.agents.diffusion.crowd import default_model_dir

    out = {"scenes": list(scenes), "people": [int(n) for n in counts], "seconds": float(seconds),
           "seeds": [int(s) for s in seeds], "policy_config_sha256": None, "crowd_model": crowd_model,
           "human_model": human_model, "pose_every": int(pose_every)}
    if human_model == "amp":
        out["policy_config_sha256"] = _config_sha256(Path(policy_dir or default_policy_dir()))
    if crowd_model == "diffusion":
        out["diffusion_config_sha256"] = _config_sha256(default_model_dir())
    return out


def _config_sha256(model_dir: Path) -> str:
    import hashlib

    config = model_dir / "config.json"
    return hashlib.sha256(config.read_bytes()).hexdigest() if config.is_file() else str(model_dir)


def _follow_job(indexed: tuple[int, tuple]) -> tuple[int, dict[str, Any]]:
    return indexed[0], follow_scene(*indexed[1])


def _run_jobs(jobs: list[tuple], workers: int, resume: str | Path | None, settings: dict[str, Any]) -> list[dict]:
    """:func:`follow_scene` over ``jobs`` (rows in job order); with ``resume``, finished rows are kept in
    that file as they end and read back instead of being run again (see :func:`following`)."""
    if resume is None:
        return _pool_map(follow_scene, jobs, workers)
    resume = Path(resume)
    poses_dir = resume.with_name(resume.name + ".poses")
    done: dict[tuple, dict[str, Any]] = {}
    if resume.exists():
        lines = resume.read_text().splitlines()
        good = []
        for line in lines:
            try:
                good.append(json.loads(line))
            except json.JSONDecodeError:  # a run killed while writing its last line
                break
        if not good or "settings" not in good[0]:
            raise ValueError(f"{resume} is not a following-run file of navzoo eval pedestrians (no settings line); "
                             "use another --out or delete it")
        if good[0]["settings"] != settings:
            diff = sorted(k for k in settings.keys() | good[0]["settings"].keys()
                          if settings.get(k) != good[0]["settings"].get(k))
            raise ValueError(f"{resume} holds an interrupted run with other settings ({', '.join(diff)}); rerun with "
                             "the same settings to resume it, or use another --out (or delete the file)")
        for row in good[1:]:
            f, w = _run_arrays(poses_dir, row["scene"], row["pedestrians"], row["job_seed"])
            if f.is_file() and w.is_file() and "walk_collisions" in row:  # older files lack the walked tracks: rerun
                with np.load(w) as kin:
                    walk_kin = {k: kin[k] for k in kin.files}
                done[(row["scene"], row["pedestrians"], row["job_seed"])] = row | {"poses": np.load(f),
                                                                                     "walk_kin": walk_kin}
        resume.write_text("".join(json.dumps(r) + "\n" for r in good[:1] + [
            r for r in good[1:] if (r["scene"], r["pedestrians"], r["job_seed"]) in done]))
    else:
        resume.parent.mkdir(parents=True, exist_ok=True)
        resume.write_text(json.dumps({"settings": settings}) + "\n")
    poses_dir.mkdir(parents=True, exist_ok=True)
    keys = [(j[0], j[1], j[3]) for j in jobs]
    todo = [(i, j) for i, (k, j) in enumerate(zip(keys, jobs, strict=True)) if k not in done]
    if done:
        print(f"following: resuming {resume}: {len(jobs) - len(todo)} of {len(jobs)} runs already done",
              file=sys.stderr, flush=True)

    def keep(i: int, row: dict[str, Any]) -> None:
        sc, n, sd = keys[i]
        # the arrays before the row's line: a listed row has its poses and walked kinematics
        poses_file, walk_file = _run_arrays(poses_dir, sc, n, sd)
        np.save(poses_file, row["poses"])
        np.savez(walk_file, **row["walk_kin"])
        with resume.open("a") as fh:
            fh.write(json.dumps({k: v for k, v in row.items() if k not in ("poses", "walk_kin")} | {"job_seed": sd},
                                default=lambda v: v.item() if isinstance(v, np.generic) else str(v)) + "\n")
        done[keys[i]] = row | {"job_seed": sd}

    if workers <= 1 or len(todo) <= 1:
        for i, job in todo:
            keep(i, follow_scene(*job))
    else:
        with _pool(workers, len(todo)) as pool:
            for i, row in pool.imap_unordered(_follow_job, todo):
                keep(i, row)
    return [{k: v for k, v in done[k_].items() if k != "job_seed"} for k_ in keys]


def _run_arrays(poses_dir: Path, scene: str, n: int, seed: int) -> tuple[Path, Path]:
    """Where :func:`_run_jobs` keeps a finished run's poses (.npy) and walked kinematics (.npz)."""
    stem = f"{scene}_{n}_seed{seed}"
    return poses_dir / f"{stem}.npy", poses_dir / f"{stem}_walk.npz"


def remove_resume_files(resume: Path) -> None:
    import shutil

    resume.unlink(missing_ok=True)
    shutil.rmtree(resume.with_name(resume.name + ".poses"), ignore_errors=True)


_SEED_KEYS = ("success_rate", "goal_rate", "fall_rate", "map_collision_rate", "agent_collision_rate", "path_error_m",
              "timeout_rate", "trips", "per_goal")


def check_seeds(seeds: Any) -> list[int]:
    """A non-empty list of distinct integer seeds, or a ValueError that names the problem."""
    out = list(seeds)
    if not out:
        raise ValueError("seeds must name at least one seed")
    if not all(isinstance(s, int | np.integer) and not isinstance(s, bool) for s in out):
        raise ValueError(f"seeds must be integers, got {out!r}")
    if len(set(out)) != len(out):
        raise ValueError(f"seeds must be distinct, got {out!r}")
    return [int(s) for s in out]


def seeds_option(prog: str, seed: int | None, seeds: str | None) -> list[int] | None:
    """The seeds of a ``--seed S`` / ``--seeds S1,S2,...`` command-line pair (None: one seed), or a
    SystemExit naming the problem."""
    if seeds is None:
        return None
    if seed is not None:
        raise SystemExit(f"{prog}: give --seed or --seeds, not both")
    try:
        return check_seeds([int(x) for x in seeds.split(",")])
    except ValueError as e:
        raise SystemExit(f"{prog}: --seeds {seeds!r}: {e}") from None


def _following_metrics(rows: list[dict[str, Any]], seconds: float) -> dict[str, Any]:
    """Trip rates pooled over ``rows`` of :func:`follow_scene`."""
    n_trips = sum(r["success"] + r["off_path"] + r["fall"] + r["timeout"] for r in rows)
    total = max(1, n_trips)
    timed = all("contact_steps" in r for r in rows)  # runs resumed from files before 2026-12-04 lack them
    steps = np.sum([r["contact_steps"] for r in rows], axis=0) if timed and rows else None
    return {
        "success_rate": sum(r["success"] for r in rows) / total,
        "goal_rate": sum(r["success"] + r["off_path"] for r in rows) / total,
        "fall_rate": sum(r["fall"] for r in rows) / total,
        "map_collision_rate": sum(r["map_trips"] for r in rows) / total,
        "agent_collision_rate": sum(r["agent_trips"] for r in rows) / total,
        "path_error_m": (sum(r["err_sum"] for r in rows) / max(1, sum(r["err_n"] for r in rows))
                         if any(r["path_error"] for r in rows) else None),
        "timeout_rate": sum(r["timeout"] for r in rows) / total,
        # shares of the standing people's time in contact with the scene / with other people (None: not counted)
        "map_contact_time": None if steps is None else float(steps[0] / max(steps[2], 1)),
        "agent_contact_time": None if steps is None else float(steps[1] / max(steps[2], 1)),
        "trips": n_trips,
        "trips_running": sum(r["running"] for r in rows),
        "per_goal": goal_trip_rates([r["by_goal"] for r in rows]) if all("by_goal" in r for r in rows) else None,
        "seconds_per_scene": seconds,
        "scenes": [{k: r[k] for k in ("seed", "scene", "pedestrians", "success", "off_path", "fall", "timeout",
                                      "map_trips", "agent_trips", "by_goal", "contact_steps", "wall_s") if k in r}
                   for r in rows],
    }


def goal_trip_rates(counts: list[dict[str, int]]) -> dict[str, Any]:
    """Rates of the goal trips (one per goal, :class:`Trips`) pooled over scene rows' ``by_goal`` counts."""
    n = sum(c["success"] + c["off_path"] + c["fall"] + c["timeout"] for c in counts)
    rate = {k: sum(c[k] for c in counts) / max(1, n)
            for k in ("success", "off_path", "fall", "timeout", "map_trips", "agent_trips")}
    return {"success_rate": rate["success"], "goal_rate": rate["success"] + rate["off_path"],
            "fall_rate": rate["fall"], "map_collision_rate": rate["map_trips"],
            "agent_collision_rate": rate["agent_trips"], "timeout_rate": rate["timeout"], "trips": n}


def _kinematic_scene(scene: str, n: int, seconds: float, seed: int, max_poses: int) -> np.ndarray:
    wrapped, env = _make(scene, n, "kinematic", seconds, seed, None)
    poses: list[np.ndarray] = []
    count = 0
    while not env._needs_reset and count < max_poses:
        wrapped.step({})
        poses.append(realism.normalize_poses(body_keypoints(env.client, env.humans.ids)))
        count += n
    wrapped.close()
    return np.concatenate(poses)


def kinematic_poses(scenes: tuple[str, ...], seconds: float, seed: int = 0, max_poses: int = 20_000,
                    workers: int = 1) -> np.ndarray:
    """Poses (M, 45) of kinematic (walk-cycle replay) pedestrians run like :func:`following`."""
    jobs = [(sc, n, seconds, seed, max_poses) for sc, n in zip(scenes, people_per_scene(len(scenes)), strict=True)]
    return np.concatenate(_pool_map(_kinematic_scene, jobs, workers))


def throughput(counts: tuple[int, ...] = (1, 2, 4, 8, 16, 32, 64), steps: int = 90, scene: str = "station",
               policy_dir: str | None = None) -> list[dict[str, Any]]:
    """Agent steps/s with pedestrians only (AMP bodies + batched policy), median of 3 timed blocks."""
    rows = []
    for n in counts:
        wrapped, env = _make(scene, n, "amp", 1e6, 0, policy_dir)
        for _ in range(10):
            wrapped.step({})
        blocks = []
        for _ in range(3):
            t0 = time.perf_counter()
            for _ in range(steps // 3):
                wrapped.step({})
            blocks.append((time.perf_counter() - t0) / (steps // 3))
        step_s = float(np.median(blocks))
        rows.append({"pedestrians": n, "env_steps_per_s": 1.0 / step_s, "agent_steps_per_s": n / step_s,
                     "realtime_factor": DT / step_s})
        wrapped.close()
    return rows


def record_video(path: str | Path, scene: str = "lobby", n: int = 12, seconds: float = 12.0, seed: int = 0,
                 policy_dir: str | None = None, size: tuple[int, int] = (800, 450), distance: float = 7.0) -> Path:
    """An mp4 (15 fps) of an AMP crowd: PyBullet TinyRenderer camera 7 m from the crowd's centre,
    following it smoothly and slowly circling."""
    import cv2

    wrapped, env = _make(scene, n, "amp", seconds, seed, policy_dir)
    w, h = size
    proj = p.computeProjectionMatrixFOV(55.0, w / h, 0.1, 100.0, physicsClientId=env.client)
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"), 15, (w, h))
    target = env.pos[env.n_robots:].mean(axis=0)
    k = 0
    while not env._needs_reset:
        wrapped.step({})
        k += 1
        target = 0.97 * target + 0.03 * env.pos[env.n_robots:].mean(axis=0)
        if k % 2 == 0:
            view = p.computeViewMatrixFromYawPitchRoll([target[0], target[1], 0.6], distance, 20.0 + 1.0 * env.sim_time,
                                                       -32.0, 0.0, 2, physicsClientId=env.client)
            img = p.getCameraImage(w, h, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=env.client)[2]
            rgb = np.asarray(img, dtype=np.uint8).reshape(h, w, 4)[..., :3]
            writer.write(cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
    writer.release()
    wrapped.close()
    return path


def evaluate(quick: bool = False, motions: str | None = None, policy_dir: str | None = None, seed: int = 0,
             video: str | None = None, with_throughput: bool = True, workers: int = 1,
             seeds: list[int] | None = None, out_file: str | Path | None = None,
             scenes: Any = None, env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """All four measurements (module docstring). ``seeds`` runs the following protocol once per seed
    (:func:`following`); realism then uses the first seed, as ``seed`` does otherwise. With ``out_file``
    (the CLI's ``--out``) the result is written there, and until then the following runs are kept in
    ``<out_file>.following.jsonl`` as they end, so that an interrupted evaluation rerun with the same
    settings resumes there; that file goes once the result is written. ``scenes``: the scenes of the following
    runs and of the kinematic realism crowd (:func:`expand_scenes`; ``"heldout"`` for the held-out ten), 3-15
    people spread over them; default the protocol's 8 (quick: lobby and corridor)."""
    from navzoo.agents.amp.tracking import load_motions, track_clips

    if seeds is not None:
        seeds = check_seeds(seeds)
        seed = seeds[0]

    t0 = time.time()
    overrides = check_env_overrides(env_overrides)  # before the minutes of clip tracking
    if scenes is not None:
        scenes = expand_scenes(scenes)
    else:
        scenes = ("lobby", "corridor") if quick else SCENES
    seconds = 20.0 if quick else 200.0
    lib = load_motions(motions)
    kwargs = {} if policy_dir is None else {"policy_dir": policy_dir}
    track = track_clips(motions=lib, max_seconds=4.0 if quick else None, **kwargs)
    tracking = {k: track[k] for k in ("mean_pos_error_m", "max_pos_error_m", "mean_rot_error_rad", "clip_success_rate",
                                      "worst_pos_error_m", "fall_rate", "n_clips")}
    resume = Path(str(out_file) + ".following.jsonl") if out_file else None
    follow, amp_poses = following(scenes, seconds, seed, policy_dir, workers=workers, seeds=seeds, resume=resume,
                                  env_overrides=overrides)
    ref = realism.RealismReference.fit(realism.clip_poses(lib), seed=seed)
    kin_poses = kinematic_poses(scenes, seconds, seed, workers=workers)
    keys = ("coverage_k50", "entropy_k50", "dist_k50", "coverage_k100", "entropy_k100", "dist_k100", "mmd")
    out: dict[str, Any] = {
        "tracking": tracking,
        "following": follow,
        "realism": {
            "amp": {k: v for k, v in realism.realism_metrics(amp_poses, ref).items() if k in keys + ("n_generated",)},
            "kinematic": {k: v for k, v in realism.realism_metrics(kin_poses, ref).items() if k in keys + ("n_generated",)},
            "reference_mmd_floor": ref.mmd_floor,
        },
    }
    if with_throughput:
        out["throughput"] = throughput((1, 4, 16) if quick else (1, 2, 4, 8, 16, 32, 64), policy_dir=policy_dir)
    if video:
        out["video"] = str(record_video(video, policy_dir=policy_dir, seconds=6.0 if quick else 12.0))
    if overrides:
        out["env_overrides"] = overrides  # of the following runs only
    out["quick"] = quick
    out["wall_s"] = round(time.time() - t0, 1)
    if out_file:
        Path(out_file).parent.mkdir(parents=True, exist_ok=True)
        Path(out_file).write_text(json.dumps(out, default=float) + "\n")
        remove_resume_files(resume)
    return out


PAPER = {
    "tracking": {"mean_pos_error_m": 0.218, "max_pos_error_m": 0.433, "mean_rot_error_rad": 0.343,
                 "clip_success_rate": 0.646},
    "following": {"success_rate": 0.7424, "fall_rate": 0.0499, "map_collision_rate": 0.0374,
                  "agent_collision_rate": 0.1717, "path_error_m": 0.189},
}


def markdown(result: dict[str, Any]) -> str:
    """Markdown tables of an evaluation result, next to the paper's figures (for docs/pedestrians.md)."""
    def f(v: Any) -> str:
        return f"{v:.3f}" if isinstance(v, float) else str(v)

    lines = ["| tracking | navzoo | paper (Isaac Lab, AMASS) |", "|---|---|---|"]
    for k, ref in PAPER["tracking"].items():
        lines.append(f"| {k} | {f(result['tracking'][k])} | {ref} |")
    lines.append(f"| clips | {result['tracking']['n_clips']} | |")
    lines += ["", "| following | navzoo | paper (SFM+AMP) |", "|---|---|---|"]
    for k, ref in PAPER["following"].items():
        lines.append(f"| {k} | {f(result['following'][k])} | {ref} |")
    fo = result["following"]
    lines.append(f"| goal_rate / timeout_rate | {f(fo['goal_rate'])} / {f(fo['timeout_rate'])} | |")
    lines.append(f"| trips (running at the end) | {fo['trips']} ({fo['trips_running']}) | |")
    if fo.get("per_goal"):
        g = fo["per_goal"]
        lines.append(f"| one trip per goal: success / fall / timeout (trips) | {f(g['success_rate'])} / "
                     f"{f(g['fall_rate'])} / {f(g['timeout_rate'])} ({g['trips']}) | |")
    if "by_seed" in fo:
        sd = fo["success_rate_seed_sd"]
        lines.append(f"| seeds (success sd between seeds) | {', '.join(map(str, fo['seeds']))} "
                     f"({'n/a' if sd is None else f(sd)}) | |")
        lines += ["", "| seed | trips | success | goal | fall | map contact | agent contact | path error (m) | timeout |",
                  "|---|---|---|---|---|---|---|---|---|"]
        for r in fo["by_seed"]:
            lines.append(f"| {r['seed']} | {r['trips']} | {f(r['success_rate'])} | {f(r['goal_rate'])} | "
                         f"{f(r['fall_rate'])} | {f(r['map_collision_rate'])} | {f(r['agent_collision_rate'])} | "
                         f"{f(r['path_error_m'])} | {f(r['timeout_rate'])} |")
    seeded = any("seed" in r for r in fo["scenes"])
    lines += ["", "| scene | " + ("seed | " if seeded else "") + "pedestrians | success | off path | fall | timeout | "
              "map contact | agent contact |", "|---" * (9 if seeded else 8) + "|"]
    for r in fo["scenes"]:
        lines.append(f"| {r['scene']} | " + (f"{r['seed']} | " if seeded else "") + f"{r['pedestrians']} | "
                     f"{r['success']} | {r['off_path']} | {r['fall']} | {r['timeout']} | {r['map_trips']} | "
                     f"{r['agent_trips']} |")
    keys = ("coverage_k50", "entropy_k50", "dist_k50", "coverage_k100", "entropy_k100", "dist_k100", "mmd",
            "n_generated")
    lines += ["", "| realism | " + " | ".join(keys) + " |", "|---" * (len(keys) + 1) + "|"]
    for model in ("amp", "kinematic"):
        lines.append(f"| {model} | " + " | ".join(f(result["realism"][model][k]) for k in keys) + " |")
    lines.append(f"| reference split-half MMD floor | | | | | | | {f(result['realism']['reference_mmd_floor'])} | |")
    if "throughput" in result:
        lines += ["", "| pedestrians | env steps/s | agent steps/s | x real time |", "|---|---|---|---|"]
        for r in result["throughput"]:
            lines.append(f"| {r['pedestrians']} | {r['env_steps_per_s']:.1f} | {r['agent_steps_per_s']:.1f} | "
                         f"{r['realtime_factor']:.2f} |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="navzoo eval pedestrians", description=__doc__.splitlines()[0])
    add_arguments(parser)
    return run_cli(parser.parse_args(argv))


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true", help="reduced run (2 scenes x 20 s, clips capped at 4 s)")
    parser.add_argument("--motions", default=None, help="folder of reference clips (default: packaged locomotion)")
    parser.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    parser.add_argument("--seed", type=int, default=None, help="seed of the scenes (default 0)")
    parser.add_argument("--seeds", default=None, metavar="S1,S2,...",
                        help="run the following protocol once per seed (e.g. 0,1,2,3) and report the rates pooled "
                             "over the seeds, each seed's rates and their spread; realism uses the first seed")
    parser.add_argument("--scenes", default=None,
                        help="scenes of the following runs, comma-separated (default the protocol's 8; quick: "
                             "lobby,corridor); 'heldout': the 10 library scenes no setting was chosen on")
    parser.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE",
                        help="NavConfig field for the following runs, repeatable (e.g. --set amp_wall_strength=0.3; "
                             "values read as JSON, else words); the realism crowd, throughput and video keep the defaults")
    parser.add_argument("--video", default=None, help="also write an mp4 of an AMP crowd here")
    parser.add_argument("--no-throughput", action="store_true")
    parser.add_argument("--workers", type=int, default=1, help="processes for the scenes of the following run")
    parser.add_argument("--out", default=None,
                        help="also write the JSON result to this file; an interrupted run rerun with the same "
                             "--out and settings resumes its following runs (kept in OUT.following.jsonl until done)")
    parser.add_argument("--json", action="store_true", help="print JSON")
    parser.add_argument("--markdown", default=None, metavar="RESULT_JSON",
                        help="print Markdown tables of an earlier result (--out file) and exit")


def env_set_option(command: str, items: list[str]) -> dict[str, Any]:
    """``--set KEY=VALUE`` items as NavConfig overrides, parsed as every ``--set`` is
    (:func:`navzoo.envs.config.parse_override`: values read as JSON, else kept as words: ``0.3``, ``true``, ``orca``,
    ``off``) and checked by :func:`check_env_overrides`; an item without ``=``, a key given twice, an unknown field,
    a field the protocol sets or a refused value is a ValueError naming it, after ``command``."""
    from navzoo.envs.config import parse_override

    out: dict[str, Any] = {}
    try:
        for item in items:
            key, value = parse_override(item)
            if key in out:
                raise ValueError(f"{key} given twice")
            out[key] = value
        return check_env_overrides(out)
    except ValueError as exc:
        raise ValueError(f"{command}: --set: {exc}") from None


def run_cli(args: argparse.Namespace) -> int:
    if args.markdown:
        print(markdown(json.loads(Path(args.markdown).read_text())))
        return 0
    seeds = seeds_option("navzoo eval pedestrians", args.seed, args.seeds)
    overrides = env_set_option("navzoo eval pedestrians", args.env_set)
    result = evaluate(args.quick, args.motions, args.policy, 0 if args.seed is None else args.seed, args.video,
                      not args.no_throughput, args.workers, seeds=seeds, out_file=args.out, scenes=args.scenes,
                      env_overrides=overrides)
    print(json.dumps(result, indent=None if args.json else 2, default=float))  # evaluate wrote --out
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
