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

The robots are frozen: a baseline, or a learned robot policy registered as a benchmark method (e.g.
``transformer-ppo-crowdnav-diffdrive``). Robots and AMP pedestrians learning at the same time is not
supported yet.

An env copy restarts as a whole when one of its pedestrians falls or its episode ends (time limit,
or every robot done). The pedestrians that fell are *terminated*; the others are *truncated* and
bootstrapped from their last observation.

``python -m navzoo.rl.amp_joint train --out runs/amp_joint ...`` trains (resumable, Ctrl-C safe, starting
from the shipped training checkpoint by default); ``... evaluate --policy DIR`` measures falls,
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
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["AmpJointArgs", "NavAmpVecEnv", "evaluate", "main", "shipped_training_checkpoint", "train"]

REPO_ROOT = Path(__file__).resolve().parents[2]
SHIPPED_STATE = REPO_ROOT / "training" / "amp"  # the committed training checkpoint of the shipped policy


def _pose(state: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """A copy of the pose fields of a ``read_state()`` dict: what the next frame's finite-difference
    velocities (:func:`navzoo.agents.amp.features.finite_difference_velocities`) start from."""
    return {key: np.array(state[key], copy=True) for key in ("root_pos", "root_quat", "sph", "rev")}


class NavAmpVecEnv:
    """The pedestrians of ``n_envs`` navzoo worlds as one :class:`~navzoo.agents.amp.learner.AmpVecEnv`.

    Args:
        env_id: a registered scenario id (``navzoo.envs.registry.SCENARIOS``).
        n_envs: env copies, stepped in this process.
        n_humans: pedestrians per copy (each is one row of the batch).
        n_robots: robots per copy (0: pedestrians only).
        robot_policy: the frozen robots' policy: a benchmark method name (``navzoo.agents.baselines``).
        seed: copy ``k``'s episodes are seeded from ``seed`` and ``k``.
        env_overrides: further NavConfig fields (``crowd_model``, ``time_limit``, ...).
        reference: the style reference (default: the controller's training reference).
        amp_window: frames per discriminator input (the shipped controller's: 2).
    """

    def __init__(self, env_id: str, n_envs: int, n_humans: int, n_robots: int = 1, robot_policy: str = "orca",
                 seed: int = 0, env_overrides: dict[str, Any] | None = None, reference: Any = None,
                 amp_window: int = 2) -> None:
        import navzoo
        from navzoo.agents import baselines
        from navzoo.agents.amp.features import FEATURE_DIM
        from navzoo.agents.amp.path_env import PathTaskConfig, amp_obs_version
        from navzoo.agents.amp.sim import ACTION_DIM
        from navzoo.agents.amp.train import grounded_locomotion_reference
        from navzoo.envs.config import AMP_CONTROL_HZ

        for name, v, lo in (("n_envs", n_envs, 1), ("n_humans", n_humans, 1), ("n_robots", n_robots, 0),
                            ("amp_window", amp_window, 1)):
            if isinstance(v, bool) or not isinstance(v, int | np.integer) or v < lo:
                raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
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
        self.amp_obs_version = amp_obs_version(PathTaskConfig(amp_velocity="finite_difference"), self.reference)
        self.robot_policy_name = robot_policy
        self.robot_policies = [baselines.make_policy(robot_policy) for _ in self.envs] if self.n_robots else []
        self.seed = int(seed)
        self._episodes = np.zeros(self.n_copies, dtype=np.int64)
        self._robot_obs: list[dict[str, Any]] = [{} for _ in self.envs]
        self._prev: list[dict[str, np.ndarray]] = [{} for _ in self.envs]
        self._window = np.zeros((self.num_envs, self.window, FEATURE_DIM), dtype=np.float32)
        self._obs = np.zeros((self.num_envs, self.obs_dim), dtype=np.float32)
        self.reset_stats()

    # ------------------------------------------------------------------ statistics
    def reset_stats(self) -> None:
        """Zero the counters of :meth:`stats`."""
        self._stats = {"pedestrian_steps": 0, "falls": 0, "agent_contact_steps": 0, "robot_contact_steps": 0,
                       "map_contact_steps": 0, "path_error_sum": 0.0, "robot_episodes": 0, "robot_goals": 0,
                       "robot_collisions": 0}

    def stats(self) -> dict[str, float]:
        """Rates since :meth:`reset_stats`: falls per pedestrian-minute, contact shares of pedestrian steps
        (with anything / with a robot / with the map), mean path error, robot goal and collision rates."""
        s = self._stats
        n = max(1, s["pedestrian_steps"])
        minutes = s["pedestrian_steps"] * self.dt / 60.0
        out = {
            "pedestrian_steps": s["pedestrian_steps"],
            "falls": s["falls"],
            "falls_per_pedestrian_minute": s["falls"] / minutes if minutes > 0 else float("nan"),
            "agent_contact_share": s["agent_contact_steps"] / n,
            "robot_contact_share": s["robot_contact_steps"] / n,
            "map_contact_share": s["map_contact_steps"] / n,
            "path_error_m": s["path_error_sum"] / n,
            "robot_episodes": s["robot_episodes"],
        }
        if s["robot_episodes"]:
            out["robot_success_rate"] = s["robot_goals"] / s["robot_episodes"]
            out["robot_collision_rate"] = s["robot_collisions"] / s["robot_episodes"]
        return out

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
        self._prev[k] = _pose(state)
        # The first frame has no predecessor: standing bodies, zero velocities (as the path env's standing starts).
        self._window[self._rows(k)] = amp_features(state)[:, None, :]

    def reset(self, seed: int | None = None) -> np.ndarray:
        if seed is not None:
            self.seed = int(seed)
            self._episodes[:] = 0
        for k in range(self.n_copies):
            self._reset_copy(k)
        return self._obs.copy()

    # ------------------------------------------------------------------ step
    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        from navzoo.agents.amp.features import amp_features, finite_difference_velocities

        a = np.asarray(actions, dtype=np.float32)
        if a.shape != (self.num_envs, self.act_dim) or not np.isfinite(a).all():
            raise ValueError(f"actions must be finite with shape {(self.num_envs, self.act_dim)}, got {a.shape}")
        E = self.num_envs
        reward = np.zeros(E, dtype=np.float32)
        terminated = np.zeros(E, dtype=bool)
        truncated = np.zeros(E, dtype=bool)
        amp_obs = np.zeros((E, self.amp_obs_dim), dtype=np.float32)
        final_obs = self._obs.copy()
        s = self._stats
        for k, env in enumerate(self.envs):
            rows = self._rows(k)
            acts: dict[str, np.ndarray] = {h: a[rows][j] for j, h in enumerate(self.humans)}
            if self.n_robots:
                live = {r: o for r, o in self._robot_obs[k].items() if r in env.agents}
                if live:
                    acts.update(self.robot_policies[k].act(live, env))
            obs, rew, term, trunc, info = env.step(acts)
            state = env.amp.state()
            feats = amp_features(finite_difference_velocities(self._prev[k], state, self.dt))
            self._prev[k] = _pose(state)
            win = np.roll(self._window[rows], -1, axis=1)
            win[:, -1] = feats
            self._window[rows] = win
            amp_obs[rows] = win.reshape(self.n_humans, -1)
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
            if restart:
                terminated[rows] = h_term
                truncated[rows] = ~h_term
                final_obs[rows] = new_obs
                self._reset_copy(k)
            else:
                self._obs[rows] = new_obs
        info_out: dict[str, Any] = {"amp_obs": amp_obs}
        if (terminated | truncated).any():
            info_out["final_obs"] = final_obs
        return self._obs.copy(), reward, terminated, truncated, info_out

    def sample_reference_amp_obs(self, n: int, rng: np.random.Generator) -> np.ndarray:
        from navzoo.agents.amp.path_env import reference_amp_windows

        return reference_amp_windows(self.reference, n, rng, self.window, self.dt, "finite_difference")

    def close(self) -> None:
        for env in self.envs:
            env.close()


# ---------------------------------------------------------------------- the shipped starting point
def shipped_training_checkpoint(dst: str | Path) -> Path:
    """Assemble the committed training checkpoint of the shipped AMP policy (``training/amp``: its
    ``state.pt`` split in parts, ``meta.json``) into ``dst/<name>/``; returns that checkpoint folder."""
    from navzoo.agents.amp import checkpoint as ckpt

    parts = sorted(SHIPPED_STATE.glob("state.pt.part-*"))
    if not parts or not (SHIPPED_STATE / "meta.json").is_file():
        raise FileNotFoundError(f"{SHIPPED_STATE} holds no training checkpoint (state.pt.part-* and meta.json)")
    name = (SHIPPED_STATE / "name").read_text().strip()
    out = Path(dst) / name
    out.mkdir(parents=True, exist_ok=True)
    with open(out / ckpt.STATE_FILE, "wb") as f:
        for part in parts:
            f.write(part.read_bytes())
    shutil.copy(SHIPPED_STATE / "meta.json", out / ckpt.META_FILE)
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
    init: str = "shipped"  # "shipped" (the committed training checkpoint) or a checkpoint folder
    time_limit_s: float | None = None
    ckpt_every: int = 10
    env: dict[str, Any] = field(default_factory=dict)


def _learner_config(args: AmpJointArgs, saved: dict[str, Any]):
    from navzoo.agents.amp.learner import AmpConfig

    keep = {k: v for k, v in saved.items() if k in {f.name for f in dataclasses.fields(AmpConfig)}}
    keep.update(seed=args.seed, rollout_steps=args.rollout_steps, epochs=args.epochs,
                minibatch_size=args.minibatch_size, actor_lr=args.actor_lr, disc_lr=args.disc_lr,
                ckpt_replay_rows=min(int(keep.get("ckpt_replay_rows", 8000)), 8000))
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
    fixed = ("env_id", "n_envs", "n_humans", "n_robots", "robot_policy", "init", "env")
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
        env = NavAmpVecEnv(args.env_id, args.n_envs, args.n_humans, args.n_robots, args.robot_policy, args.seed,
                           args.env)
        try:
            learner = AmpLearner(env, _learner_config(args, meta.get("config") or {}), device=args.device)
            resumed = ckpt.latest_checkpoint(out / "checkpoints") is not None
            if not resumed:
                learner.load_checkpoint(start, any_num_envs=True)
            start_step = int(meta["counters"]["global_step"])
            t0 = time.time()
            result = learner.train(start_step + args.steps, log_dir=out, ckpt_dir=out / "checkpoints",
                                   ckpt_every=args.ckpt_every, verbose=True, time_limit_s=args.time_limit_s)
            learner.export_policy(out / "policy")
            stats = env.stats()
        finally:
            env.close()
    summary = {**{k: v for k, v in result.items() if isinstance(v, int | float | str | bool | type(None))},
               "out": str(out), "policy": str(out / "policy"), "start": str(args.init),
               "start_global_step": start_step, "pedestrian_steps_this_run": stats["pedestrian_steps"],
               "train_stats": stats, "wall_s": round(time.time() - t0, 1)}
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
def _env_kv(items: Sequence[str]) -> dict[str, Any]:
    out: dict[str, Any] = {}
    for it in items:
        if "=" not in it:
            raise ValueError(f"--set takes KEY=VALUE, got {it!r}")
        k, v = it.split("=", 1)
        try:
            out[k] = json.loads(v)
        except json.JSONDecodeError:
            out[k] = v
    return out


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(prog="python -m navzoo.rl.amp_joint", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="cmd", required=True)
    tr = sub.add_parser("train", help="train AMP pedestrians among frozen robots (resumable)")
    ev = sub.add_parser("evaluate", help="falls, contacts, path error and robot outcomes of an AMP policy")
    for p in (tr, ev):
        p.add_argument("--env", dest="env_id", default=AmpJointArgs.env_id)
        p.add_argument("--n-envs", type=int, default=AmpJointArgs.n_envs)
        p.add_argument("--n-humans", type=int, default=AmpJointArgs.n_humans)
        p.add_argument("--n-robots", type=int, default=AmpJointArgs.n_robots)
        p.add_argument("--robot-policy", default=AmpJointArgs.robot_policy)
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
    ev.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    ev.add_argument("--steps", type=int, default=900, help="control steps (30 Hz) of every copy")
    ev.add_argument("--json", action="store_true")
    a = parser.parse_args(argv)
    try:
        env = _env_kv(a.set)
        if a.cmd == "train":
            args = AmpJointArgs(out=a.out, env_id=a.env_id, n_envs=a.n_envs, n_humans=a.n_humans, n_robots=a.n_robots,
                                robot_policy=a.robot_policy, steps=a.steps, rollout_steps=a.rollout_steps,
                                epochs=a.epochs, minibatch_size=a.minibatch_size, actor_lr=a.actor_lr,
                                disc_lr=a.disc_lr, device=a.device, seed=a.seed or 0, init=a.init,
                                time_limit_s=a.time_limit_s, ckpt_every=a.ckpt_every, env=env)
            print(json.dumps(train(args), default=str))
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
