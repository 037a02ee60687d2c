"""Which AMP discriminator inputs separate policy rollouts from the reference clips, one feature at a time.

For an exported AMP pedestrian policy this collects discriminator input windows (``info["amp_obs"]``,
2 frames x 105 features of :func:`navzoo.agents.amp.features.amp_features`) from closed-loop rollouts
of the path task the shipped checkpoint was trained on (stage 3, obstacle rays, 4 boxes and two
humanoids per patch, no doors, per-humanoid replans, grounded clips for starts; deterministic actions,
no steering trim) and as many reference windows sampled the way the learner samples them
(``AmpPathEnv.sample_reference_amp_obs``: grounded locomotion clips, finite-difference velocities).
It then reports, for every one of the 210 input dimensions, the single-feature ROC AUC

    AUC = P(x_policy > x_reference) + 0.5 P(tie)     (rank-based, Mann-Whitney U / (n_p n_r))

so 0.5 = no separation, 1 = every policy value above every reference value, 0 = every one below; and
the "spread AUC", the same statistic for the distance to the reference median (> 0.5: the policy's
values lie farther out), which sees differences in spread that the plain AUC misses.

Also reported: split-half AUCs (policy windows of even vs odd patches); the same statistics for
rollouts with training's fixed action noise (``--compare-action-std``, default exp(-2.9) = 0.055) and
for the policy windows kept in the training checkpoint's replay buffer (the last 100,000 of training,
stochastic actions); the checkpoint's own discriminator (accuracy by sign, AUC, mean logits, style
reward) on all of these, and on windows whose velocity columns are swapped between the deterministic
and the noisy rollouts; held-out AUCs of linear probes (logistic regression) on feature groups.

Run (about 3 min on the 2-core VM for 8,000 windows a side, one process)::

    python scripts/amp_disc_feature_auc.py --samples 8000 --seconds 30 --json OUT.json

``--ckpt DIR`` is the training checkpoint (``training/amp``: ``state.pt`` or its parts
``state.pt.part-a*``, reassembled in a temporary directory and checked against ``meta.json``); its
discriminator and replay rows are skipped with ``--ckpt ''``.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import tempfile
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch
from scipy.stats import rankdata

from navzoo.agents.amp import checkpoint as ckpt
from navzoo.agents.amp.features import (
    FEATURE_DIM,
    FEATURE_SLICES,
    KEY_BODY_NAMES,
    N_FEATURE_KEYS,
    N_RAYS,
    REV,
    SPH,
    load_humanoid_model,
)
from navzoo.agents.amp.networks import style_reward
from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.train import grounded_locomotion_reference

# ---------------------------------------------------------------------------------------------- names

# Joint frames of humanoid.urdf at rest: x forward, y up, z right (the base frame; all joint origins
# carry no rotation). For a small rotation w, the 6-D features are x-axis = (1, w_z, -w_y) and
# z-axis = (w_y, -w_x, 1): rotation about z is the sagittal plane (flexion/extension: + swings a
# hanging hip or shoulder forward, lifts the toes at an ankle, leans the chest back), about x the frontal
# plane, about y a twist.
_SIX_D = ("x-axis.x", "x-axis.y [~ +rot about z: sagittal]", "x-axis.z [~ -rot about y: twist]",
          "z-axis.x [~ +rot about y: twist]", "z-axis.y [~ -rot about x: frontal]", "z-axis.z")
_CHILD_AXES = ("x [fwd: frontal]", "y [up: twist]", "z [right: sagittal]")
_HEADING_AXES = ("forward", "left", "up")


def feature_names() -> list[tuple[str, str]]:
    """(short name, meaning) of each of the 105 per-frame features, in the order of ``amp_features``."""
    names = load_humanoid_model().names
    out: list[tuple[str, str]] = [("root_height", "root (pelvis COM) height, world z, m")]
    for axis, label in (("fwd", "body forward axis"), ("up", "body up axis")):
        for c, comp in zip("xyz", _HEADING_AXES, strict=True):
            out.append((f"root_rot.{axis}.{c}", f"{label}, heading-frame {comp} component"))
    for c, comp in zip("xyz", _HEADING_AXES, strict=True):
        out.append((f"root_lin_vel.{c}", f"root velocity, heading frame, {comp}, m/s"))
    for c, comp in zip("xyz", ("about forward (roll)", "about left (pitch)", "about up (yaw)"), strict=True):
        out.append((f"root_ang_vel.{c}", f"root angular velocity, heading frame, {comp}, rad/s"))
    for j in SPH:
        for k, comp in enumerate(_SIX_D):
            out.append((f"{names[j]}.rot6d[{k}]", f"{names[j]} rotation (parent frame), {comp}"))
    for j in REV:
        out.append((f"{names[j]}.angle", f"{names[j]} angle about +z (right), rad"))
    for j in SPH:
        for c, comp in zip("xyz", _CHILD_AXES, strict=True):
            out.append((f"{names[j]}.vel.{c}", f"{names[j]} angular velocity (child frame) about {comp}, rad/s"))
    for j in REV:
        out.append((f"{names[j]}.rate", f"{names[j]} angular rate, rad/s"))
    for b in KEY_BODY_NAMES[:N_FEATURE_KEYS]:
        for c, comp in zip("xyz", _HEADING_AXES, strict=True):
            out.append((f"{b}.pos.{c}", f"{b} COM relative to the root, heading frame, {comp}, m"))
    assert len(out) == FEATURE_DIM
    return out


def window_names(window: int) -> list[tuple[str, str]]:
    """Names of the ``window * 105`` discriminator inputs: frame ``t-k`` (oldest first) and feature."""
    base = feature_names()
    frames = [f"t-{window - 1 - k}" if k < window - 1 else "t" for k in range(window)]
    return [(f"{f}:{n}", m) for f in frames for n, m in base]


# ---------------------------------------------------------------------------------------------- statistics


def auc_per_column(pos: np.ndarray, neg: np.ndarray) -> np.ndarray:
    """P(pos > neg) + 0.5 P(pos = neg) for every column: rank-based (Mann-Whitney U / (n_pos n_neg))."""
    n_p, n_n = len(pos), len(neg)
    ranks = rankdata(np.concatenate([pos, neg]).astype(np.float64), axis=0)  # average ranks for ties
    u = ranks[:n_p].sum(axis=0) - n_p * (n_p + 1) / 2.0
    return u / (n_p * n_n)


def spread_auc_per_column(pos: np.ndarray, neg: np.ndarray) -> np.ndarray:
    """:func:`auc_per_column` of the distance to the reference (``neg``) median: > 0.5 when the policy
    values lie farther out than the reference's. Sees a difference in spread that the plain AUC, a
    location statistic, misses (a zero-mean joint velocity with 3x the reference's spread has AUC 0.5)."""
    med = np.median(neg, axis=0)
    return auc_per_column(np.abs(pos - med), np.abs(neg - med))


def _moments(x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    x = x.astype(np.float64)
    return x.mean(axis=0), x.std(axis=0)


def linear_probe_auc(pos: np.ndarray, neg: np.ndarray, cols: np.ndarray, seed: int, steps: int = 200) -> float:
    """Held-out AUC of a logistic regression (L2 1e-3, LBFGS) on columns ``cols``: fit on 70 % of each
    side, score the other 30 %. Separability by a linear function, not by the discriminator's MLP."""
    rng = np.random.default_rng(seed)
    x = np.concatenate([pos[:, cols], neg[:, cols]]).astype(np.float64)
    y = np.concatenate([np.ones(len(pos)), np.zeros(len(neg))])
    test = np.zeros(len(y), dtype=bool)
    for side in (np.flatnonzero(y == 1), np.flatnonzero(y == 0)):
        test[rng.choice(side, size=int(0.3 * len(side)), replace=False)] = True
    mu, sd = x[~test].mean(axis=0), x[~test].std(axis=0) + 1e-8
    xt = torch.as_tensor((x - mu) / sd, dtype=torch.float64)
    yt = torch.as_tensor(y, dtype=torch.float64)
    tr = torch.as_tensor(~test)
    w = torch.zeros(len(cols) + 1, dtype=torch.float64, requires_grad=True)
    opt = torch.optim.LBFGS([w], max_iter=steps, line_search_fn="strong_wolfe")

    def closure() -> torch.Tensor:
        opt.zero_grad()
        z = xt[tr] @ w[:-1] + w[-1]
        loss = torch.nn.functional.binary_cross_entropy_with_logits(z, yt[tr]) + 1e-3 * w[:-1].square().sum()
        loss.backward()
        return loss

    opt.step(closure)
    with torch.no_grad():
        z = (xt[~tr] @ w[:-1] + w[-1]).numpy()
    yt_test = y[test]
    return float(auc_per_column(z[yt_test == 1][:, None], z[yt_test == 0][:, None])[0])


# ---------------------------------------------------------------------------------------------- checkpoint


def load_training_checkpoint(path: Path) -> tuple[dict[str, Any], dict[str, Any]]:
    """Tensors and meta of a training checkpoint directory holding ``state.pt`` or ``state.pt.part-*``."""
    if (path / ckpt.STATE_FILE).is_file():
        return ckpt.load_checkpoint(path)
    with tempfile.TemporaryDirectory() as tmp:
        return ckpt.load_checkpoint(ckpt.join_split_checkpoint(path, tmp))  # checks the joined state's sha256


def discriminator_of(tensors: dict[str, Any], meta: dict[str, Any]):
    """(logit function of raw windows, info) from a checkpoint's discriminator and input normaliser."""
    from navzoo.agents.amp.learner import AmpConfig
    from navzoo.agents.amp.networks import Discriminator
    from navzoo.agents.amp.normalizer import RunningMeanStd

    cfg = AmpConfig.from_dict(meta["config"])
    dim = int(meta["dims"]["amp_obs_dim"])
    disc = Discriminator(dim, cfg.disc_hidden, cfg.activation)
    disc.load_state_dict(tensors["disc"])
    disc.eval()
    norm = RunningMeanStd(dim, cfg.norm_eps, cfg.obs_clip)
    norm.load_state_dict(tensors["amp_norm"])

    @torch.no_grad()
    def logits(x: np.ndarray) -> np.ndarray:
        return disc(norm.normalize(torch.as_tensor(np.asarray(x, np.float32)))).numpy().astype(np.float64)

    return logits, {"disc_hidden": list(cfg.disc_hidden), "amp_norm_count": float(norm.count)}


def policy_matches_checkpoint(policy: Any, tensors: dict[str, Any]) -> bool:
    """Whether the exported policy's actor and observation normaliser equal the checkpoint's."""
    mine = {f"actor.{k}": v for k, v in policy.actor.state_dict().items()}
    mine |= {f"obs_norm.{k}": v for k, v in policy.obs_norm.state_dict().items()}
    theirs = {f"actor.{k}": v for k, v in tensors["actor"].items()}
    theirs |= {f"obs_norm.{k}": v for k, v in tensors["obs_norm"].items()}
    return mine.keys() == theirs.keys() and all(torch.equal(mine[k].cpu(), theirs[k].cpu()) for k in mine)


def disc_summary(logit_pol: np.ndarray, logit_ref: np.ndarray) -> dict[str, float]:
    """Accuracy by sign, AUC and mean logits / style reward of the discriminator (reference = positive)."""
    style = style_reward(torch.as_tensor(logit_pol)).numpy()  # the learner's style reward
    return {
        "acc_policy": float(np.mean(logit_pol < 0)),
        "acc_reference": float(np.mean(logit_ref > 0)),
        "auc_reference_above_policy": float(auc_per_column(logit_ref[:, None], logit_pol[:, None])[0]),
        "mean_logit_policy": float(logit_pol.mean()),
        "mean_logit_reference": float(logit_ref.mean()),
        "mean_style_reward_policy": float(style.mean()),
    }


def velocity_columns(window: int, groups: tuple[str, ...]) -> np.ndarray:
    """Boolean mask of the window's columns that belong to the feature ``groups`` (in every frame)."""
    mask = np.zeros(window * FEATURE_DIM, dtype=bool)
    for k in range(window):
        for g in groups:
            s = FEATURE_SLICES[g]
            mask[k * FEATURE_DIM + s.start:k * FEATURE_DIM + s.stop] = True
    return mask


def swap_ablation(logits: Any, a: np.ndarray, b: np.ndarray, ref_logits: np.ndarray, window: int,
                  label_a: str, label_b: str) -> dict[str, dict[str, float]]:
    """The discriminator on windows whose velocity columns come from the other set (rows paired at
    random): which of poses and velocities carries its verdict. The swapped windows are not physically
    consistent (their velocities are not the differences of their poses); an indication, not a proof."""
    rng = np.random.default_rng(0)
    n = min(len(a), len(b))
    a, b = a[rng.permutation(len(a))[:n]], b[rng.permutation(len(b))[:n]]
    out = {}
    for groups, what in ((("root_lin_vel", "root_ang_vel", "sph_vel", "rev_vel"), "all velocities"),
                         (("sph_vel", "rev_vel"), "joint velocities")):
        mask = velocity_columns(window, groups)
        x = a.copy()
        x[:, mask] = b[:, mask]
        out[f"{label_a} poses + {label_b} {what}"] = disc_summary(logits(x), ref_logits)
        x = b.copy()
        x[:, mask] = a[:, mask]
        out[f"{label_b} poses + {label_a} {what}"] = disc_summary(logits(x), ref_logits)
    return out


# ---------------------------------------------------------------------------------------------- rollouts


def collect_policy_windows(policy: Any, env: AmpPathEnv, steps: int, warmup: int, action_std: float,
                           seed: int) -> dict[str, np.ndarray]:
    """All ``info["amp_obs"]`` rows of ``steps`` control steps after ``warmup`` (every env, every step),
    with each row's env index and the steps since that env's last reset (1 = first step of an episode,
    whose older frame is the start state with its initial velocities)."""
    rng = np.random.default_rng(seed + 1)
    obs = env.reset(seed=seed)
    age = np.zeros(env.num_envs, dtype=int)
    rows, envs, ages, falls, ends, speed = [], [], [], 0, 0, []
    fwd = FEATURE_DIM * (env.cfg.amp_window - 1) + FEATURE_SLICES["root_lin_vel"].start
    for t in range(warmup + steps):
        act = policy(obs)
        if action_std > 0:
            act = np.clip(act + action_std * rng.standard_normal(act.shape), -1.0, 1.0)
        obs, _, term, trunc, info = env.step(act)
        age += 1
        if t >= warmup:
            rows.append(info["amp_obs"].copy())
            envs.append(np.arange(env.num_envs))
            ages.append(age.copy())
            falls += int((term & info["fallen"]).sum())
            ends += int((term | trunc).sum())
            speed.append(info["amp_obs"][:, fwd])
        age[term | trunc] = 0
    return {"windows": np.concatenate(rows), "env": np.concatenate(envs), "age": np.concatenate(ages),
            "falls": np.array(falls), "episodes_ended": np.array(ends), "fwd_speed": np.concatenate(speed)}


# ---------------------------------------------------------------------------------------------- main


def _fmt_row(rank: int, f: dict[str, Any]) -> str:
    return (f"{rank:>3} {f['dim']:>4} {f['name']:<31} {f['auc']:6.3f} {f['auc_half_a']:5.3f}/{f['auc_half_b']:5.3f} "
            f"{f['spread_auc']:6.3f} {f['policy_mean']:+8.3f} {f['policy_std']:6.3f} {f['reference_mean']:+8.3f} "
            f"{f['reference_std']:6.3f}" + (f" {f['auc_replay_vs_reference']:6.3f}" if "auc_replay_vs_reference" in f
                                            else "")
            + (f" {f['noisy_auc']:6.3f} {f['noisy_spread_auc']:6.3f} {f['noisy_std']:6.3f}" if "noisy_auc" in f else ""))


def _column_stats(x: np.ndarray, ref: np.ndarray) -> dict[str, np.ndarray]:
    mean, std = _moments(x)
    return {"auc": auc_per_column(x, ref), "spread_auc": spread_auc_per_column(x, ref), "mean": mean, "std": std}


def parse_args(argv: list[str] | None = None) -> argparse.Namespace:
    from navzoo.agents.amp.learner import AmpConfig

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--policy", default="policies/amp_pedestrian", help="exported policy directory")
    ap.add_argument("--ckpt", default="training/amp", help="training checkpoint directory ('' = none)")
    ap.add_argument("--samples", type=int, default=4000, help="windows per side (policy, reference)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--envs", type=int, default=32, help="humanoids simulated together (two per patch)")
    ap.add_argument("--seconds", type=float, default=None,
                    help="rollout length after the warm-up (default: enough for 2 windows per sample, "
                         "at least one 10 s episode); windows are drawn at random from all of it")
    ap.add_argument("--warmup", type=float, default=2.0, help="seconds of rollout discarded first")
    ap.add_argument("--stage", type=int, default=3)
    ap.add_argument("--door-prob", type=float, default=0.0, help="5174 trained without doors")
    ap.add_argument("--replan-sync", type=int, default=0, help="1: synchronised replans (runs 21+); 5174: 0")
    ap.add_argument("--action-std", type=float, default=0.0,
                    help="Gaussian action noise of the main rollout; 0 = deterministic (the action mean)")
    ap.add_argument("--compare-action-std", type=float, default=round(float(np.exp(AmpConfig().init_log_std)), 5),
                    help="also collect windows with this action noise (default: training's fixed exp(-2.9)); "
                         "0 = skip")
    ap.add_argument("--keep-trim", action="store_true",
                    help="apply the policy config's steering trim (training had none)")
    ap.add_argument("--velocity-span", type=int, default=1,
                    help="control steps the velocity features span (PathTaskConfig.amp_velocity_span; the checkpoint's)")
    ap.add_argument("--top", type=int, default=25)
    ap.add_argument("--no-probes", action="store_true", help="skip the linear probes on feature groups")
    ap.add_argument("--json", default=None, help="write everything here")
    return ap.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(argv)
    torch.set_num_threads(1)
    t_start = time.time()

    policy = ckpt.load_policy(args.policy)
    if not args.keep_trim:
        policy.override(steering_trim=0.0)
    rays = policy.obs_dim == FEATURE_DIM + 2 * PathTaskConfig().n_waypoints + N_RAYS
    task = PathTaskConfig(stage=args.stage, pd_mode="motor", obstacle_obs=rays,
                          boxes_per_patch=4 if rays and args.stage == 3 else 0,
                          pair_patches=rays and args.stage == 3, door_prob=args.door_prob,
                          replan_sync=bool(args.replan_sync), amp_velocity="finite_difference",
                          amp_velocity_span=args.velocity_span)

    reference = grounded_locomotion_reference()
    hz = task.control_hz
    warmup = int(round(args.warmup * hz))
    steps = (int(np.ceil(args.seconds * hz)) if args.seconds
             else max(int(round(task.episode_seconds * hz)), int(np.ceil(2 * args.samples / args.envs))))
    rng = np.random.default_rng(args.seed)

    def rollout(action_std: float) -> tuple[np.ndarray, dict[str, Any], np.ndarray, AmpPathEnv]:
        env = AmpPathEnv(args.envs, reference, task, seed=args.seed)
        t0 = time.time()
        col = collect_policy_windows(policy, env, steps, warmup, action_std, args.seed)
        n = min(args.samples, len(col["windows"]))
        pick = np.sort(rng.choice(len(col["windows"]), size=n, replace=False))
        info = {"action_std": action_std, "envs": args.envs, "steps": steps, "warmup_steps": warmup,
                "windows_collected": int(len(col["windows"])), "windows_used": int(n),
                "falls": int(col["falls"]), "episodes_ended": int(col["episodes_ended"]),
                "share_first_step_of_episode": float(np.mean(col["age"][pick] == 1)),
                "forward_speed_mean": float(col["fwd_speed"].mean()),
                "forward_speed_quartiles": np.percentile(col["fwd_speed"], [25, 50, 75]).tolist(),
                "seconds": round(time.time() - t0, 1)}
        return col["windows"][pick].astype(np.float64), info, env.patch[col["env"][pick]], env

    pol, rollout_info, patch, env = rollout(args.action_std)
    ref = env.sample_reference_amp_obs(len(pol), rng).astype(np.float64)  # as AmpLearner.update does
    amp_obs_version = env.amp_obs_version
    env.close()
    noisy = None
    if args.compare_action_std > 0:
        noisy, noisy_info, _, env = rollout(args.compare_action_std)
        env.close()

    names = window_names(task.amp_window)
    main_stats = _column_stats(pol, ref)
    auc_a = auc_per_column(pol[patch % 2 == 0], ref)
    auc_b = auc_per_column(pol[patch % 2 == 1], ref)
    result: dict[str, Any] = {
        "what": "single-feature ROC AUC of the AMP discriminator inputs, AUC = P(policy > reference) + 0.5 P(tie); "
                "spread_auc: the same for the distance to the reference median",
        "args": vars(args),
        "task": dataclasses.asdict(task),
        "amp_obs_version": amp_obs_version,
        "policy": {"dir": args.policy, "steering_trim_applied": policy.steering_trim,
                   "trained_iterations": policy.config.get("trained_iterations")},
        "rollout": rollout_info,
        "reference": {"windows": int(len(ref)), "sampler": "AmpPathEnv.sample_reference_amp_obs "
                      "(grounded locomotion clips, finite-difference velocities)"},
    }
    extra: dict[str, dict[str, np.ndarray]] = {}
    if noisy is not None:
        result["rollout_noisy"] = noisy_info
        extra["noisy"] = _column_stats(noisy, ref)

    if args.ckpt:
        tensors, meta = load_training_checkpoint(Path(args.ckpt))
        if (meta.get("amp_obs_version") or "velocity=physics;ground=None") != amp_obs_version:
            raise SystemExit(f"{args.ckpt}: its discriminator read {meta.get('amp_obs_version')!r}, these windows are "
                             f"{amp_obs_version!r} (set --velocity-span to the checkpoint's, or --ckpt '')")
        logits, dinfo = discriminator_of(tensors, meta)
        replay = tensors["replay"]["data"].numpy().astype(np.float64)
        lr = logits(ref)
        result["checkpoint"] = {
            "dir": args.ckpt, "iteration": int(meta["iteration"]), "amp_obs_version": meta.get("amp_obs_version"),
            "amp_obs_version_matches_env": meta.get("amp_obs_version") == amp_obs_version,
            "policy_matches_checkpoint_actor": policy_matches_checkpoint(policy, tensors),
            "replay_rows": int(len(replay)),
            "replay_note": "a uniform sample of the last 100,000 policy windows of training (stochastic actions)",
            **dinfo,
        }
        sets = {"rollout": pol, "replay": replay} | ({"rollout_noisy": noisy} if noisy is not None else {})
        disc: dict[str, Any] = {f"{k}_vs_reference": disc_summary(logits(x), lr) for k, x in sets.items()}
        disc["logit_percentiles_5_25_50_75_95"] = {
            k: np.percentile(logits(x), [5, 25, 50, 75, 95]).tolist() for k, x in (sets | {"reference": ref}).items()}
        if noisy is not None:
            label = "deterministic" if args.action_std == 0 else f"std {args.action_std}"
            disc["swap_ablation"] = swap_ablation(logits, pol, noisy, lr, task.amp_window, label,
                                                  f"noisy (std {args.compare_action_std})")
        result["discriminator"] = disc
        extra["replay"] = _column_stats(replay, ref)
        auc_pol_rep = auc_per_column(pol, replay)

    features = []
    for d, (name, meaning) in enumerate(names):
        f: dict[str, Any] = {
            "dim": d, "name": name, "meaning": meaning, "auc": float(main_stats["auc"][d]),
            "sep": float(abs(main_stats["auc"][d] - 0.5)), "auc_half_a": float(auc_a[d]),
            "auc_half_b": float(auc_b[d]), "spread_auc": float(main_stats["spread_auc"][d]),
            "policy_mean": float(main_stats["mean"][d]), "policy_std": float(main_stats["std"][d]),
            "reference_mean": float(ref[:, d].mean()), "reference_std": float(ref[:, d].std()),
        }
        f["policy_constant"], f["reference_constant"] = f["policy_std"] < 1e-7, f["reference_std"] < 1e-7
        if "replay" in extra:
            r = extra["replay"]
            f |= {"auc_replay_vs_reference": float(r["auc"][d]), "spread_auc_replay": float(r["spread_auc"][d]),
                  "replay_mean": float(r["mean"][d]), "replay_std": float(r["std"][d]),
                  "auc_rollout_vs_replay": float(auc_pol_rep[d])}
        if "noisy" in extra:
            r = extra["noisy"]
            f |= {"noisy_auc": float(r["auc"][d]), "noisy_spread_auc": float(r["spread_auc"][d]),
                  "noisy_mean": float(r["mean"][d]), "noisy_std": float(r["std"][d])}
        features.append(f)
    result["features"] = features
    order = sorted(range(len(features)), key=lambda d: -features[d]["sep"])
    spread_order = sorted(range(len(features)), key=lambda d: -abs(features[d]["spread_auc"] - 0.5))
    last = slice(FEATURE_DIM * (task.amp_window - 1), FEATURE_DIM * task.amp_window)
    result["top"] = [features[d]["name"] for d in order[: args.top]]
    result["top_last_frame"] = [f["name"] for f in sorted(features[last], key=lambda f: -f["sep"])[: args.top]]
    result["top_spread"] = [features[d]["name"] for d in spread_order[: args.top]]
    if noisy is not None:
        result["top_noisy_spread"] = [f["name"] for f in sorted(features, key=lambda f: -abs(f["noisy_spread_auc"] - 0.5))
                                      [: args.top]]
    for key, lo in (("auc", 0.45), ("auc", 0.4), ("spread_auc", 0.45), ("spread_auc", 0.4),
                    ("noisy_auc", 0.45), ("noisy_spread_auc", 0.45)):
        if key in features[0]:
            result[f"n_{key}_beyond_{0.5 + lo:.2f}_or_{0.5 - lo:.2f}"] = int(
                sum(abs(f[key] - 0.5) > lo for f in features))
    result["constant_features"] = [f["name"] for f in features if f["policy_constant"] or f["reference_constant"]]

    if not args.no_probes:
        groups: dict[str, list[int]] = {g: list(np.flatnonzero(velocity_columns(task.amp_window, (g,))))
                                        for g in FEATURE_SLICES}
        poses = ("root_height", "root_rot", "sph_rot", "rev_angle", "key_pos")
        groups["poses (height, orientation, joints, key bodies)"] = list(
            np.flatnonzero(velocity_columns(task.amp_window, poses)))
        groups["velocities (root, joints)"] = list(np.flatnonzero(
            velocity_columns(task.amp_window, tuple(g for g in FEATURE_SLICES if g not in poses))))
        groups["all"] = list(range(len(names)))
        result["linear_probe_heldout_auc"] = {
            g: linear_probe_auc(pol, ref, np.array(c), args.seed) for g, c in groups.items()}

    result["wall_s"] = round(time.time() - t_start, 1)
    _print_report(result, features, order, spread_order, args.top)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps(result, indent=1) + "\n")
        print(f"wrote {args.json}")
    return 0


def _print_report(result: dict[str, Any], features: list[dict[str, Any]], order: list[int],
                  spread_order: list[int], top: int) -> None:
    ro = result["rollout"]
    print(f"{ro['windows_used']} policy windows (action std {ro['action_std']}; {ro['envs']} bodies x {ro['steps']} "
          f"steps after {ro['warmup_steps']}, {ro['falls']} falls, forward speed {ro['forward_speed_mean']:.2f} m/s), "
          f"{result['reference']['windows']} reference windows")
    for k, v in result.get("discriminator", {}).items():
        if k.endswith("_vs_reference"):
            print(f"discriminator, {k}: " + ", ".join(f"{a} {b:.3f}" for a, b in v.items()))
    for k, v in result.get("discriminator", {}).get("swap_ablation", {}).items():
        print(f"  swap: {k:<62} acc_policy {v['acc_policy']:.3f}, mean logit {v['mean_logit_policy']:+.3f}, "
              f"AUC {v['auc_reference_above_policy']:.4f}")
    hdr = (f"{'#':>3} {'dim':>4} {'feature':<31} {'AUC':>6} {'halves':>11} {'spread':>6} {'pol mean':>8} {'std':>6} "
           f"{'ref mean':>8} {'std':>6}" + (" replay" if "auc_replay_vs_reference" in features[0] else "")
           + ("  noisy spread    std" if "noisy_auc" in features[0] else ""))
    print("AUC = P(policy > reference); halves: even / odd patches; spread: AUC of |x - reference median|; "
          "replay: AUC of the checkpoint's replay rows; noisy: AUC, spread AUC and std of rollouts with "
          "training's action noise")
    print(hdr)
    for r, d in enumerate(order[:top], 1):
        print(_fmt_row(r, features[d]))
    print(f"most different in spread (|spread - 0.5| largest, top {top // 2}):")
    print(hdr)
    for r, d in enumerate(spread_order[: top // 2], 1):
        print(_fmt_row(r, features[d]))
    shown = [features[d]["name"].split(":", 1)[1] for d in order[:top] + spread_order[: top // 2]]
    if "noisy_spread_auc" in features[0]:
        noisy_order = sorted(range(len(features)), key=lambda d: -abs(features[d]["noisy_spread_auc"] - 0.5))
        print(f"most different in spread with training's action noise (top {top // 2}):")
        print(hdr)
        for r, d in enumerate(noisy_order[: top // 2], 1):
            print(_fmt_row(r, features[d]))
        shown += [features[d]["name"].split(":", 1)[1] for d in noisy_order[: top // 2]]
    print("meanings:")
    for name in dict.fromkeys(shown):
        print(f"  {name}: {next(f['meaning'] for f in features if f['name'].endswith(':' + name))}")
    print("; ".join(f"{k}: {v}" for k, v in result.items() if k.startswith("n_")))
    print(f"constant on a side: {result['constant_features']}")
    if "linear_probe_heldout_auc" in result:
        print("linear probes, held-out AUC: " + ", ".join(
            f"{g} {v:.3f}" for g, v in result["linear_probe_heldout_auc"].items()))
    print(f"wall {result['wall_s']} s")


if __name__ == "__main__":
    raise SystemExit(main())
