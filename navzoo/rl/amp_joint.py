"""Physics pedestrians that keep learning among robots: the AMP learner on the pedestrians of navzoo worlds.

The AMP controller (issue 3) was trained alone, each humanoid on its own patch. Here its learner
(:class:`navzoo.agents.amp.learner.AmpLearner`: PPO + discriminator, replay buffer, checkpoints) trains
the pedestrians of real navzoo scenes (``human_model="amp"``) while robots drive among them. Every
pedestrian of every env copy is one row of the learner's batch, and its reward is the paper's
``r = r_style + 0.5 r_task``:

- ``r_task`` is the env's pedestrian reward (track + energy + direction), the same terms the
  controller was trained with;
- ``r_style`` comes from the discriminator, which keeps training on the pedestrians' own state
  transitions against the reference motions. The style reward is never switched off during joint
  training.

The robots are frozen -- a baseline, a learned robot policy registered as a benchmark method (e.g.
``transformer-ppo-crowdnav-diffdrive``) or an exported one (``sb3:DIR``) -- or they learn at the same
time (``robot_learn``): SB3 PPO with the transformer actor-critic, fed one robot decision every
``action_repeat`` env steps from inside the AMP learner's loop (:class:`navzoo.rl.stepped_ppo.SteppedPPO`),
on the env's robot reward. Both learners checkpoint together (the robots' state rides in the AMP
checkpoint) and resume together.

An env copy restarts as a whole when one of its pedestrians falls or its episode ends (time limit,
or every robot done). The pedestrians that fell are *terminated*; the others are *truncated* and
bootstrapped from their last observation.

``python -m navzoo.rl.amp_joint train --out runs/amp_joint ...`` trains (resumable, Ctrl-C safe, starting
by default from the shipped policy inside the committed training checkpoint, :func:`shipped_training_checkpoint`); ``... evaluate --policy DIR`` measures falls,
contacts, path error and the robots' outcomes of an exported policy, or of the shipped one, with
robots present. ``navzoo train joint --humans learn --set human_model=amp`` dispatches here.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import shutil
import sys
import tempfile
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.agents.amp.vec import SubprocVecEnv

__all__ = ["AmpJointArgs", "NavAmpVecEnv", "SubprocNavAmpVecEnv", "evaluate", "main", "shipped_training_checkpoint",
           "stats_from_counters", "train"]

REPO_ROOT = Path(__file__).resolve().parents[2]
SHIPPED_STATE = REPO_ROOT / "training" / "amp"  # the committed training checkpoint of the shipped policy
AMP_WINDOW = 2  # frames per discriminator input of the shipped controller


def stats_from_counters(counters: Sequence[dict[str, Any]], dt: float) -> dict[str, float]:
    """:meth:`NavAmpVecEnv.stats` of the summed ``counters`` of one or more envs (e.g. of every worker)."""
    s = {k: sum(c[k] for c in counters) for k in counters[0]}
    n = max(1, s["pedestrian_steps"])
    minutes = s["pedestrian_steps"] * dt / 60.0
    out = {
        "pedestrian_steps": s["pedestrian_steps"],
        "falls": s["falls"],
        "falls_per_pedestrian_minute": s["falls"] / minutes if minutes > 0 else float("nan"),
        "agent_contact_share": s["agent_contact_steps"] / n,
        "robot_contact_share": s["robot_contact_steps"] / n,
        "map_contact_share": s["map_contact_steps"] / n,
        "path_error_m": s["path_error_sum"] / n,
        "stance_split_m": s["stance_sum"] / n,
        "robot_episodes": s["robot_episodes"],
    }
    if s["robot_episodes"]:
        out["robot_success_rate"] = s["robot_goals"] / s["robot_episodes"]
        out["robot_collision_rate"] = s["robot_collisions"] / s["robot_episodes"]
    return out


class NavAmpVecEnv:
    """The pedestrians of ``n_envs`` navzoo worlds as one :class:`~navzoo.agents.amp.learner.AmpVecEnv`.

    Args:
        env_id: a registered scenario id (``navzoo.envs.registry.SCENARIOS``).
        n_envs: env copies, stepped in this process.
        n_humans: pedestrians per copy (each is one row of the batch).
        n_robots: robots per copy (0: pedestrians only).
        robot_policy: the frozen robots' policy: a benchmark method name (``navzoo.agents.baselines``) or
            ``sb3:DIR`` (an exported robot policy folder).
        seed: copy ``k``'s episodes are seeded from ``seed`` and ``k``.
        env_overrides: further NavConfig fields (``crowd_model``, ``time_limit``, ...).
        reference: the style reference (default: the controller's training reference).
        amp_window: frames per discriminator input (the shipped controller's: 2).
        amp_velocity_span: control steps that the discriminator's finite-difference velocities span
            (:class:`navzoo.agents.amp.features.PoseHistory`; the shipped controller's: 1).
        robot_learn: robots learn with this :class:`~navzoo.rl.stepped_ppo.RobotLearnConfig` (then
            ``robot_policy`` is not used); None: they are frozen on ``robot_policy``.
        log_dir: the learning robots' TensorBoard and ``robot_metrics.jsonl``.

    With learning robots, all robots decide together every ``robot_learn.action_repeat`` env steps (one
    row per robot of every copy). A copy that restarts between two decisions ends its robots' rows there
    (truncated, bootstrapped from their last observation); its new robots stand still until the next
    decision, at most ``action_repeat - 1`` steps. A robot that finished while others of its copy go on
    is a zero padding row (zero reward, ended at every decision) until the copy restarts.
    """

    def __init__(self, env_id: str, n_envs: int, n_humans: int, n_robots: int = 1, robot_policy: str = "orca",
                 seed: int = 0, env_overrides: dict[str, Any] | None = None, reference: Any = None,
                 amp_window: int = AMP_WINDOW, robot_learn: Any = None, log_dir: str | Path | None = None,
                 amp_velocity_span: int = 1) -> None:
        import navzoo
        from navzoo.agents.amp.features import FEATURE_DIM, PoseHistory
        from navzoo.agents.amp.path_env import amp_obs_version
        from navzoo.agents.amp.sim import ACTION_DIM
        from navzoo.agents.amp.train import grounded_locomotion_reference
        from navzoo.envs.config import AMP_CONTROL_HZ

        for name, v, lo in (("n_envs", n_envs, 1), ("n_humans", n_humans, 1), ("n_robots", n_robots, 0),
                            ("amp_window", amp_window, 1)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
        task = _task(amp_velocity_span)  # checks the span
        overrides = dict(env_overrides or {})
        for key in ("human_model", "n_humans", "n_robots", "dt"):
            if key in overrides:
                raise ValueError(f"env_overrides may not set {key!r}: NavAmpVecEnv fixes it")
        self.dt = 1.0 / AMP_CONTROL_HZ
        self.envs = [navzoo.make(env_id, raw=True, human_model="amp", n_humans=int(n_humans), n_robots=int(n_robots),
                                 dt=self.dt, flat_obs=True, **overrides) for _ in range(int(n_envs))]
        self.n_copies, self.n_humans, self.n_robots = int(n_envs), int(n_humans), int(n_robots)
        self.num_envs = self.n_copies * self.n_humans
        env0 = self.envs[0]
        self.humans = list(env0.possible_agents[self.n_robots:])
        self.obs_dim = int(env0.observation_space(self.humans[0]).shape[0])
        self.act_dim = int(ACTION_DIM)
        self.window = int(amp_window)
        self.amp_obs_dim = self.window * int(FEATURE_DIM)
        self.reference = reference if reference is not None else grounded_locomotion_reference()
        self.span = int(task.amp_velocity_span)
        self.amp_obs_version = amp_obs_version(task, self.reference)
        self.robots = list(env0.possible_agents[:self.n_robots])
        self.robot_learner = None
        if robot_learn is not None:
            from navzoo.rl.stepped_ppo import SteppedPPO

            if not self.n_robots:
                raise ValueError("learning robots need n_robots >= 1")
            self.robot_policy_name = "learn"
            self.robot_policies = []
            self.robot_learner = SteppedPPO(env0.observation_space(self.robots[0]), env0.action_space(self.robots[0]),
                                            self.n_copies * self.n_robots, robot_learn, seed=int(seed),
                                            log_dir=log_dir, env_overrides=overrides)
            R = self.n_copies * self.n_robots
            self._repeat = int(robot_learn.action_repeat)
            self._tick = 0
            self._r_open = False
            self._r_act = np.zeros((R, int(env0.action_space(self.robots[0]).shape[0])), dtype=np.float32)
            self._r_acc = np.zeros(R, dtype=np.float32)
            self._r_done = np.zeros(R, dtype=bool)
            self._r_pad = np.zeros(R, dtype=bool)
            self._r_stale = np.zeros(R, dtype=bool)
            self._r_final: dict[int, np.ndarray] = {}
            self._r_events: dict[int, str] = {}
        else:
            self.robot_policy_name = robot_policy
            self.robot_policies = [_robot_policy(robot_policy) for _ in self.envs] if self.n_robots else []
        self.seed = int(seed)
        self._episodes = np.zeros(self.n_copies, dtype=np.int64)
        self._robot_obs: list[dict[str, Any]] = [{} for _ in self.envs]
        self._history = [PoseHistory(self.n_humans, self.span) for _ in self.envs]
        self._window = np.zeros((self.num_envs, self.window, FEATURE_DIM), dtype=np.float32)
        self._obs = np.zeros((self.num_envs, self.obs_dim), dtype=np.float32)
        self.reset_stats()

    # ------------------------------------------------------------------ statistics
    def reset_stats(self) -> None:
        """Zero the counters of :meth:`stats`."""
        self._stats = {"pedestrian_steps": 0, "falls": 0, "agent_contact_steps": 0, "robot_contact_steps": 0,
                       "map_contact_steps": 0, "path_error_sum": 0.0, "stance_sum": 0.0, "robot_episodes": 0, "robot_goals": 0,
                       "robot_collisions": 0}

    def counters(self) -> dict[str, Any]:
        """The raw counts behind :meth:`stats` (they add up over envs: :func:`stats_from_counters`)."""
        return dict(self._stats)

    def stats(self) -> dict[str, float]:
        """Rates since :meth:`reset_stats`: falls per pedestrian-minute, contact shares of pedestrian steps
        (with anything / with a robot / with the map), mean path error, robot goal and collision rates."""
        return stats_from_counters([self._stats], self.dt)

    # ------------------------------------------------------------------ reset
    def _rows(self, k: int) -> slice:
        return slice(k * self.n_humans, (k + 1) * self.n_humans)

    def _reset_copy(self, k: int) -> None:
        from navzoo.agents.amp.features import amp_features

        env = self.envs[k]
        seed = self.seed + 7919 * k + 104_729 * int(self._episodes[k])
        self._episodes[k] += 1
        obs, _ = env.reset(seed=seed)
        for p in self.robot_policies[k:k + 1]:
            p.reset(env)
        self._robot_obs[k] = {a: o for a, o in obs.items() if a.startswith("robot_")}
        self._obs[self._rows(k)] = np.stack([np.asarray(obs[a], np.float32) for a in self.humans])
        state = env.amp.state()
        self._history[k].reset(state)
        # The first frame has no predecessor: standing bodies, zero velocities (as the path env's standing starts).
        self._window[self._rows(k)] = amp_features(state)[:, None, :]

    def reset(self, seed: int | None = None) -> np.ndarray:
        if self.robot_learner is not None:
            if self._r_open:  # every robot episode is cut here: close the open decision
                self.robot_learner.observe(self._r_acc, np.ones_like(self._r_done), padding=self._r_pad)
                self._r_open = False
            self._tick = 0
        if seed is not None:
            self.seed = int(seed)
            self._episodes[:] = 0
        for k in range(self.n_copies):
            self._reset_copy(k)
        return self._obs.copy()

    # ------------------------------------------------------------------ step
    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        from navzoo.agents.amp.features import amp_features

        a = np.asarray(actions, dtype=np.float32)
        if a.shape != (self.num_envs, self.act_dim) or not np.isfinite(a).all():
            raise ValueError(f"actions must be finite with shape {(self.num_envs, self.act_dim)}, got {a.shape}")
        E = self.num_envs
        reward = np.zeros(E, dtype=np.float32)
        terminated = np.zeros(E, dtype=bool)
        truncated = np.zeros(E, dtype=bool)
        amp_obs = np.zeros((E, self.amp_obs_dim), dtype=np.float32)
        split = np.zeros(E)  # |running mean of the feet's fore-aft split| (m) after the step, for the training log
        final_obs = self._obs.copy()
        s = self._stats
        learn = self.robot_learner is not None
        if learn and self._tick == 0:
            self._robot_decide()
        for k, env in enumerate(self.envs):
            rows = self._rows(k)
            acts: dict[str, np.ndarray] = {h: a[rows][j] for j, h in enumerate(self.humans)}
            if learn:
                for i, r in enumerate(self.robots):
                    row = k * self.n_robots + i
                    if r in env.agents:
                        acts[r] = np.zeros_like(self._r_act[row]) if self._r_stale[row] else self._r_act[row]
            elif self.n_robots:
                live = {r: o for r, o in self._robot_obs[k].items() if r in env.agents}
                if live:
                    acts.update(self.robot_policies[k].act(live, env))
            obs, rew, term, trunc, info = env.step(acts)
            state = env.amp.state()
            feats = amp_features(self._history[k].velocities(state, self.dt))
            win = np.roll(self._window[rows], -1, axis=1)
            win[:, -1] = feats
            self._window[rows] = win
            amp_obs[rows] = win.reshape(self.n_humans, -1)
            split[rows] = np.abs(env.amp.stance)
            s["stance_sum"] += float(split[rows].sum())
            h_term = np.array([bool(term.get(h, False)) for h in self.humans])
            h_trunc = np.array([bool(trunc.get(h, False)) for h in self.humans])
            reward[rows] = [float(rew.get(h, 0.0)) for h in self.humans]
            new_obs = np.stack([np.asarray(obs[h], np.float32) if h in obs else self._obs[rows][j]
                                for j, h in enumerate(self.humans)])
            self._robot_obs[k] = {r: o for r, o in obs.items() if r.startswith("robot_")}
            # statistics
            s["pedestrian_steps"] += self.n_humans
            for h in self.humans:
                inf = info.get(h, {})
                s["falls"] += int(bool(term.get(h, False)) and bool(inf.get("fallen", False)))
                s["agent_contact_steps"] += int(bool(inf.get("agent_contact", False)))
                s["map_contact_steps"] += int(bool(inf.get("map_contact", False)))
                s["robot_contact_steps"] += int(bool(inf.get("robot_contact", False)))
                s["path_error_sum"] += float(inf.get("path_error", 0.0))
            for r in env.possible_agents[:self.n_robots]:
                if term.get(r, False) or trunc.get(r, False):
                    s["robot_episodes"] += 1
                    ev = info[r].get("event", "")
                    s["robot_goals"] += int(ev == "goal")
                    s["robot_collisions"] += int(str(ev).startswith("collision"))
            restart = h_term.any() or h_trunc.any() or not any(h in env.agents for h in self.humans)
            if learn:
                self._robot_outcomes(k, obs, rew, term, trunc, info, restart)
            if restart:
                terminated[rows] = h_term
                truncated[rows] = ~h_term
                final_obs[rows] = new_obs
                self._reset_copy(k)
            else:
                self._obs[rows] = new_obs
        if learn:
            self._tick = (self._tick + 1) % self._repeat
        info_out: dict[str, Any] = {"amp_obs": amp_obs, "log/stance_split_m": split}
        if (terminated | truncated).any():
            info_out["final_obs"] = final_obs
        return self._obs.copy(), reward, terminated, truncated, info_out

    # ------------------------------------------------------------------ learning robots
    def _robot_decide(self) -> None:
        """Close the last decision (rewards, ends) and sample the next one for every robot row."""
        L = self.robot_learner
        if self._r_open:
            L.observe(self._r_acc, self._r_done | self._r_pad, final_obs=self._r_final, events=self._r_events,
                      padding=self._r_pad)
        obs = np.zeros((self.n_copies * self.n_robots, *L.model.observation_space.shape), dtype=np.float32)
        pad = np.zeros(len(obs), dtype=bool)
        for k, env in enumerate(self.envs):
            for i, r in enumerate(self.robots):
                row = k * self.n_robots + i
                if r in env.agents and r in self._robot_obs[k]:
                    obs[row] = self._robot_obs[k][r]
                else:
                    pad[row] = True
        self._r_act = L.act(obs).astype(np.float32)
        self._r_acc[:] = 0.0
        self._r_done[:] = False
        self._r_stale[:] = False
        self._r_pad = pad
        self._r_final, self._r_events = {}, {}
        self._r_open = True

    def _robot_outcomes(self, k: int, obs: dict[str, Any], rew: dict[str, float], term: dict[str, bool],
                        trunc: dict[str, bool], info: dict[str, Any], restart: bool) -> None:
        """Add copy ``k``'s robot rewards of this step to the open decision; end rows whose robot finished
        or whose copy restarts (truncated: bootstrapped from the last observation)."""
        for i, r in enumerate(self.robots):
            row = k * self.n_robots + i
            if self._r_stale[row] or self._r_pad[row] or self._r_done[row]:
                continue
            self._r_acc[row] += float(rew.get(r, 0.0))
            ended = bool(term.get(r, False)) or bool(trunc.get(r, False))
            if ended or restart:
                self._r_done[row] = True
                self._r_events[row] = str(info.get(r, {}).get("event", "truncated")) if ended else "truncated"
                if not term.get(r, False) and r in obs:
                    self._r_final[row] = np.asarray(obs[r], np.float32)
        if restart:
            self._r_stale[k * self.n_robots:(k + 1) * self.n_robots] = True

    def companion_state(self) -> dict[str, Any] | None:
        """The learning robots' state, saved inside the AMP learner's checkpoint (None: frozen robots)."""
        return None if self.robot_learner is None else {"robot_learner": self.robot_learner.state_dict()}

    def load_companion_state(self, state: dict[str, Any] | None) -> None:
        """Restore :meth:`companion_state` from an AMP checkpoint; ``ValueError`` if it does not fit."""
        if self.robot_learner is None:
            return
        if not state or "robot_learner" not in state:
            raise ValueError("it holds no learning robots' state (made by a run whose robots were frozen)")
        self.robot_learner.load_state_dict(state["robot_learner"])
        self._r_open = False
        self._tick = 0

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray:
        return _reference_windows(self.reference, self.window, self.dt, n, rng, self.span)

    def close(self) -> None:
        for env in self.envs:
            env.close()


def _task(span: int) -> Any:
    """The path-task settings whose discriminator inputs the navzoo-scene trainer shares (for
    :func:`~navzoo.agents.amp.path_env.amp_obs_version`)."""
    from navzoo.agents.amp.path_env import PathTaskConfig

    return PathTaskConfig(amp_velocity="finite_difference", amp_velocity_span=span)


def _reference_windows(reference: Any, window: int, dt: float, n: int, rng: np.random.Generator,
                       span: int = 1) -> np.ndarray:
    from navzoo.agents.amp.path_env import reference_amp_windows

    return reference_amp_windows(reference, n, rng, window, dt, "finite_difference", span)


def _nav_amp_env(env_id: str, n_envs: int, n_humans: int, n_robots: int, robot_policy: str, seed: int,
                 env_overrides: dict[str, Any], span: int = 1) -> NavAmpVecEnv:
    return NavAmpVecEnv(env_id, n_envs, n_humans, n_robots, robot_policy, seed, env_overrides,
                        amp_velocity_span=span)


def _check_scenes(scenes: Sequence[str]) -> list[str]:
    from navzoo.world.library import list_scenes

    names = [str(x).strip() for x in scenes]
    known = set(list_scenes())
    unknown = [x for x in names if x not in known]
    if not names or unknown:
        raise ValueError(f"unknown scene(s) {unknown or names}; library scenes: {sorted(known)}")
    return names


class SubprocNavAmpVecEnv(SubprocVecEnv):
    """The pedestrians of navzoo scenes in ``workers`` processes, one :class:`NavAmpVecEnv` each
    (``n_envs`` copies x ``n_humans``), as one ``AmpVecEnv``: the AMP learner on the device machine's cores.

    Worker ``w`` runs scene ``scenes[w % len(scenes)]`` (None: the scene of ``env_id``) with the seed
    ``seed + 1009 w``. Robots are frozen (``robot_policy``); learning robots need one process
    (:class:`NavAmpVecEnv`). :meth:`stats` sums every worker's counters.
    """

    robot_learner = None

    def __init__(self, env_id: str, n_envs: int, n_humans: int, n_robots: int = 0, robot_policy: str = "orca",
                 seed: int = 0, env_overrides: dict[str, Any] | None = None, workers: int = 2,
                 scenes: Sequence[str] | None = None, amp_velocity_span: int = 1) -> None:
        from navzoo.agents.amp.path_env import amp_obs_version
        from navzoo.agents.amp.train import grounded_locomotion_reference
        from navzoo.envs.config import AMP_CONTROL_HZ

        if isinstance(workers, bool) or not isinstance(workers, int | np.integer) or workers < 1:
            raise ValueError(f"workers must be an integer >= 1, got {workers!r}")
        task = _task(amp_velocity_span)  # checks the span before any worker starts
        overrides = dict(env_overrides or {})
        if scenes is not None:
            if "scene" in overrides:
                raise ValueError("give the scenes either as scenes or as the 'scene' override, not both")
            scenes = _check_scenes(scenes)
        self.dt = 1.0 / AMP_CONTROL_HZ
        self.window = AMP_WINDOW  # the workers' NavAmpVecEnv default
        self.span = int(task.amp_velocity_span)
        self.scenes = [scenes[w % len(scenes)] if scenes else overrides.get("scene") for w in range(int(workers))]
        makers = [partial(_nav_amp_env, env_id, int(n_envs), int(n_humans), int(n_robots), robot_policy,
                          int(seed) + 1009 * w, {**overrides, **({"scene": sc} if sc else {})}, self.span)
                  for w, sc in enumerate(self.scenes)]
        reference = grounded_locomotion_reference()
        super().__init__(makers, partial(_reference_windows, reference, self.window, self.dt, span=self.span),
                         amp_obs_version(task, reference))

    def stats(self) -> dict[str, float]:
        return stats_from_counters(self.counters(), self.dt)


def _robot_policy(spec: str) -> Any:
    """A frozen robot policy: a benchmark method name, or ``sb3:DIR`` (an exported robot policy folder, e.g.
    the ``robot_policy/`` of a run whose robots learned)."""
    from navzoo.agents import baselines

    if isinstance(spec, str) and spec.startswith("sb3:"):
        from navzoo.agents.robot_train import load_policy

        path = Path(spec[4:])
        if not (path / "config.json").is_file():
            raise FileNotFoundError(f"robot policy {spec!r}: {path} is not an exported robot policy folder")
        return load_policy(path)
    return baselines.make_policy(spec)


# ---------------------------------------------------------------------- the shipped starting point
def shipped_training_checkpoint(dst: str | Path) -> Path:
    """Assemble the training checkpoint to continue the shipped AMP policy from, in ``dst/shipped/<name>/``
    (returned).

    The committed checkpoint (``training/amp``: ``state.pt`` split in parts, ``meta.json``) is checkpoint
    5174's. Since 2026-11-27 the shipped policy is a weight average of 5174 and two branches of it, which
    has no checkpoint of its own, so the shipped policy's actor and observation normaliser are put into
    5174's checkpoint (:func:`navzoo.agents.amp.checkpoint.checkpoint_with_policy`); the critic,
    discriminator and optimisers are 5174's."""
    from navzoo.agents.amp import checkpoint as ckpt
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    name = (SHIPPED_STATE / "name").read_text().strip()
    raw = ckpt.join_split_checkpoint(SHIPPED_STATE, Path(dst) / "committed" / name)
    out = ckpt.checkpoint_with_policy(raw, default_policy_dir(), Path(dst) / "shipped")
    shutil.rmtree(raw.parent, ignore_errors=True)
    return out


# ---------------------------------------------------------------------- training
@dataclass
class AmpJointArgs:
    out: str = "runs/amp_joint"
    env_id: str = "navzoo/Lobby-v0"
    n_envs: int = 2
    n_humans: int = 6
    n_robots: int = 1
    robot_policy: str = "orca"
    steps: int = 200_000  # pedestrian steps to train in this run's lifetime (on top of the start's)
    rollout_steps: int = 16
    epochs: int = 5
    minibatch_size: int = 192
    actor_lr: float = 2e-5
    disc_lr: float = 2e-5
    device: str = "cpu"
    seed: int = 0
    init: str = "shipped"  # "shipped" (the shipped policy in the committed checkpoint) or a checkpoint folder
    time_limit_s: float | None = None
    ckpt_every: int = 10
    env: dict[str, Any] = field(default_factory=dict)
    robot_learn: dict[str, Any] | None = None  # RobotLearnConfig fields: robots learn too; None: frozen robots
    # > 1 or scenes given: worker processes, each with n_envs copies (SubprocNavAmpVecEnv; frozen robots only)
    workers: int = 1
    scenes: list[str] | None = None  # library scene names, one per worker in turn (None: env_id's scene)
    snapshot_every: int = 0  # > 0: export the policy every that many iterations (and at the start) to out/snapshots
    keep_checkpoints: int | None = None  # None: the start checkpoint's setting
    # the discriminator's finite-difference velocities span this many control steps (features.PoseHistory;
    # the shipped controller: 1); another span than the start checkpoint's needs reset_disc
    amp_velocity_span: int = 1
    # start from args.init with a fresh discriminator (weights, optimiser, input normaliser, replay buffer); a
    # resumed run keeps its own discriminator
    reset_disc: bool = False
    # weight of the actor's trust region around the policy the run starts from (AmpConfig.anchor_coef: the mean
    # KL from the start policy on the rollout's states); the start policy is the anchor of every fresh run, and
    # its KL is logged as anchor/kl whatever the weight. 0 = off
    anchor_coef: float = 0.0


def _learner_config(args: AmpJointArgs, saved: dict[str, Any]):
    from navzoo.agents.amp.learner import AmpConfig

    keep = {k: v for k, v in saved.items() if k in {f.name for f in dataclasses.fields(AmpConfig)}}
    keep.update(seed=args.seed, rollout_steps=args.rollout_steps, epochs=args.epochs,
                minibatch_size=args.minibatch_size, actor_lr=args.actor_lr, disc_lr=args.disc_lr,
                anchor_coef=args.anchor_coef,
                ckpt_replay_rows=min(int(keep.get("ckpt_replay_rows", 8000)), 8000))
    if args.keep_checkpoints is not None:
        keep["keep_checkpoints"] = int(args.keep_checkpoints)
    for k in ("actor_hidden", "critic_hidden", "disc_hidden"):
        if k in keep:
            keep[k] = tuple(keep[k])
    return AmpConfig(**keep)


def train(args: AmpJointArgs) -> dict[str, Any]:
    """Train the pedestrians of ``args.env_id`` among frozen robots, starting from ``args.init``; resumes
    from ``args.out/checkpoints`` when it holds one. Writes ``metrics.jsonl`` (TensorBoard too),
    checkpoints and ``policy/`` (the exported controller)."""
    import torch

    from navzoo.agents.amp import checkpoint as ckpt
    from navzoo.agents.amp.learner import AmpLearner

    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    saved_args = out / "amp_joint_args.json"
    mine = dataclasses.asdict(args)
    fixed = ("env_id", "n_envs", "n_humans", "n_robots", "robot_policy", "init", "env", "workers", "scenes",
             "amp_velocity_span")
    robot_cfg = None
    if args.robot_learn is not None:
        from navzoo.rl.stepped_ppo import RobotLearnConfig

        if not isinstance(args.robot_learn, dict):
            raise ValueError(f"robot_learn must be a mapping of RobotLearnConfig fields, got {args.robot_learn!r}")
        names = {f.name for f in dataclasses.fields(RobotLearnConfig)}
        unknown = sorted(set(args.robot_learn) - names)
        if unknown:
            raise ValueError(f"unknown robot_learn key(s) {unknown}; valid keys: {sorted(names)}")
        robot_cfg = RobotLearnConfig(**args.robot_learn)
        mine["robot_policy"] = "learn"
    if robot_cfg is not None and (args.workers > 1 or args.scenes):
        raise ValueError("learning robots need one process (workers=1, no scenes list); freeze the robots "
                         "to train pedestrians over several workers or scenes")
    if args.scenes is not None:
        args.scenes = _check_scenes(args.scenes)
        mine["scenes"] = args.scenes
    if isinstance(args.workers, bool) or not isinstance(args.workers, int) or args.workers < 1:
        raise ValueError(f"workers must be an integer >= 1, got {args.workers!r}")
    if saved_args.is_file() and ckpt.latest_checkpoint(out / "checkpoints") is not None:
        old = json.loads(saved_args.read_text())
        diff = [k for k in fixed if old.get(k) != mine.get(k)]
        if diff:
            raise ValueError(f"{out} holds a run with other {diff} ({ {k: old.get(k) for k in diff} }); "
                             "use another --out")
    saved_args.write_text(json.dumps(mine, indent=2))
    torch.set_num_threads(1)
    with tempfile.TemporaryDirectory() as tmp:
        start = shipped_training_checkpoint(tmp) if args.init == "shipped" else Path(args.init)
        _, meta = ckpt.load_checkpoint(start)
        env: Any
        if args.workers > 1 or args.scenes:
            env = SubprocNavAmpVecEnv(args.env_id, args.n_envs, args.n_humans, args.n_robots, args.robot_policy,
                                      args.seed, args.env, workers=args.workers, scenes=args.scenes,
                                      amp_velocity_span=args.amp_velocity_span)
        else:
            env = NavAmpVecEnv(args.env_id, args.n_envs, args.n_humans, args.n_robots, args.robot_policy, args.seed,
                               args.env, robot_learn=robot_cfg, log_dir=out, amp_velocity_span=args.amp_velocity_span)
        try:
            learner = AmpLearner(env, _learner_config(args, meta.get("config") or {}), device=args.device)
            resumed = ckpt.latest_checkpoint(out / "checkpoints") is not None
            if not resumed:
                learner.load_checkpoint(start, any_num_envs=True, reset_disc=bool(args.reset_disc))
                learner.set_anchor()  # the start policy; a resumed run loads its own from its checkpoint
            start_step = int(meta["counters"]["global_step"])
            t0 = time.time()
            result = learner.train(start_step + args.steps, log_dir=out, ckpt_dir=out / "checkpoints",
                                   ckpt_every=args.ckpt_every, verbose=True, time_limit_s=args.time_limit_s,
                                   snapshot_dir=out / "snapshots", snapshot_every=args.snapshot_every)
            learner.export_policy(out / "policy")
            if env.robot_learner is not None:
                env.robot_learner.export(out / "robot_policy", {
                    "trained_with": "python -m navzoo.rl.amp_joint train (robots learning among learning AMP "
                                    "pedestrians)", "env_id": args.env_id, "n_humans": args.n_humans,
                    "n_robots": args.n_robots, "env_overrides": args.env})
            stats = env.stats()
        finally:
            env.close()
    summary = {**{k: v for k, v in result.items() if isinstance(v, int | float | str | bool | type(None))},
               "out": str(out), "policy": str(out / "policy"), "start": str(args.init),
               "start_global_step": start_step, "pedestrian_steps_this_run": stats["pedestrian_steps"],
               "train_stats": stats, "wall_s": round(time.time() - t0, 1)}
    if env.robot_learner is not None:
        summary |= {"robot_policy": str(out / "robot_policy"), "robot_timesteps": env.robot_learner.num_timesteps,
                    "robot_updates": env.robot_learner.updates}
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=str))
    return summary


# ---------------------------------------------------------------------- evaluation
def evaluate(policy: str | None, env_id: str, n_envs: int, n_humans: int, n_robots: int, robot_policy: str,
             steps: int, seed: int = 1000, env_overrides: dict[str, Any] | None = None) -> dict[str, Any]:
    """Run an exported AMP controller (``policy`` folder; None = the shipped one) deterministically for
    ``steps`` control steps of every copy, with frozen robots; returns :meth:`NavAmpVecEnv.stats`."""
    from navzoo.agents.amp.checkpoint import load_policy
    from navzoo.agents.amp.pedestrian_policy import default_policy_dir

    pdir = Path(policy) if policy else default_policy_dir()
    act = load_policy(pdir)
    env = NavAmpVecEnv(env_id, n_envs, n_humans, n_robots, robot_policy, seed, env_overrides)
    try:
        obs = env.reset(seed=seed)
        env.reset_stats()
        t0 = time.time()
        for _ in range(int(steps)):
            obs, *_ = env.step(np.clip(act(obs), -1.0, 1.0))
        out = {"policy": str(pdir), "env_id": env_id, "n_envs": n_envs, "n_humans": n_humans, "n_robots": n_robots,
               "robot_policy": robot_policy, "steps": int(steps), "seed": seed, **env.stats(),
               "wall_s": round(time.time() - t0, 1)}
    finally:
        env.close()
    return out


# ---------------------------------------------------------------------- command line
def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m navzoo.rl.amp_joint", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    tr = sub.add_parser("train", help="train AMP pedestrians among frozen or learning robots (resumable)")
    ev = sub.add_parser("evaluate", help="falls, contacts, path error and robot outcomes of an AMP policy")
    for p in (tr, ev):
        p.add_argument("--env", dest="env_id", default=AmpJointArgs.env_id)
        p.add_argument("--n-envs", type=int, default=AmpJointArgs.n_envs)
        p.add_argument("--n-humans", type=int, default=AmpJointArgs.n_humans)
        p.add_argument("--n-robots", type=int, default=AmpJointArgs.n_robots)
        p.add_argument("--robot-policy", default=AmpJointArgs.robot_policy,
                       help="frozen robots: a benchmark method name or sb3:DIR (an exported robot policy)")
        p.add_argument("--seed", type=int, default=None)
        p.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="NavConfig override")
    tr.add_argument("--out", default=AmpJointArgs.out)
    tr.add_argument("--steps", type=int, default=AmpJointArgs.steps, help="pedestrian steps to train")
    tr.add_argument("--rollout-steps", type=int, default=AmpJointArgs.rollout_steps)
    tr.add_argument("--epochs", type=int, default=AmpJointArgs.epochs)
    tr.add_argument("--minibatch-size", type=int, default=AmpJointArgs.minibatch_size)
    tr.add_argument("--actor-lr", type=float, default=AmpJointArgs.actor_lr)
    tr.add_argument("--disc-lr", type=float, default=AmpJointArgs.disc_lr)
    tr.add_argument("--device", default="cpu")
    tr.add_argument("--init", default="shipped", help="'shipped' or an AMP checkpoint folder to start from")
    tr.add_argument("--time-limit-s", type=float, default=None)
    tr.add_argument("--ckpt-every", type=int, default=10)
    tr.add_argument("--workers", type=int, default=1,
                    help="worker processes, each with --n-envs copies (frozen robots only)")
    tr.add_argument("--scenes", default=None, metavar="A,B,...",
                    help="library scenes, one per worker in turn (default: the scene of --env)")
    tr.add_argument("--snapshot-every", type=int, default=0,
                    help="export the policy to OUT/snapshots every N iterations and at the start (0: off)")
    tr.add_argument("--keep-checkpoints", type=int, default=None, help="training checkpoints to keep")
    tr.add_argument("--amp-velocity-span", type=int, default=1, metavar="STEPS",
                    help="control steps the discriminator's velocities span (1: the shipped controller's inputs; "
                         "another value needs --reset-disc)")
    tr.add_argument("--anchor-coef", type=float, default=AmpJointArgs.anchor_coef, metavar="W",
                    help="hold the actor near the start policy: W x the mean KL from it on the rollout's states "
                         "(AmpConfig.anchor_coef; 0 = off)")
    tr.add_argument("--reset-disc", action="store_true",
                    help="start from --init with a fresh discriminator (weights, optimiser, normaliser, replay)")
    rl = tr.add_argument_group("learning robots (--robots learn: SB3 PPO with the transformer, stepped in the same worlds)")
    rl.add_argument("--robots", choices=["frozen", "learn"], default="frozen",
                    help="frozen (on --robot-policy) or learning at the same time as the pedestrians")
    rl.add_argument("--robot-init", default=None, metavar="DIR",
                    help="exported robot policy whose weights start the robots (e.g. policies/transformer_ppo_crowdnav)")
    rl.add_argument("--robot-lr", type=float, default=1e-4)
    rl.add_argument("--robot-n-steps", type=int, default=32, help="robot decisions per row per PPO rollout")
    rl.add_argument("--robot-epochs", type=int, default=6)
    rl.add_argument("--robot-batch-size", type=int, default=None)
    rl.add_argument("--robot-action-repeat", type=int, default=3, help="30 Hz env steps per robot decision")
    rl.add_argument("--robot-forward-only", action="store_true", help="speed command in [0, 1] (diff-drive robots)")
    ev.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    ev.add_argument("--steps", type=int, default=900, help="control steps (30 Hz) of every copy")
    ev.add_argument("--json", action="store_true")
    a = parser.parse_args(argv)
    try:
        from navzoo.envs.config import parse_overrides

        env = parse_overrides(a.set)
        if a.cmd == "train":
            args = AmpJointArgs(out=a.out, env_id=a.env_id, n_envs=a.n_envs, n_humans=a.n_humans, n_robots=a.n_robots,
                                robot_policy=a.robot_policy, steps=a.steps, rollout_steps=a.rollout_steps,
                                epochs=a.epochs, minibatch_size=a.minibatch_size, actor_lr=a.actor_lr,
                                disc_lr=a.disc_lr, device=a.device, seed=a.seed or 0, init=a.init,
                                time_limit_s=a.time_limit_s, ckpt_every=a.ckpt_every, env=env,
                                workers=a.workers, scenes=a.scenes.split(",") if a.scenes else None,
                                snapshot_every=a.snapshot_every, keep_checkpoints=a.keep_checkpoints,
                                amp_velocity_span=a.amp_velocity_span, reset_disc=a.reset_disc,
                                anchor_coef=a.anchor_coef,
                                robot_learn=None if a.robots == "frozen" else {
                                    "init_from": a.robot_init, "lr": a.robot_lr, "n_steps": a.robot_n_steps,
                                    "n_epochs": a.robot_epochs, "batch_size": a.robot_batch_size,
                                    "action_repeat": a.robot_action_repeat, "forward_only": a.robot_forward_only})
            summary = train(args)
            print(json.dumps(summary, default=str))
            if summary.get("interrupted"):
                return 130  # Ctrl-C: the iteration finished and a checkpoint was saved (as navzoo train joint)
        else:
            res = evaluate(a.policy, a.env_id, a.n_envs, a.n_humans, a.n_robots, a.robot_policy, a.steps,
                           seed=1000 if a.seed is None else a.seed, env_overrides=env)
            print(json.dumps(res) if a.json else "\n".join(f"{k}: {v}" for k, v in res.items()))
    except (ValueError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
