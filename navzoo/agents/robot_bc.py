"""Imitation pretraining of the transformer robot policy (demonstrations + DAgger), before PPO.

CrowdNav's learned policies start from imitation learning on ORCA demonstrations before RL; navzoo's
paper-scene policy does the same, because PPO started from random weights (or from the CrowdNav
policy, which never saw a wall) spends its first hundreds of thousands of steps crashing into the
walls of the station, the home and the grocery store.

* ``collect``: run an expert (a privileged classical method, default ``orca``) as the robot in the
  training scenes, with the training observations (subgoals included), and store per step the
  observation, the expert's action, the reward and the episode ends, in shards
  ``<out>/<scene>_s<seed>_b<beta>.npz`` (a finished shard is never redone: the command resumes).
  With ``--learner DIR`` and ``--beta B < 1`` each step executes the expert's action with probability
  ``B`` and else the learner's, still labelled with the expert's (DAgger): states the learner itself
  reaches get the expert's answer.
* ``pretrain``: fit the actor-critic to the shards: the actor by the log-likelihood of the expert's
  actions, the critic by the discounted return of the demonstration; then export it like a trained
  policy (``policy.pt`` + ``config.json``) for ``navzoo train robot --init-from``.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np
import torch

__all__ = ["collect", "discounted_returns", "load_demos", "main", "pretrain"]

DEFAULT_OVERRIDES = {"robot_subgoal": 3.0, "robot_progress": "geodesic", "wall_proximity": 0.2}


def discounted_returns(rewards: np.ndarray, ends: np.ndarray, gamma: float) -> np.ndarray:
    """Discounted return of every step, restarting after each ``ends[t]`` (episode end, terminal or cut)."""
    out = np.zeros(len(rewards), dtype=np.float64)
    acc = 0.0
    for t in range(len(rewards) - 1, -1, -1):
        if ends[t]:
            acc = 0.0
        acc = float(rewards[t]) + gamma * acc
        out[t] = acc
    return out


def _shard_name(env_id: str, seed: int, beta: float) -> str:
    scene = env_id.split("/")[-1].split("-")[0].lower()
    return f"{scene}_s{seed}_b{beta:g}.npz"


def collect(out: str | Path, env_ids: Sequence[str], episodes: int, seed: int = 0, expert: str = "orca",
            learner: str | Path | None = None, beta: float = 1.0,
            overrides: dict[str, Any] | None = None) -> list[Path]:
    """Write one shard per scene with ``episodes`` episodes (seeds ``seed .. seed + episodes - 1``).

    Returns the shard paths (existing ones are kept as they are). Raises ``ValueError`` for a
    ``beta`` outside (0, 1], or ``beta < 1`` without a learner.
    """
    import navzoo
    from navzoo.agents.baselines import make_policy

    if not 0.0 < beta <= 1.0:
        raise ValueError(f"beta must be in (0, 1], got {beta!r}")
    if beta < 1.0 and learner is None:
        raise ValueError("beta < 1 needs a learner policy folder (--learner) whose actions are mixed in")
    if episodes < 1:
        raise ValueError(f"episodes must be >= 1, got {episodes!r}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    overrides = dict(DEFAULT_OVERRIDES if overrides is None else overrides)
    learner_pol = None
    if learner is not None:
        from navzoo.agents.robot_train import load_policy

        learner_pol = load_policy(learner, deterministic=False)
    paths = []
    for env_id in env_ids:
        path = out / _shard_name(env_id, seed, beta)
        paths.append(path)
        if path.is_file():
            print(json.dumps({"shard": str(path), "skipped": "exists"}), flush=True)
            continue
        env = navzoo.make(env_id, flat_obs=True, n_robots=1, **overrides)
        nav = env.unwrapped
        exp = make_policy(expert)
        rng = np.random.default_rng(seed)
        rows: dict[str, list] = {k: [] for k in ("obs", "action", "reward", "end", "terminal", "by_expert")}
        outcomes: list[str] = []
        t0 = time.perf_counter()
        for ep in range(episodes):
            obs, _ = env.reset(seed=seed + ep)
            exp.reset(nav)
            if learner_pol is not None:
                learner_pol.reset(nav)
            while True:
                robot_obs = {"robot_0": obs["robot_0"]}
                a_exp = np.asarray(exp.act(robot_obs, nav)["robot_0"], dtype=np.float32)
                use_expert = learner_pol is None or rng.random() < beta
                a_run = a_exp if use_expert else np.asarray(learner_pol.act(robot_obs, nav)["robot_0"], np.float32)
                a_run = np.clip(a_run, [0.0, -1.0], [1.0, 1.0]).astype(np.float32)  # forward-only robots
                acts = {"robot_0": a_run}
                rows["obs"].append(np.asarray(obs["robot_0"], dtype=np.float32))
                rows["action"].append(np.clip(a_exp, [0.0, -1.0], [1.0, 1.0]))
                rows["by_expert"].append(use_expert)
                obs, rew, term, trunc, info = env.step(acts)
                done = bool(term.get("robot_0") or trunc.get("robot_0")) or "robot_0" not in obs
                rows["reward"].append(float(rew.get("robot_0", 0.0)))
                rows["terminal"].append(bool(term.get("robot_0", False)))
                rows["end"].append(done)
                if done:
                    outcomes.append(info.get("robot_0", {}).get("event", "timeout"))
                    break
        env.close()
        arrays = {"obs": np.stack(rows["obs"]), "action": np.stack(rows["action"]).astype(np.float32),
                  "reward": np.array(rows["reward"], np.float32), "end": np.array(rows["end"], bool),
                  "terminal": np.array(rows["terminal"], bool), "by_expert": np.array(rows["by_expert"], bool)}
        meta = {"env_id": env_id, "seed": seed, "episodes": episodes, "expert": expert, "beta": beta,
                "learner": None if learner is None else str(learner), "overrides": overrides,
                "outcomes": {k: outcomes.count(k) for k in sorted(set(outcomes))}, "steps": len(rows["reward"]),
                "seconds": round(time.perf_counter() - t0, 1)}
        tmp = path.with_name(path.name + ".tmp.npz")
        np.savez_compressed(tmp, meta=np.array(json.dumps(meta)), **arrays)
        tmp.replace(path)
        print(json.dumps({"shard": str(path), **meta}), flush=True)
    return paths


def load_demos(demo_dir: str | Path) -> tuple[dict[str, np.ndarray], list[dict[str, Any]]]:
    """All shards of ``demo_dir`` concatenated (``obs``, ``action``, ``reward``, ``end``, ...) and their metadata.

    Raises:
        FileNotFoundError: when the folder holds no shard.
        ValueError: when a shard is unreadable or its arrays disagree (names the shard).
    """
    files = sorted(Path(demo_dir).glob("*.npz"))
    files = [f for f in files if not f.name.endswith(".tmp.npz")]
    if not files:
        raise FileNotFoundError(f"no demonstration shards (*.npz) in {demo_dir}; run `collect` first")
    parts: dict[str, list[np.ndarray]] = {}
    metas = []
    for f in files:
        try:
            with np.load(f, allow_pickle=False) as z:
                meta = json.loads(str(z["meta"]))
                data = {k: z[k] for k in ("obs", "action", "reward", "end", "terminal", "by_expert")}
        except (OSError, KeyError, ValueError) as err:
            raise ValueError(f"demonstration shard {f} is unreadable: {err}") from err
        n = len(data["reward"])
        if any(len(v) != n for v in data.values()) or n == 0 or not data["end"][-1]:
            raise ValueError(f"demonstration shard {f}: arrays of different lengths, empty, or a cut episode")
        for k, v in data.items():
            parts.setdefault(k, []).append(v)
        metas.append({"file": f.name, **meta})
    return {k: np.concatenate(v) for k, v in parts.items()}, metas


def pretrain(demo_dir: str | Path, out: str | Path, init_from: str | Path | None = None, epochs: int = 10,
             batch_size: int = 256, lr: float = 3e-4, gamma: float = 0.99, value_coef: float = 0.5,
             min_log_std: float = -1.6, seed: int = 0, device: str = "cpu", threads: int | None = None,
             forward_only: bool = True, val_fraction: float = 0.1) -> dict[str, Any]:
    """Fit the transformer actor-critic to the demonstrations and export it to ``out``; returns a summary.

    The validation split is by episode (a random ``val_fraction`` of the episodes). With ``init_from``
    the network (architecture, action box, weights) is that exported policy's; else navzoo's default
    transformer with ``forward_only`` actions or not. Raises ``ValueError`` when the demonstrations'
    observations do not fit the network.
    """
    from gymnasium import spaces
    from stable_baselines3.common.policies import ActorCriticPolicy

    from navzoo.agents.robot_train import FORWARD_ONLY_ACTIONS, export_policy, init_weights_from, load_policy
    from navzoo.agents.transformer import observation_dict_space, transformer_policy_kwargs

    if threads:
        torch.set_num_threads(threads)
    torch.manual_seed(seed)
    data, metas = load_demos(demo_dir)
    overrides = metas[0]["overrides"]
    if any(m["overrides"] != overrides for m in metas):
        raise ValueError(f"demonstration shards in {demo_dir} were collected with different env options")
    ret = discounted_returns(data["reward"], data["end"], gamma).astype(np.float32)
    ep_id = np.concatenate([[0], np.cumsum(data["end"][:-1])])
    n_eps = int(ep_id[-1]) + 1
    if n_eps < 2:
        raise ValueError(f"{demo_dir} holds {n_eps} episode; pretraining needs at least 2 (one is held out)")
    val_eps = set(np.random.default_rng(seed).choice(n_eps, max(1, int(round(val_fraction * n_eps))), replace=False))
    is_val = np.isin(ep_id, list(val_eps))
    scan_rays = int(overrides.get("scan_rays") or 0)
    if init_from is not None:  # its architecture and action box, its weights
        policy = load_policy(init_from).model
        ext = policy.features_extractor
        if scan_rays and not ext.scan_rays:  # the same network plus a scan input (starting at zero)
            kw = {**ext.config(), "scan_rays": scan_rays}
            obs_space = spaces.flatten_space(observation_dict_space(ext.k_neighbors, ext.history, ext.map_cells,
                                                                    scan_rays))
            arch = policy.net_arch
            widened = ActorCriticPolicy(obs_space, policy.action_space, lr_schedule=lambda _: lr,
                                        net_arch=arch if isinstance(arch, dict) else list(arch),
                                        activation_fn=policy.activation_fn,
                                        features_extractor_class=type(ext), features_extractor_kwargs=kw,
                                        share_features_extractor=policy.share_features_extractor)
            init_weights_from(widened, init_from)
            policy = widened
        policy.set_training_mode(True)
        act_space = policy.action_space
    else:  # the default architecture (navzoo train robot's defaults)
        obs_space = spaces.flatten_space(observation_dict_space(6, 8, 32, scan_rays))
        act_space = FORWARD_ONLY_ACTIONS if forward_only else spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
        policy = ActorCriticPolicy(obs_space, act_space, lr_schedule=lambda _: lr,
                                   **transformer_policy_kwargs(scan_rays=scan_rays or None))
    if data["obs"].shape[1] != policy.observation_space.shape[0]:
        raise ValueError(f"demonstrations have observations of size {data['obs'].shape[1]}, the policy takes "
                         f"{policy.observation_space.shape[0]}")
    forward_only = bool(act_space.low[0] >= 0.0)
    policy = policy.to(device)
    opt = torch.optim.Adam(policy.parameters(), lr=lr)
    tr_idx, va_idx = np.flatnonzero(~is_val), np.flatnonzero(is_val)
    obs_t = torch.as_tensor(data["obs"])
    act_t = torch.as_tensor(data["action"])
    ret_t = torch.as_tensor(ret)
    rng = np.random.default_rng(seed)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    log = open(out / "pretrain.jsonl", "a")

    def evaluate(idx: np.ndarray) -> dict[str, float]:
        policy.set_training_mode(False)
        nll, mse, vl = 0.0, 0.0, 0.0
        with torch.no_grad():
            for s in range(0, len(idx), 1024):
                b = idx[s:s + 1024]
                o, a, r = obs_t[b].to(device), act_t[b].to(device), ret_t[b].to(device)
                values, logp, _ = policy.evaluate_actions(o, a)
                mean = policy.get_distribution(o).distribution.mean
                nll += float(-logp.sum())
                mse += float(((mean.clamp(torch.as_tensor(act_space.low, device=device),
                                          torch.as_tensor(act_space.high, device=device)) - a) ** 2).sum())
                vl += float(((values.flatten() - r) ** 2).sum())
        n = max(len(idx), 1)
        return {"nll": nll / n, "action_mse": mse / n / 2, "value_mse": vl / n}

    t0 = time.perf_counter()
    for epoch in range(epochs):
        policy.set_training_mode(True)
        perm = rng.permutation(tr_idx)
        for s in range(0, len(perm), batch_size):
            b = perm[s:s + batch_size]
            o, a, r = obs_t[b].to(device), act_t[b].to(device), ret_t[b].to(device)
            values, logp, _ = policy.evaluate_actions(o, a)
            loss = -logp.mean() + value_coef * ((values.flatten() - r) ** 2).mean()
            opt.zero_grad()
            loss.backward()
            torch.nn.utils.clip_grad_norm_(policy.parameters(), 0.5)
            opt.step()
            with torch.no_grad():
                policy.log_std.clamp_(min=min_log_std)
        row = {"epoch": epoch + 1, "elapsed_s": round(time.perf_counter() - t0, 1),
               "train": evaluate(tr_idx[:20000]), "val": evaluate(va_idx),
               "log_std": [round(float(v), 3) for v in policy.log_std.detach().cpu()]}
        print(json.dumps(row), flush=True)
        log.write(json.dumps(row) + "\n")
        log.flush()
    log.close()
    meta = {"trained_with": "navzoo.agents.robot_bc pretrain", "demos": [m["file"] for m in metas],
            "demo_steps": int(len(ret)), "demo_episodes": n_eps, "epochs": epochs, "batch_size": batch_size,
            "lr": lr, "gamma": gamma, "init_from": None if init_from is None else str(init_from),
            "env_overrides": overrides, "forward_only": forward_only, "num_timesteps": 0}
    export_policy(policy.cpu(), out / "policy", meta)
    return {"out": str(out / "policy"), "steps": int(len(ret)), "episodes": n_eps, "last": row}


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m navzoo.agents.robot_bc {collect,pretrain} ...``."""
    from navzoo.agents.robot_train import TRAIN_SCENES, parse_scenes

    p = argparse.ArgumentParser(prog="python -m navzoo.agents.robot_bc", description=__doc__.split("\n\n")[0])
    sub = p.add_subparsers(dest="cmd", required=True)
    c = sub.add_parser("collect", help="record expert demonstrations (resumable, one shard per scene)")
    c.add_argument("--out", required=True)
    c.add_argument("--scenes", default="station,home,grocery")
    c.add_argument("--episodes", type=int, default=20, help="episodes per scene")
    c.add_argument("--seed", type=int, default=0)
    c.add_argument("--expert", default="orca", help="a classical method of navzoo.agents.baselines")
    c.add_argument("--learner", default=None, help="exported policy whose actions are mixed in (DAgger)")
    c.add_argument("--beta", type=float, default=1.0, help="probability of executing the expert's action")
    c.add_argument("--scan-rays", type=int, default=0, metavar="R",
                   help="also record a range scan with R rays (NavConfig.scan_rays; 0 = none)")
    t = sub.add_parser("pretrain", help="fit the policy to the demonstrations and export it")
    t.add_argument("--demos", required=True, help="folder of shards (collect --out)")
    t.add_argument("--out", required=True)
    t.add_argument("--init-from", default=None, help="exported policy to start from")
    t.add_argument("--epochs", type=int, default=10)
    t.add_argument("--batch-size", type=int, default=256)
    t.add_argument("--lr", type=float, default=3e-4)
    t.add_argument("--device", default="cpu")
    t.add_argument("--threads", type=int, default=None)
    t.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    try:
        if args.cmd == "collect":
            scenes = parse_scenes(args.scenes) if args.scenes else TRAIN_SCENES
            overrides = {**DEFAULT_OVERRIDES, **({"scan_rays": args.scan_rays} if args.scan_rays else {})}
            collect(args.out, scenes, args.episodes, seed=args.seed, expert=args.expert, learner=args.learner,
                    beta=args.beta, overrides=overrides)
        else:
            summary = pretrain(args.demos, args.out, init_from=args.init_from, epochs=args.epochs,
                               batch_size=args.batch_size, lr=args.lr, device=args.device, threads=args.threads,
                               seed=args.seed)
            print(json.dumps(summary), flush=True)
    except (ValueError, FileNotFoundError) as err:
        print(f"error: {err}", file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
