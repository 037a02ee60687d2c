"""Motion realism (navzoo.benchmark.realism) split by the body's speed: which poses make the MMD of a crowd.

The realism of `navzoo eval pedestrians` scores every pose of the standing pedestrians of the following run
against all frames of the reference clips (locomotion). A crowd in jams stands a lot, the clips rarely do, so a
crowd's MMD mixes how well each pose is made with how often the body is slow. This script runs pedestrians like
the following protocol (same scenes, people, social-force targets) and scores the poses in speed bands
(horizontal root speed, m/s), next to the reference's own frames in the same bands:

    python scripts/amp_realism_by_speed.py --source shipped=policies/amp_pedestrian --source kinematic \\
        --scenes lobby:15,square_crossing:10 --seconds 60 --out docs/results/amp_realism_by_speed_vm.json

A source is ``kinematic`` (the walk-cycle replay) or ``LABEL=POLICY_DIR`` (an exported AMP policy). Per source
and band: the share of its poses in the band, and realism_metrics of those poses against the whole reference.
The reference rows score the reference's own frames of each band the same way: what the speed mix alone does.
And per source, where in the body the poses differ from the clips: the posture bias (its mean walking pose minus
the clips' mean walking pose, per keypoint, spine lengths) with the MMD left once every pose is shifted by minus
that bias; and, for (up to 5,000 of) its poses, the nearest reference frame (all 45 coordinates) and the mean
distance of each keypoint to that frame's keypoint (the reference rows: each frame against the nearest frame of
another clip).
With ``--tracking`` each policy is also scored on its own closed-loop tracking of the reference clips (the
paper's protocol over whole clips, poses of the standing body every control step): the poses it makes when the
clips steer it, against those it makes walking the crowd task.
Poses are recorded every ``--pose-every`` control steps (30 Hz) of every standing body, as the protocol does.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from navzoo.agents.amp.tracking import load_motions, track_clips
from navzoo.benchmark import realism
from navzoo.benchmark.pedestrians import _make, body_keypoints, parse_scene_counts

KEYS = ("coverage_k50", "entropy_k50", "coverage_k100", "entropy_k100", "mmd")


def parse_bands(text: str) -> list[float]:
    """Band edges ``a,b,...`` (m/s, increasing, positive) -> [0, a, b, ..., inf]."""
    try:
        edges = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"--bands {text!r}: expected comma-separated speeds in m/s, e.g. 0.3,0.9") from None
    if not edges or any(e <= 0 for e in edges) or any(b <= a for a, b in zip(edges, edges[1:], strict=False)):
        raise SystemExit(f"--bands {text!r}: speeds must be positive and increasing")
    return [0.0, *edges, float("inf")]


def parse_scenes(text: str) -> list[tuple[str, int]]:
    try:
        return parse_scene_counts(text)
    except ValueError as e:
        raise SystemExit(str(e)) from None


def parse_source(text: str) -> tuple[str, str | None]:
    if text == "kinematic":
        return "kinematic", None
    label, sep, path = text.partition("=")
    if not sep or not label or not path:
        raise SystemExit(f"--source {text!r}: give 'kinematic' or LABEL=POLICY_DIR")
    if not Path(path, "config.json").is_file():
        raise SystemExit(f"--source {text!r}: {path} is not an exported AMP policy folder (no config.json)")
    return label, path


def band_labels(bands: list[float]) -> list[str]:
    return [f"{a:g}-{b:g}" if np.isfinite(b) else f">={a:g}" for a, b in zip(bands, bands[1:], strict=False)]


def run_scene(scene: str, n: int, seconds: float, seed: int, policy_dir: str | None,
              pose_every: int) -> tuple[np.ndarray, np.ndarray]:
    """Normalised poses (M, 45) and horizontal root speeds (M,) of the standing pedestrians of one scene."""
    human_model = "kinematic" if policy_dir is None else "amp"
    wrapped, env = _make(scene, n, human_model, seconds, seed, policy_dir)
    ids = env.amp.ids if env.amp is not None else env.humans.ids
    h = np.arange(env.n_robots, env.n_total)
    poses, speeds = [], []
    steps = 0
    while not env._needs_reset:
        wrapped.step({})
        steps += 1
        if steps % pose_every:
            continue
        standing = ~env.human_fallen if env.amp is not None else np.ones(n, dtype=bool)
        if not standing.any():
            continue
        j = np.flatnonzero(standing)
        poses.append(realism.normalize_poses(body_keypoints(env.client, [ids[k] for k in j])))
        speeds.append(np.linalg.norm(env.vel[h][j], axis=1))
    wrapped.close()
    if not poses:
        return np.zeros((0, realism.POSE_DIM)), np.zeros(0)
    return np.concatenate(poses), np.concatenate(speeds)


def reference_speeds(lib, fps: float = realism.DEFAULT_FPS) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The reference's poses (as realism.clip_poses), each frame's horizontal root speed
    (realism.clip_root_speeds) and its clip index."""
    poses, cid = realism.clip_poses(lib, fps=fps, return_clip_ids=True)
    return poses, realism.clip_root_speeds(lib, fps), cid


def score(poses: np.ndarray, speeds: np.ndarray, bands: list[float], ref) -> dict:
    """Per band (and all poses): share of the poses, count, and the realism metrics of KEYS."""
    out = {"all": {"share": 1.0, "n": int(len(poses)),
                   **{k: v for k, v in realism.realism_metrics(poses, ref).items() if k in KEYS}}}
    for label, a, b in zip(band_labels(bands), bands, bands[1:], strict=False):
        sel = (speeds >= a) & (speeds < b)
        row = {"share": float(sel.mean()) if len(sel) else 0.0, "n": int(sel.sum())}
        if sel.sum() >= 100:  # fewer poses than that give no meaningful coverage or MMD
            row |= {k: v for k, v in realism.realism_metrics(poses[sel], ref).items() if k in KEYS}
        out[label] = row
    return out


def keypoint_residuals(poses: np.ndarray, ref_poses: np.ndarray, rng: np.random.Generator,
                       exclude_same: np.ndarray | None = None, ref_ids: np.ndarray | None = None,
                       max_poses: int = 5000) -> dict[str, float]:
    """Mean distance (spine lengths) of each keypoint to the same keypoint of the pose's nearest reference
    frame (nearest over all 45 coordinates). ``exclude_same`` (M,) with ``ref_ids``: clip ids of ``poses``
    and of the reference frames; a pose is then matched only to frames of other clips."""
    idx = rng.choice(len(poses), size=min(max_poses, len(poses)), replace=False)
    x = poses[idx]
    rr = (ref_poses * ref_poses).sum(1)
    nearest = np.empty(len(x), dtype=np.int64)
    for i in range(0, len(x), 1024):  # squared distances by matrix products, 1024 poses at a time
        xi = x[i:i + 1024]
        d = (xi * xi).sum(1)[:, None] + rr[None, :] - 2.0 * (xi @ ref_poses.T)
        if exclude_same is not None:
            d[exclude_same[idx[i:i + 1024]][:, None] == ref_ids[None, :]] = np.inf
        nearest[i:i + 1024] = d.argmin(1)
    near = ref_poses[nearest]
    diff = (x - near).reshape(len(x), realism.N_KEYPOINTS, 3)
    res = np.linalg.norm(diff, axis=2).mean(0)
    return {name: float(v) for name, v in zip(realism.KEYPOINT_NAMES, res, strict=True)}


def posture(poses: np.ndarray, speeds: np.ndarray, ref_poses: np.ndarray, ref_speeds: np.ndarray, ref,
            walk: float) -> dict:
    """A posture bias: the mean walking pose (speed >= ``walk``) minus the reference's mean walking pose, per
    keypoint (x forward, y left, z up, spine lengths), and the MMD of all poses once each is shifted by
    minus that bias (what is left of the MMD without it)."""
    mine, theirs = poses[speeds >= walk], ref_poses[ref_speeds >= walk]
    if len(mine) < 100:
        return {}
    bias = mine.mean(0) - theirs.mean(0)
    shifted = realism.realism_metrics(poses - bias, ref)["mmd"]
    per_kp = bias.reshape(realism.N_KEYPOINTS, 3)
    return {"mmd_bias_removed": float(shifted),
            "bias": {k: [float(v) for v in per_kp[i]] for i, k in enumerate(realism.KEYPOINT_NAMES)}}


def table(result: dict) -> str:
    labels = ["all", *band_labels([0.0, *result["bands"], float("inf")])]
    lines = ["| source | band (m/s) | share of poses | coverage / entropy K=50 | coverage / entropy K=100 | MMD |",
             "|---|---|---|---|---|---|"]
    for name, per in result["sources"].items():
        for lab in labels:
            r = per[lab]
            if "mmd" in r:
                lines.append(f"| {name} | {lab} | {r['share']:.2f} | {r['coverage_k50']:.2f} / {r['entropy_k50']:.2f} | "
                             f"{r['coverage_k100']:.2f} / {r['entropy_k100']:.2f} | {r['mmd']:.3f} |")
            else:
                lines.append(f"| {name} | {lab} | {r['share']:.2f} | (fewer than 100 poses) | | |")
    lines.append(f"| reference split-half MMD floor | | | | | {result['reference_mmd_floor']:.3f} |")
    names = list(result["sources"])
    lines += ["", "| keypoint: distance to the nearest reference frame (spine lengths) | " + " | ".join(names) + " |",
              "|---" * (len(names) + 1) + "|"]
    for k in realism.KEYPOINT_NAMES:
        lines.append(f"| {k} | " + " | ".join(f"{result['keypoints'][n][k]:.3f}" for n in names) + " |")
    bi = [n for n in names if result["posture"].get(n)]
    lines += ["", "| keypoint: mean walking pose minus the clips' (x fwd, y left, z up; spine lengths) | "
              + " | ".join(bi) + " |", "|---" * (len(bi) + 1) + "|"]
    for k in realism.KEYPOINT_NAMES[1:]:
        lines.append(f"| {k} | " + " | ".join("{:+.2f} {:+.2f} {:+.2f}".format(*result["posture"][n]["bias"][k])
                                             for n in bi) + " |")
    lines.append("| MMD with the bias removed (all poses) | "
                 + " | ".join(f"{result['posture'][n]['mmd_bias_removed']:.3f}" for n in bi) + " |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--source", action="append", required=True, help="'kinematic' or LABEL=POLICY_DIR (repeat)")
    ap.add_argument("--scenes", default="lobby:15,square_crossing:10", help="SCENE:PEOPLE,... (default %(default)s)")
    ap.add_argument("--seconds", type=float, default=60.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--pose-every", type=int, default=3, help="record poses every N control steps (default 3)")
    ap.add_argument("--bands", default="0.3,0.9", help="speed band edges in m/s (default %(default)s)")
    ap.add_argument("--motions", default=None, help="reference clips folder (default: packaged locomotion)")
    ap.add_argument("--walk", type=float, default=0.9, help="walking speed (m/s) for the posture bias (default 0.9)")
    ap.add_argument("--tracking", action="store_true",
                    help="also score each policy's closed-loop tracking of the reference clips (whole clips)")
    ap.add_argument("--out", default=None, help="write the JSON result here")
    args = ap.parse_args(argv)
    if args.seconds <= 0 or args.pose_every < 1:
        raise SystemExit("--seconds must be positive and --pose-every at least 1")
    bands = parse_bands(args.bands)
    scenes = parse_scenes(args.scenes)
    sources = [parse_source(s) for s in args.source]
    if len({s[0] for s in sources}) != len(sources):
        raise SystemExit("--source labels must be distinct")

    lib = load_motions(args.motions)
    ref_poses, ref_speeds, ref_ids = reference_speeds(lib)
    ref = realism.RealismReference.fit(ref_poses, seed=args.seed)
    result = {"scenes": [f"{s}:{n}" for s, n in scenes], "seconds": args.seconds, "seed": args.seed,
              "pose_every": args.pose_every, "tracking": bool(args.tracking), "bands": bands[1:-1], "reference_mmd_floor": ref.mmd_floor,
              "sources": {"reference clips": score(ref_poses, ref_speeds, bands, ref)},
              "keypoints": {"reference clips": keypoint_residuals(ref_poses, ref_poses, np.random.default_rng(args.seed),
                                                                  exclude_same=ref_ids, ref_ids=ref_ids)},
              "posture": {}}
    for label, policy in sources:
        t0 = time.time()
        runs = [run_scene(s, n, args.seconds, args.seed, policy, args.pose_every) for s, n in scenes]
        poses = np.concatenate([p for p, _ in runs])
        speeds = np.concatenate([v for _, v in runs])
        if len(poses) == 0:
            raise SystemExit(f"{label}: no standing poses were recorded")
        result["sources"][label] = score(poses, speeds, bands, ref)
        result["keypoints"][label] = keypoint_residuals(poses, ref_poses, np.random.default_rng(args.seed))
        result["posture"][label] = posture(poses, speeds, ref_poses, ref_speeds, ref, args.walk)
        print(f"{label}: {len(poses)} poses in {time.time() - t0:.0f} s", file=sys.stderr, flush=True)
        if args.tracking and policy is not None:
            sink: list = []
            track_clips(policy, lib, stop_on_failure=False, pose_sink=sink)
            poses = np.concatenate([p for p, _ in sink])
            speeds = np.concatenate([v for _, v in sink])
            name = f"{label} (clip tracking)"
            result["sources"][name] = score(poses[::args.pose_every], speeds[::args.pose_every], bands, ref)
            result["keypoints"][name] = keypoint_residuals(poses, ref_poses, np.random.default_rng(args.seed))
            result["posture"][name] = posture(poses, speeds, ref_poses, ref_speeds, ref, args.walk)
    print(table(result))
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(result, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
