"""A warm start for AMP training: behaviour cloning of the clips' own PD targets (an experiment, 2026-11-29).

Why: clip tracking's rotation error compares the body's link orientations with the clip's, frame by frame.
A clip compared with *itself* 0.2 s later already errs by 0.33 rad and 0.3 s later by 0.43 rad
(docs/pedestrians_log.md, "What the rotation error measures"), so the paper's 0.343 rad needs a controller that
continues the clip's own gait, in phase, from the reference state it starts in. The policies trained from
random weights adopt a gait of their own within a few control steps (0.48-0.56 rad). This module gives the
actor that continuation before any reinforcement learning:

1. **oracle rollouts**: reference state initialisation at random (clip, time) starts of the training clips,
   then each control step the PD targets are the clip's pose ``lead`` control steps ahead (the oracle of
   stage 0; with the position motors it keeps the pose within 0.05 rad of the clip while the body is up, but
   it has no balance feedback and falls after about a second). The executed targets carry Gaussian noise in
   action units (the states spread like a noisy policy's, DART-style); the recorded labels are the clean
   oracle actions. The observation is the policy's own (``policy_observation``: the simulator's state, the
   clip's root path as the target waypoints, extended at its final velocity after its end, as in clip
   tracking). Rollouts stop at falls;
2. **regression**: an actor of the training architecture fitted to the labels (mean squared error on the
   normalised observations; the observation normaliser is the data's mean and variance);
3. **a training checkpoint** at iteration 0 of a ``navzoo train amp`` run (fresh critic and discriminator,
   this actor and normaliser), which a run resumes with ``--any-num-envs 1``, and the exported policy.

CLI::

    python -m navzoo.agents.amp.bc --out runs/amp_bc --starts 4096 --seconds 1.5 --epochs 30 \\
        --hidden 1024,512 --amp-velocity-span 4 --disc-lr 2e-5 --disc-grad-penalty 50 --disc-weight-decay 5e-4

With ``--data-out F.npz`` the cloning pairs are kept too, for the actor's cloning term during reinforcement
learning (``navzoo train amp --bc-coef W --bc-data F.npz``, ``AmpConfig.bc_coef``); ``--pairs-only`` writes only
them, and ``--workers N`` spreads the rollouts over N processes (the same pairs for any N: each batch of
:data:`BATCH` bodies draws its own noise stream from ``--seed``)::

    python -m navzoo.agents.amp.bc --pairs-only --data-out /tmp/bc_pairs.npz --workers 16 --amp-velocity-span 4

``--min-ahead S`` keeps only the pairs after which the oracle's body stayed up at least S seconds more
(:func:`viable_pairs`): the oracle does not balance, so its labels shortly before a fall teach the wrong action.
"""

from __future__ import annotations

import argparse
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navzoo import sim as nzsim
from navzoo.agents.amp.features import policy_observation
from navzoo.agents.amp.path_env import PathTaskConfig
from navzoo.agents.amp.sim import PhysicsHumanoids, actions_to_targets, targets_to_actions
from navzoo.agents.amp.tracking import clip_end_motion
from navzoo.agents.reference import ReferenceMotion

#: Humanoids per PyBullet client in the oracle rollouts (40 m apart, like clip tracking).
BATCH = 64
SPACING = 40.0


def clip_waypoints(ref: ReferenceMotion, clips: np.ndarray, times: np.ndarray, n: int, dt: float) -> np.ndarray:
    """(B, n, 2) root positions of ``clips`` at ``times + dt * (1..n)``; after a clip's end the path goes on
    at the clip's final root velocity, as in clip tracking (:func:`~navzoo.agents.amp.tracking.clip_end_motion`)."""
    clips = np.asarray(clips, dtype=np.int64)
    b = len(clips)
    full = np.array([ref.duration(int(c)) for c in clips])
    ahead = np.asarray(times, dtype=np.float64)[:, None] + dt * np.arange(1, n + 1)[None, :]  # (B, n)
    inside = np.minimum(ahead, full[:, None])
    pos = np.asarray(ref.state_at(np.repeat(clips, n), inside.reshape(-1)).root_pos)[:, :2].reshape(b, n, 2)
    end, vel = clip_end_motion(ref, clips, full)
    extra = end[:, None, :] + vel[:, None, :] * np.maximum(ahead - full[:, None], 0.0)[..., None]
    return np.where((ahead > full[:, None])[..., None], extra, pos)


def _rollout_batch(ref: ReferenceMotion, clips: np.ndarray, t0: np.ndarray, dur: np.ndarray, steps: int, lead: int,
                   noise: float, seed: np.random.SeedSequence, cfg: PathTaskConfig) -> dict[str, np.ndarray]:
    """One PyBullet client of oracle rollouts (``len(clips)`` bodies): its pairs and how long each body stayed up."""
    rng = np.random.default_rng(seed)
    hz = cfg.control_hz
    n = len(clips)
    cols = int(np.ceil(np.sqrt(n)))
    k = np.arange(n)
    origin = np.stack([(k % cols) * SPACING, (k // cols) * SPACING, np.zeros(n)], axis=1)
    start = ref.state_at(clips, t0)
    shift = origin - np.c_[np.asarray(start.root_pos)[:, :2], np.zeros(n)]
    obs, act, clip_of, time_of, body_of, step_of = [], [], [], [], [], []
    up_s = np.zeros(n)
    client = nzsim.connect()
    try:
        bodies = PhysicsHumanoids(client, n, physics_hz=cfg.physics_hz, control_hz=hz, pd_mode=cfg.pd_mode)
        bodies.set_state(start.translated(shift))
        up = np.ones(n, dtype=bool)
        for step in range(steps):
            t = t0 + step / hz
            state = bodies.read_state()
            wp = clip_waypoints(ref, clips, t, cfg.n_waypoints, cfg.waypoint_dt) + shift[:, None, :2]
            o = policy_observation(state, wp)
            tgt = ref.state_at(clips, np.minimum(t + lead / hz, dur))
            a = np.clip(targets_to_actions(tgt.sph, tgt.rev), -1.0, 1.0)
            obs.append(o[up])
            act.append(a[up].astype(np.float32))
            clip_of.append(clips[up])
            time_of.append(t[up])
            body_of.append(k[up])
            step_of.append(np.full(int(up.sum()), step))
            executed = np.clip(a + noise * rng.standard_normal(a.shape), -1.0, 1.0) if noise > 0 else a
            bodies.apply_targets(*actions_to_targets(executed))
            bodies.step()
            up &= ~bodies.fallen()
            up_s[up] = (step + 1) / hz
            if not up.any():
                break
    finally:
        nzsim.disconnect(client)
    body, at = np.concatenate(body_of), np.concatenate(step_of)
    # seconds the body stayed up after each pair; a body still up at the end of its rollout: inf
    ahead = np.where(up[body], np.inf, up_s[body] - at / hz).astype(np.float32)
    return {"obs": np.concatenate(obs), "act": np.concatenate(act), "clip": np.concatenate(clip_of),
            "time": np.concatenate(time_of), "ahead_s": ahead, "up_s": up_s}


#: The reference motion of a rollout worker process, sent once when it starts (not with every batch).
_WORKER_REF: ReferenceMotion | None = None


def _set_worker_reference(ref: ReferenceMotion) -> None:
    global _WORKER_REF
    _WORKER_REF = ref


def _rollout_batch_in_worker(*job: Any) -> dict[str, np.ndarray]:
    return _rollout_batch(_WORKER_REF, *job)


def oracle_rollouts(ref: ReferenceMotion, starts: int, seconds: float = 1.5, lead: int = 2, noise: float = 0.055,
                    seed: int = 0, config: PathTaskConfig | None = None, workers: int = 1) -> dict[str, np.ndarray]:
    """Observations (M, obs_dim) and clean oracle actions (M, 28) of ``starts`` rollouts (see the module doc),
    plus ``clip`` / ``time`` (M,) of each sample, ``ahead_s`` (M,): how long the body stayed up after the sample
    (``inf`` if it did not fall within the rollout; see :func:`viable_pairs`), and ``up_s`` (starts,): how long
    each body stayed up.

    The rollouts run in batches of :data:`BATCH` bodies, each batch with its own noise stream spawned from
    ``seed``, so the pairs are the same for any number of ``workers`` (processes; 1 runs them in this one)."""
    if starts < 1 or not seconds > 0 or lead < 1 or noise < 0 or workers < 1:
        raise ValueError(f"need starts >= 1, seconds > 0, lead >= 1, noise >= 0, workers >= 1; got {starts}, "
                         f"{seconds}, {lead}, {noise}, {workers}")
    cfg = config or PathTaskConfig()
    rng = np.random.default_rng(seed)
    n_clips = len(ref.clip_names())
    clips_all = rng.integers(0, n_clips, starts)
    dur = np.array([ref.duration(int(c)) for c in clips_all])
    t_all = rng.uniform(0.0, 1.0, starts) * np.maximum(dur - 0.2, 0.0)
    steps = int(round(seconds * cfg.control_hz))
    batches = [np.arange(b0, min(starts, b0 + BATCH)) for b0 in range(0, starts, BATCH)]
    seeds = np.random.SeedSequence([seed, 1]).spawn(len(batches))
    jobs = [(clips_all[sel], t_all[sel], dur[sel], steps, lead, noise, sq, cfg) for sel, sq in zip(batches, seeds, strict=True)]
    if workers == 1 or len(jobs) == 1:
        parts = [_rollout_batch(ref, *job) for job in jobs]
    else:
        import multiprocessing as mp
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(min(workers, len(jobs)), mp_context=mp.get_context("spawn"),
                                 initializer=_set_worker_reference, initargs=(ref,)) as pool:
            parts = list(pool.map(_rollout_batch_in_worker, *zip(*jobs, strict=True)))
    return {k: np.concatenate([p[k] for p in parts]) for k in ("obs", "act", "clip", "time", "ahead_s", "up_s")}


def viable_pairs(data: dict[str, np.ndarray], min_ahead_s: float) -> dict[str, np.ndarray]:
    """The pairs after which the oracle's body stayed up at least ``min_ahead_s`` seconds more (all pairs of a body
    that did not fall within its rollout). The oracle has no balance feedback: in the last second before a fall
    its label is still the clip's pose, the wrong action for a body that is falling, and the cloning term would
    teach it exactly in the states clip tracking starts from. ``up_s`` is kept as it is."""
    if not min_ahead_s >= 0:
        raise ValueError(f"min_ahead_s must be >= 0, got {min_ahead_s!r}")
    if "ahead_s" not in data:
        raise ValueError("these pairs carry no 'ahead_s' (made before 2026-11-29's fourth session): make them again")
    keep = data["ahead_s"] >= min_ahead_s
    return {k: (v[keep] if k != "up_s" else v) for k, v in data.items()}


def with_clear_rays(data: dict[str, np.ndarray], obs_dim: int) -> dict[str, np.ndarray]:
    """Pairs for a learner of ``obs_dim`` inputs. Pairs are made without obstacle rays; for an obstacle-aware
    learner (``N_RAYS`` more inputs) the rays are appended as they read with nothing within range (0, see
    :func:`~navzoo.agents.amp.features.obstacle_observation`): the oracle rollouts run 40 m apart on open ground,
    as clip tracking does, where an obstacle-aware policy's rays read exactly that. Any other width is refused."""
    from navzoo.agents.amp.features import N_RAYS

    width = data["obs"].shape[1]
    if width == obs_dim:
        return data
    if width + N_RAYS != obs_dim:
        raise ValueError(f"behaviour-cloning pairs have {width} observation columns; the learner takes {obs_dim} "
                         f"({width} or {width} + {N_RAYS} obstacle rays would fit)")
    return {**data, "obs": np.concatenate([data["obs"], np.zeros((len(data["obs"]), N_RAYS), data["obs"].dtype)], 1)}


def save_data(path: str | Path, data: dict[str, np.ndarray]) -> Path:
    """Write the cloning pairs (``obs``, ``act``, ``clip``, ``time``, and ``ahead_s`` where present) to a compressed
    ``.npz`` (no pickles),
    atomically: an interrupted write leaves no file at ``path``."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".part")  # written whole, then renamed: never a half file under ``path``
    with tmp.open("wb") as f:
        np.savez_compressed(f, **{k: np.asarray(data[k]) for k in ("obs", "act", "clip", "time", "ahead_s") if k in data})
    tmp.replace(path)
    return path


def load_data(path: str | Path) -> dict[str, np.ndarray]:
    """Read cloning pairs written by :func:`save_data`; a file without ``obs`` and ``act`` of matching rows, or with
    non-finite values, is refused with a message naming it."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no behaviour-cloning data at {path}")
    try:
        with np.load(path, allow_pickle=False) as z:
            data = {k: z[k] for k in z.files}
    except (OSError, ValueError) as e:
        raise ValueError(f"{path} is not a behaviour-cloning .npz ({e})") from None
    obs, act = data.get("obs"), data.get("act")
    if obs is None or act is None or obs.ndim != 2 or act.ndim != 2 or len(obs) != len(act) or len(obs) == 0:
        raise ValueError(f"{path} must hold 'obs' (M, D) and 'act' (M, A) arrays with M > 0 matching rows")
    if not (np.isfinite(obs).all() and np.isfinite(act).all()):
        raise ValueError(f"{path} holds non-finite observations or actions")
    return data


def fit_actor(obs: np.ndarray, act: np.ndarray, hidden: tuple[int, ...] = (1024, 512), epochs: int = 30,
              lr: float = 1e-3, batch: int = 512, val_frac: float = 0.1, seed: int = 0, init_log_std: float = -2.9,
              obs_clip: float = 5.0, norm_eps: float = 1e-5, log: Any = print) -> tuple[Any, Any, dict[str, float]]:
    """An :class:`~navzoo.agents.amp.networks.Actor` and a :class:`RunningMeanStd` fitted to (obs, act); returns
    them and ``{"train_mse", "val_mse", "val_mse_zero"}`` (the last: predicting the mean action)."""
    from navzoo.agents.amp.networks import Actor
    from navzoo.agents.amp.normalizer import RunningMeanStd

    if len(obs) != len(act) or len(obs) < 10:
        raise ValueError(f"need matching obs and act with at least 10 rows, got {len(obs)} and {len(act)}")
    gen = torch.Generator().manual_seed(seed)
    norm = RunningMeanStd(obs.shape[1], norm_eps, obs_clip)
    norm.update(torch.as_tensor(obs, dtype=torch.float64))
    x = norm.normalize(torch.as_tensor(obs, dtype=torch.float32)).float()
    y = torch.as_tensor(act, dtype=torch.float32)
    perm = torch.randperm(len(x), generator=gen)
    n_val = max(1, int(len(x) * val_frac))
    val, tr = perm[:n_val], perm[n_val:]
    actor = Actor(obs.shape[1], act.shape[1], hidden, "relu", init_log_std, False, gen)
    opt = torch.optim.Adam([p for p in actor.parameters() if p.requires_grad], lr=lr)
    sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(1, epochs))
    train_mse = float("nan")
    for ep in range(epochs):
        order = tr[torch.randperm(len(tr), generator=gen)]
        total = 0.0
        for i in range(0, len(order), batch):
            mb = order[i : i + batch]
            loss = (actor(x[mb]) - y[mb]).square().mean()
            opt.zero_grad()
            loss.backward()
            opt.step()
            total += float(loss.detach()) * len(mb)
        sched.step()
        train_mse = total / len(tr)
        with torch.no_grad():
            val_mse = float((actor(x[val]) - y[val]).square().mean())
        if log and (ep % 5 == 0 or ep == epochs - 1):
            log(f"epoch {ep + 1}/{epochs}: train mse {train_mse:.5f}, val mse {val_mse:.5f}")
    with torch.no_grad():
        val_mse = float((actor(x[val]) - y[val]).square().mean())
        zero = float((y[tr].mean(0) - y[val]).square().mean())
    return actor, norm, {"train_mse": train_mse, "val_mse": val_mse, "val_mse_zero": zero}


def write_run(out: str | Path, actor: Any, norm: Any, learner_kw: dict[str, Any], task: PathTaskConfig,
              reference: ReferenceMotion, seed: int = 0) -> dict[str, str]:
    """Iteration 0 of a ``navzoo train amp`` run in ``out`` (``out/checkpoints``, ``out/policy``): a learner of
    ``AmpConfig(**learner_kw)`` on a small :class:`AmpPathEnv`, with ``actor`` and ``norm`` put in."""
    from navzoo.agents.amp.learner import AmpConfig, AmpLearner
    from navzoo.agents.amp.path_env import AmpPathEnv

    out = Path(out)
    env = AmpPathEnv(4, reference, task, seed=seed)
    try:
        learner = AmpLearner(env, AmpConfig(seed=seed, **learner_kw), device="cpu")
        learner.actor.load_state_dict(actor.state_dict())
        learner.obs_norm.load_state_dict(norm.state_dict())
        ckpt = learner.save_checkpoint(out / "checkpoints")
        policy = learner.export_policy(out / "policy")
    finally:
        env.close()
    return {"checkpoint": str(ckpt), "policy": str(policy)}


def main(argv: list[str] | None = None) -> int:
    from navzoo.agents.amp.train import grounded_locomotion_reference

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", default=None, help="the training run to write (not needed with --pairs-only)")
    ap.add_argument("--starts", type=int, default=4096)
    ap.add_argument("--seconds", type=float, default=1.5)
    ap.add_argument("--lead", type=int, default=2, help="oracle targets: the clip's pose this many control steps ahead")
    ap.add_argument("--noise", type=float, default=0.055, help="action noise of the executed oracle targets")
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--lr", type=float, default=1e-3)
    ap.add_argument("--hidden", default="1024,512")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--stage", type=int, default=1)
    ap.add_argument("--amp-velocity-span", type=int, default=1)
    ap.add_argument("--disc-lr", type=float, default=1e-4)
    ap.add_argument("--disc-grad-penalty", type=float, default=5.0)
    ap.add_argument("--disc-weight-decay", type=float, default=1e-4)
    ap.add_argument("--minibatch-size", type=int, default=1920)
    ap.add_argument("--data-out", default=None, help="also write the cloning pairs to this .npz (for --bc-data of "
                    "navzoo train amp)")
    ap.add_argument("--pairs-only", action="store_true", help="only write the cloning pairs (--data-out), no actor")
    ap.add_argument("--workers", type=int, default=1, help="processes for the oracle rollouts (same pairs for any)")
    ap.add_argument("--min-ahead", type=float, default=0.0, help="keep only the pairs after which the oracle's body "
                    "stayed up at least this many seconds more (viable_pairs; 0 keeps all)")
    a = ap.parse_args(argv)
    if a.pairs_only and not a.data_out:
        ap.error("--pairs-only needs --data-out F.npz")
    if not a.pairs_only and not a.out:
        ap.error("--out DIR is required (or --pairs-only with --data-out)")
    hidden = tuple(int(h) for h in a.hidden.split(","))
    t0 = time.time()
    ref = grounded_locomotion_reference()
    task = PathTaskConfig(stage=a.stage, amp_velocity_span=a.amp_velocity_span)
    try:
        data = oracle_rollouts(ref, a.starts, a.seconds, a.lead, a.noise, a.seed, task, workers=a.workers)
        made = len(data["obs"])
        data = viable_pairs(data, a.min_ahead)
    except ValueError as e:
        ap.exit(2, f"error: {e}\n")
    print(f"{len(data['obs'])} samples from {a.starts} starts; bodies up a median {np.median(data['up_s']):.2f} s "
          f"({time.time() - t0:.0f} s)" + (f"; {made - len(data['obs'])} dropped, made less than {a.min_ahead} s "
                                           f"before a fall" if a.min_ahead > 0 else ""), flush=True)
    if a.data_out:
        print(f"cloning pairs -> {save_data(a.data_out, data)}", flush=True)
    if a.pairs_only:
        return 0
    actor, norm, fit = fit_actor(data["obs"], data["act"], hidden, a.epochs, a.lr, seed=a.seed)
    learner_kw = {"actor_hidden": hidden, "critic_hidden": hidden, "disc_hidden": hidden,
                  "minibatch_size": a.minibatch_size, "disc_lr": a.disc_lr, "disc_grad_penalty": a.disc_grad_penalty,
                  "disc_weight_decay": a.disc_weight_decay}
    paths = write_run(a.out, actor, norm, learner_kw, task, ref, a.seed)
    summary = {"samples": int(len(data["obs"])), "samples_made": made, "starts": a.starts, "median_up_s": float(np.median(data["up_s"])),
               **fit, **paths, "args": vars(a), "wall_s": round(time.time() - t0, 1)}
    Path(a.out, "bc.json").write_text(json.dumps(summary, indent=1))
    print(json.dumps({k: v for k, v in summary.items() if k != "args"}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
