"""How much rotation error a clip has against itself, shifted in time: what clip tracking's rotation error asks.

Clip tracking (navzoo.agents.amp.tracking, the paper's protocol) compares the simulated body with the clip frame
by frame. A controller that walks the clip's own gait but lags it by ``dt`` seconds would err by what this
script measures: for every training clip (the packaged library's navigation locomotion) and every frame t
with t + dt inside the clip, the rigid-body errors between the clip at t and the clip at t + dt, split as the
tracking splits them (root heading, root tilt, pose: the links relative to their root). Means over frames,
then over clips. No simulation; a few seconds.

    python scripts/amp_rotation_phase_floor.py --json docs/results/amp_rotation_phase_floor.json
"""

from __future__ import annotations

import argparse
import json

import numpy as np

from navzoo.agents.amp.tracking import body_errors, load_motions, rigid_bodies, rotation_parts

KEYS = ("mean_rot_error_rad", "mean_pos_error_root_frame_m", "mean_root_heading_error_rad", "mean_root_tilt_error_rad",
        "mean_pose_rot_error_rad")


def shifted_errors(lib, shift_s: float, fps: float = 30.0) -> dict[str, float]:
    """Means over clips of the per-clip mean errors between each clip and itself ``shift_s`` later."""
    per_clip = []
    for c in range(len(lib.clip_names())):
        t = np.arange(0.0, lib.duration(c) - shift_s, 1.0 / fps)
        if len(t) < 2:
            continue
        clip = np.full(len(t), c)
        a, b = lib.state_at(clip, t), lib.state_at(clip, t + shift_s)
        pa, qa = rigid_bodies(a)
        pb, qb = rigid_bodies(b)
        rot = body_errors(pa, qa, pb, qb)[1]
        # positions relative to the root, without the root's own travel (the pose's share of the position error)
        pos_local = np.linalg.norm((pa - pa[:, :1]) - (pb - pb[:, :1]), axis=-1).mean(axis=-1)
        yaw, tilt, pose = rotation_parts(qa, qb)
        per_clip.append([rot.mean(), pos_local.mean(), yaw.mean(), tilt.mean(), pose.mean()])
    m = np.mean(per_clip, axis=0)
    return {"shift_s": shift_s, "n_clips": len(per_clip), **{k: float(v) for k, v in zip(KEYS, m, strict=True)}}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--shifts", default="0.05,0.1,0.15,0.2,0.3,0.4,0.5,0.6")
    ap.add_argument("--motions", default=None, help="a motion library folder (default: the training clips)")
    ap.add_argument("--json", default=None, help="write the rows to this file")
    a = ap.parse_args(argv)
    lib = load_motions(a.motions)
    rows = [shifted_errors(lib, float(s)) for s in a.shifts.split(",")]
    for r in rows:
        print(json.dumps({k: round(v, 4) if isinstance(v, float) else v for k, v in r.items()}))
    if a.json:
        with open(a.json, "w") as f:
            json.dump(rows, f, indent=1)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
