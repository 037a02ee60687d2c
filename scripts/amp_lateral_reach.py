"""How far the hands and feet of AMP pedestrians reach sideways, by walking speed, against the reference clips.

Most wall-contact events of the physics pedestrians begin with the body nearly still, a hand's or a foot's swing
from an obstacle (docs/pedestrians_log.md, "Where the bodies touch the walls"). This script asks whether the
controller's limbs reach further sideways than people's do at the same speed. For every sample it takes, in the
body's heading frame, the largest sideways offset of the two hands and of the two feet from the pelvis (links'
centres of mass, ``features.KEY_BODY_NAMES``), and pools the samples in speed bands of the pelvis's planar speed:

    python scripts/amp_lateral_reach.py --scenes lobby:15,square_crossing:10,corridor:12,home:5 --seconds 60 \\
        --seed 0 --out F.json

Rows: the shipped policy (or ``--policy DIR``) walking the following protocol's scenes on social-force targets
(standing bodies after their first second, sampled every env step), and the navigation-locomotion clips the
controller was trained on (``navzoo.agents.amp.train.locomotion_reference``, every frame after each clip's
first 0.2 s, speed from the root's finite differences over 0.2 s). Per band: samples, and the median and 95th
percentile of the hand and foot reach (m).
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from navzoo.agents.amp.features import KEY_BODY_NAMES, heading
from navzoo.benchmark.pedestrians import parse_scene_counts

BANDS = ((0.0, 0.3), (0.3, 0.8), (0.8, 9.0))  # m/s
HANDS = [KEY_BODY_NAMES.index("right_hand"), KEY_BODY_NAMES.index("left_hand")]
FEET = [KEY_BODY_NAMES.index("right_foot"), KEY_BODY_NAMES.index("left_foot")]
SPEED_WINDOW_S = 0.2


def sideways(root_pos: np.ndarray, root_quat: np.ndarray, key_pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(N,) largest |sideways offset| of the hands and of the feet from the pelvis, in the heading frame (m)."""
    h = heading(root_quat)
    left = np.stack([-np.sin(h), np.cos(h)], axis=1)  # (N, 2) the heading frame's y axis
    rel = key_pos[:, :, :2] - root_pos[:, None, :2]
    lat = np.abs(np.einsum("nkd,nd->nk", rel, left))
    return lat[:, HANDS].max(axis=1), lat[:, FEET].max(axis=1)


def summarise(speed: np.ndarray, hand: np.ndarray, foot: np.ndarray) -> dict[str, dict]:
    out = {}
    for lo, hi in BANDS:
        sel = (speed >= lo) & (speed < hi)
        key = f"{lo:g}-{hi:g}" if hi < 9.0 else f">={lo:g}"
        if not sel.any():
            out[key] = {"n": 0}
            continue
        out[key] = {"n": int(sel.sum()),
                    "hand_median_m": round(float(np.median(hand[sel])), 3),
                    "hand_p95_m": round(float(np.quantile(hand[sel], 0.95)), 3),
                    "foot_median_m": round(float(np.median(foot[sel])), 3),
                    "foot_p95_m": round(float(np.quantile(foot[sel], 0.95)), 3)}
    return out


def clip_samples() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed, hand reach and foot reach of every frame of the locomotion clips (after each clip's first 0.2 s)."""
    from navzoo.agents.amp.features import KEY_LINKS
    from navzoo.agents.amp.train import locomotion_reference
    from navzoo.agents.motion_lib import humanoid_fk

    lib = locomotion_reference()
    back = max(1, int(round(SPEED_WINDOW_S * lib.fps)))
    speed, hand, foot = [], [], []
    for c in range(len(lib)):
        fr = lib.frames(c)
        if len(fr["root_pos"]) <= back:
            continue
        pos, _ = humanoid_fk(fr["root_pos"], fr["root_quat"], fr["sph"], fr["rev"])
        hd, ft = sideways(fr["root_pos"], fr["root_quat"], pos[:, list(KEY_LINKS)])
        moved = np.linalg.norm(fr["root_pos"][back:, :2] - fr["root_pos"][:-back, :2], axis=1)
        speed.append(moved * lib.fps / back)
        hand.append(hd[back:])
        foot.append(ft[back:])
    return np.concatenate(speed), np.concatenate(hand), np.concatenate(foot)


def scene_samples(scene: str, n: int, seconds: float, seed: int, policy_dir: str | None,
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Speed, hand reach and foot reach of the standing bodies of one following run (after its first second)."""
    from navzoo.benchmark.pedestrians import _make
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread():
        wrapped, env = _make(scene, n, "amp", seconds, seed, policy_dir)
        speed, hand, foot = [], [], []
        while not env._needs_reset:
            wrapped.step({})
            if env.sim_time < 1.0:
                continue
            s = env.amp.state()
            keep = ~env.human_fallen
            hd, ft = sideways(s["root_pos"], s["root_quat"], s["key_pos"])
            speed.append(np.linalg.norm(s["root_lin_vel"][:, :2], axis=1)[keep])
            hand.append(hd[keep])
            foot.append(ft[keep])
        wrapped.close()
    return np.concatenate(speed), np.concatenate(hand), np.concatenate(foot)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scenes", default="lobby:15,square_crossing:10,corridor:12,home:5", help="scene:pedestrians,...")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--policy", default=None, help="exported policy directory (default: the shipped one)")
    ap.add_argument("--out", default=None)
    args = ap.parse_args(argv)
    try:
        scenes = parse_scene_counts(args.scenes)
    except ValueError as e:
        ap.error(str(e))
    if args.seconds <= 1.0:
        ap.error(f"--seconds must be > 1 (the first second is skipped), got {args.seconds}")
    if args.policy is not None and not Path(args.policy, "config.json").is_file():
        ap.error(f"--policy {args.policy!r}: no exported policy (config.json) there")
    out: dict = {"command": "python scripts/amp_lateral_reach.py " + " ".join(argv if argv is not None else sys.argv[1:]),
                 "clips": summarise(*clip_samples())}
    print(f"clips: {json.dumps(out['clips'])}", flush=True)
    t0 = time.time()
    per = {name: scene_samples(name, n, args.seconds, args.seed, args.policy) for name, n in scenes}
    pooled = [np.concatenate([v[i] for v in per.values()]) for i in range(3)]
    out["policy"] = {"dir": args.policy or "shipped", "all": summarise(*pooled),
                     "by_scene": {name: summarise(*v) for name, v in per.items()}, "wall_s": round(time.time() - t0, 1)}
    print(f"policy: {json.dumps(out['policy']['all'])} in {out['policy']['wall_s']} s", flush=True)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(out, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
