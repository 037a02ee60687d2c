"""Train the AMP pedestrian controller: ``navzoo train amp`` / ``python -m navzoo.agents.amp.train``.

Reads top to bottom: arguments, the reference clips, the vector env (worker processes of PyBullet
humanoids following generated paths), the AMP + PPO learner, then the resumable training loop, which
checkpoints into ``<out>/checkpoints`` and logs to ``<out>/tb`` and ``<out>/metrics.jsonl``. Running
the same command again resumes from the latest checkpoint; Ctrl-C checkpoints before it exits.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig

# Navigation locomotion for the style prior: walks, turns, veers, curves, starts and stops (no runs,
# hops or clips with uneven feet), mirrored copies included.
LOCOMOTION_TAGS = ("walk", "walk_slow", "walk_fast", "turn90_left", "turn90_right", "veer_left", "veer_right",
                   "curve_left", "curve_right", "stop", "start", "restart", "sidestep_left", "sidestep_right")
EXCLUDE_TAGS = ("run", "hop", "uneven_feet", "walk_to_run")


def locomotion_reference():
    """The packaged motion library restricted to navigation locomotion (module-level: picklable)."""
    from navzoo.agents.motion_lib import MotionLibrary

    return MotionLibrary.load().select(tags=LOCOMOTION_TAGS, exclude_tags=EXCLUDE_TAGS)


def grounded_locomotion_reference():
    """:func:`locomotion_reference` with every clip's feet put on the physics ground
    (:func:`navzoo.agents.amp.path_env.ground_clips`): the training reference (module-level: picklable)."""
    from navzoo.agents.amp.path_env import ground_clips

    return ground_clips(locomotion_reference())


@dataclass
class TrainArgs:
    out: str = "runs/amp"
    total_steps: int = 20_000_000
    workers: int = 1
    envs_per_worker: int = 16
    stage: int = 1
    device: str = "cpu"
    seed: int = 0
    hidden: str = "512,256"
    rollout_steps: int = 16
    minibatch_size: int = 2048
    ckpt_every: int = 10
    ckpt_replay_rows: int = 10_000
    time_limit_s: float | None = None
    pd_mode: str = "motor"
    obstacles: int = 0  # 1: obstacle rays in the observation, boxes and paired humanoids in each patch
    # stage 3 with obstacles: share of patches split by a wall with one door (PathTaskConfig.door_prob)
    door_prob: float = 0.0
    # 1: stage-3 replans of all humanoids of a worker on the same steps (PathTaskConfig.replan_sync, since run
    # 21); 0: each humanoid 2 s after its own last plan (runs 1-20)
    replan_sync: int = 1
    # discriminator inputs (see PathTaskConfig.amp_velocity and path_env.ground_clips); a change of either
    # invalidates a checkpoint's discriminator: resume it with --reset-disc 1
    amp_velocity: str = "finite_difference"
    # finite-difference velocities over this many control steps (PathTaskConfig.amp_velocity_span; 1 up to
    # 2026-11-27); another span than the checkpoint's also needs --reset-disc 1
    amp_velocity_span: int = 1
    ground_reference: int = 1
    # 1: on resume, keep actor, critic, observation and value normalisers and their optimisers, but start a
    # fresh discriminator (weights, optimiser, input normaliser, replay buffer)
    reset_disc: int = 0
    # 1: resume a checkpoint made with another number of envs (workers x envs per worker), e.g. a run of 60
    # workers on a 64-core host going on with 15 on a 16-core one; everything but the envs' own state is restored
    # and the episodes start afresh (AmpLearner.load_checkpoint's any_num_envs)
    any_num_envs: int = 0
    # discriminator hyper-parameters (AmpConfig; a resumed checkpoint takes the values given here)
    disc_lr: float = 1e-4
    disc_grad_penalty: float = 5.0
    disc_logit_reg: float = 0.05
    disc_weight_decay: float = 1e-4
    # weight of the mirror-symmetry loss on the actor (AmpConfig.mirror_coef; 0 = off)
    mirror_coef: float = 0.0
    # weight of the stance term in the task reward (PathTaskConfig.stance_reward; 0 = the paper's reward); the
    # training log's env/stance_split_m shows the stance whatever the weight
    stance_reward: float = 0.0
    # weight of the task reward next to the style reward (AmpConfig.task_weight; the paper's r = r_amp + 0.5 r_task)
    # and the actor's learning rate (AmpConfig.actor_lr); a resumed checkpoint takes the values given here
    task_weight: float = 0.5
    actor_lr: float = 5e-5
    # log of the fixed action-noise std (AmpConfig.init_log_std; a resumed checkpoint takes the value given here).
    # The position motors follow a new target within a physics substep, so this noise shows up as joint-velocity
    # jitter that the discriminator reads (docs/pedestrians_log.md, "What the discriminator reads").
    init_log_std: float = -2.9
    # > 0: export the deterministic policy to <out>/snapshots/policy_<iteration> every that many iterations and
    # at the start, for checkpoint selection on the following protocol (scripts/amp_select_snapshots.py)
    snapshot_every: int = 0
    # training checkpoints kept in <out>/checkpoints (AmpConfig.keep_checkpoints); keep more to resume from a
    # snapshot's iteration (with --ckpt-every dividing --snapshot-every)
    keep_checkpoints: int = 3
    # the actor is not updated before this iteration (AmpConfig.actor_warmup_iters): a fresh critic learns the values
    # of an actor that starts from behaviour cloning (navzoo.agents.amp.bc) before the actor moves
    actor_warmup_iters: int = 0
    # behaviour-cloning term on the actor (AmpConfig.bc_coef) and its pairs: an .npz with "obs" and "act" written by
    # python -m navzoo.agents.amp.bc --data-out F (the observations must be this task's)
    bc_coef: float = 0.0
    bc_data: str = ""
    # recorded crowd targets (PathTaskConfig.recorded_targets / recorded_prob): an .npz of
    # scripts/amp_target_replay.py --save-targets (several, comma-separated, are pooled), walked in that share of the
    # episodes instead of generated paths
    recorded_targets: str = ""
    recorded_prob: float = 0.0
    # > 0: recorded targets wait for the body, at most this many seconds ahead (PathTaskConfig.recorded_lag_s; the
    # scenes hold targets 0.3 s ahead)
    recorded_lag_s: float = 0.0


def add_arguments(parser: argparse.ArgumentParser) -> None:
    for f in dataclasses.fields(TrainArgs):
        default = f.default
        kind = {"int": int, "float": float, "str": str}.get(str(f.type).split(" ")[0], str)
        if f.name == "time_limit_s":
            kind = float
        parser.add_argument(f"--{f.name.replace('_', '-')}", dest=f.name, type=kind, default=default)
    parser.add_argument("--json", action="store_true", help="print the final summary as JSON")


def run(args: TrainArgs) -> dict[str, Any]:
    import torch

    from navzoo.agents.amp.learner import AmpConfig, AmpLearner
    from navzoo.agents.amp.vec import SubprocAmpVecEnv

    if args.door_prob and not (args.stage == 3 and args.obstacles):
        raise ValueError(f"--door-prob {args.door_prob} needs --stage 3 --obstacles 1 (walls are stage-3 "
                         f"obstacles the policy must see), got --stage {args.stage} --obstacles {args.obstacles}")
    if args.bc_coef > 0 and not args.bc_data:
        raise ValueError(f"--bc-coef {args.bc_coef} needs --bc-data F.npz (python -m navzoo.agents.amp.bc --data-out F)")
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    hidden = tuple(int(h) for h in args.hidden.split(","))
    task = PathTaskConfig(stage=args.stage, pd_mode=args.pd_mode, obstacle_obs=bool(args.obstacles),
                          boxes_per_patch=4 if args.obstacles else 0, pair_patches=bool(args.obstacles),
                          amp_velocity=args.amp_velocity, amp_velocity_span=args.amp_velocity_span,
                          door_prob=args.door_prob, stance_reward=args.stance_reward,
                          replan_sync=bool(args.replan_sync), recorded_targets=args.recorded_targets or None,
                          recorded_prob=args.recorded_prob, recorded_lag_s=args.recorded_lag_s)
    if task.recorded_prob > 0:
        from navzoo.agents.amp.path_env import load_recorded_targets

        load_recorded_targets(task.recorded_targets, task.control_hz)  # a bad file is named before any worker starts
    make_reference = grounded_locomotion_reference if args.ground_reference else locomotion_reference
    if args.workers > 1:
        env: Any = SubprocAmpVecEnv(make_reference, args.workers, args.envs_per_worker, task, seed=args.seed)
    else:
        env = AmpPathEnv(args.envs_per_worker, make_reference(), task, seed=args.seed)
    config = AmpConfig(seed=args.seed, actor_hidden=hidden, critic_hidden=hidden, disc_hidden=hidden,
                       rollout_steps=args.rollout_steps, minibatch_size=args.minibatch_size,
                       ckpt_replay_rows=args.ckpt_replay_rows, disc_lr=args.disc_lr,
                       disc_grad_penalty=args.disc_grad_penalty, disc_logit_reg=args.disc_logit_reg,
                       disc_weight_decay=args.disc_weight_decay, mirror_coef=args.mirror_coef,
                       init_log_std=args.init_log_std, keep_checkpoints=args.keep_checkpoints,
                       task_weight=args.task_weight, actor_lr=args.actor_lr,
                       actor_warmup_iters=args.actor_warmup_iters, bc_coef=args.bc_coef)
    device = args.device if args.device != "cuda" or torch.cuda.is_available() else "cpu"
    (out / "train_args.json").write_text(json.dumps({**dataclasses.asdict(args), "task": dataclasses.asdict(task),
                                                     "learner": config.to_dict()}, indent=2, default=str))
    t0 = time.time()
    try:
        learner = AmpLearner(env, config, device=device)
        if args.bc_data:
            from navzoo.agents.amp.bc import load_data, with_clear_rays

            pairs = with_clear_rays(load_data(args.bc_data), learner.obs_dim)  # a learner with rays: open ground
            learner.set_bc_data(pairs["obs"], pairs["act"])
        result = learner.train(args.total_steps, log_dir=out, ckpt_dir=out / "checkpoints", ckpt_every=args.ckpt_every,
                               verbose=True, time_limit_s=args.time_limit_s, reset_disc=bool(args.reset_disc),
                               any_num_envs=bool(args.any_num_envs),
                               snapshot_dir=out / "snapshots", snapshot_every=args.snapshot_every)
    finally:
        env.close()
    result = {**result, "wall_s": time.time() - t0, "out": str(out)}
    learner.export_policy(out / "policy")
    return result


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    add_arguments(parser)
    ns = parser.parse_args(argv)
    as_json = ns.json
    args = TrainArgs(**{f.name: getattr(ns, f.name) for f in dataclasses.fields(TrainArgs)})
    result = run(args)
    print(json.dumps(result, default=str) if as_json else result)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())


def export_from_checkpoint(ckpt_dir: str | Path, out: str | Path) -> Path:
    """Write the deterministic policy (actor + observation normaliser) of a training checkpoint.

    Unlike :meth:`AmpLearner.load_checkpoint`, this needs no env of the checkpoint's size: the policy
    of a 240-env device run can be exported and evaluated on a laptop.
    """
    from navzoo.agents.amp import checkpoint as ckpt
    from navzoo.agents.amp.learner import AmpConfig
    from navzoo.agents.amp.networks import Actor
    from navzoo.agents.amp.normalizer import RunningMeanStd

    tensors, meta = ckpt.load_checkpoint(ckpt_dir)
    cfg = AmpConfig.from_dict(meta["config"])
    dims = meta["dims"]
    actor = Actor(dims["obs_dim"], dims["act_dim"], cfg.actor_hidden, cfg.activation, cfg.init_log_std, cfg.learn_std)
    actor.load_state_dict(tensors["actor"])
    obs_norm = RunningMeanStd(dims["obs_dim"], cfg.norm_eps, cfg.obs_clip)
    obs_norm.load_state_dict(tensors["obs_norm"])
    return ckpt.export_policy_files(out, actor, obs_norm, {
        "obs_dim": dims["obs_dim"], "act_dim": dims["act_dim"], "actor_hidden": list(cfg.actor_hidden),
        "activation": cfg.activation, "action_low": -1.0, "action_high": 1.0,
        "trained_iterations": int(meta["iteration"]), "trained_steps": int(meta["counters"].get("global_step", 0)),
    })
