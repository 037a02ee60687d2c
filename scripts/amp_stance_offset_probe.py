"""Probe: is the split stance of a trained AMP policy a constant offset of its leg actions?

Both trained lineages walk with one foot ahead of the pelvis and the other behind on average (docs/pedestrians.md,
"Where the realism gap lies"). If that were a constant bias of the policy's hip and knee PD targets, subtracting
it at inference would square the stance, as the steering trim squares the heading. This probe measures the bias
(the policy's mean action over closed-loop tracking of the reference clips, minus the clips' own mean action,
`targets_to_actions` of their joint rotations) and tracks the clips again with ALPHA times it subtracted from the
chosen joints' actions, for each ALPHA: clips tracked, falls over whole clips, body error, the feet's mean
forward offset (spine lengths, as scripts/amp_realism_by_speed.py) and the realism MMD of the tracking poses.

    python scripts/amp_stance_offset_probe.py policies/amp_pedestrian --alphas 0,0.5,1 --joints hips,knees \\
        --out docs/results/amp_stance_offset_probe_vm.json

Inference only: the weights are not changed. About 25 s per ALPHA on the 2-core VM.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

from navzoo.agents.amp import tracking
from navzoo.agents.amp.checkpoint import load_policy
from navzoo.agents.amp.sim import targets_to_actions
from navzoo.benchmark import realism

#: action columns of each joint group (SPH order: chest, neck, r_hip, r_ankle, r_shoulder, l_hip, l_ankle,
#: l_shoulder, 3 exp-map components each; then REV: r_knee, r_elbow, l_knee, l_elbow)
GROUPS = {"hips": [6, 7, 8, 15, 16, 17], "knees": [24, 26], "ankles": [9, 10, 11, 18, 19, 20],
          "shoulders": [12, 13, 14, 21, 22, 23], "elbows": [25, 27]}
FEET = (realism.KEYPOINT_NAMES.index("right_foot"), realism.KEYPOINT_NAMES.index("left_foot"))


class OffsetPolicy:
    """A loaded policy whose (clipped) actions get ``offset`` added; records the actions it returns."""

    def __init__(self, policy, offset: np.ndarray):
        self._policy, self._offset, self.actions = policy, offset, []

    def __getattr__(self, name):
        return getattr(self._policy, name)

    def __call__(self, obs):
        a = np.clip(np.asarray(self._policy(obs), dtype=np.float64), -1.0, 1.0) + self._offset
        self.actions.append(np.clip(a, -1.0, 1.0))
        return a


def reference_mean_action(lib) -> np.ndarray:
    """The clips' mean action: their joint rotations as PD targets (every frame at 30 Hz)."""
    cid, ts = [], []
    for c in range(len(lib)):
        t = realism.clip_times(lib, c)
        cid.append(np.full(t.shape, c))
        ts.append(t)
    st = lib.state_at(np.concatenate(cid), np.concatenate(ts))
    return np.clip(targets_to_actions(st.sph, st.rev), -1.0, 1.0).mean(0)


def track(policy_dir: str, lib, offset: np.ndarray, ref: realism.RealismReference, ref_mean_pose: np.ndarray):
    wrapped = OffsetPolicy(load_policy(policy_dir), offset)
    sink: list = []
    res = tracking.track_clips(wrapped, lib, stop_on_failure=False, pose_sink=sink)
    poses = np.concatenate([p for p, _ in sink])
    speeds = np.concatenate([v for _, v in sink])
    walk = poses[speeds >= 0.9]
    bias = (walk.mean(0) - ref_mean_pose).reshape(realism.N_KEYPOINTS, 3) if len(walk) else np.full((15, 3), np.nan)
    return {
        "clip_success_rate": res["clip_success_rate"], "fall_rate": res["fall_rate"],
        "mean_pos_error_m": res["mean_pos_error_m"], "mean_rot_error_rad": res["mean_rot_error_rad"],
        "mean_pose_rot_error_rad": res["mean_pose_rot_error_rad"],
        "right_foot_forward": float(bias[FEET[0], 0]), "left_foot_forward": float(bias[FEET[1], 0]),
        "mmd": realism.realism_metrics(poses, ref)["mmd"],
    }, np.concatenate(wrapped.actions).mean(0)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("policy_dir")
    ap.add_argument("--alphas", default="0,0.5,1", help="fractions of the bias to subtract (default %(default)s)")
    ap.add_argument("--joints", default="hips,knees", help=f"joint groups, of {','.join(GROUPS)} (default %(default)s)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    try:
        alphas = [float(x) for x in args.alphas.split(",")]
    except ValueError:
        raise SystemExit(f"--alphas {args.alphas!r}: expected comma-separated numbers") from None
    unknown = [g for g in args.joints.split(",") if g not in GROUPS]
    if unknown:
        raise SystemExit(f"--joints: unknown group(s) {unknown}; choose from {', '.join(GROUPS)}")
    cols = sorted({c for g in args.joints.split(",") for c in GROUPS[g]})

    lib = tracking.load_motions(None)
    ref_poses = realism.clip_poses(lib)
    ref = realism.RealismReference.fit(ref_poses, seed=0)
    # the clips' mean walking pose, as amp_realism_by_speed.py (frames at 0.9 m/s and more)
    ref_mean_pose = ref_poses[realism.clip_root_speeds(lib) >= 0.9].mean(0)

    a_ref = reference_mean_action(lib)
    row0, a_pol = track(args.policy_dir, lib, np.zeros(28), ref, ref_mean_pose)
    bias = np.zeros(28)
    bias[cols] = (a_pol - a_ref)[cols]
    out = {"policy": args.policy_dir, "joints": args.joints, "bias": bias.tolist(), "rows": []}
    print(f"action bias (policy - clips) on {args.joints}: " + ", ".join(f"{c}:{bias[c]:+.3f}" for c in cols),
          file=sys.stderr)
    for alpha in alphas:
        row = row0 if alpha == 0 else track(args.policy_dir, lib, -alpha * bias, ref, ref_mean_pose)[0]
        out["rows"].append({"alpha": alpha, **row})
        print(json.dumps({"alpha": alpha, **{k: round(v, 4) for k, v in row.items()}}), flush=True)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
