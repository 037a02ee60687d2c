"""``navzoo eval perception``: how well the robot perceives people, and what it costs.

A robot drives (ORCA, ground truth) through scenes not used to train the Monoloco network
(:data:`navzoo.perception.dataset.EVAL_SCENES`) among an ORCA crowd (the training data used social
force), while :class:`~navzoo.perception.pipeline.RobotPerception` runs on it every step. Measured:

* **localisation**: ground-plane distance between each detection's estimate and the pelvis of the
  person it came from, mean absolute (m) and relative (to the true distance from the camera), in
  distance bins;
* **orientation**: absolute angular error of the estimated body orientation (rad);
* **detection**: recall = people seen at least once by a camera in a frame / people whose pelvis is
  in a camera's field of view within ``range_m`` (10 m) of the robot (occluded people count as misses), precision =
  detections of real people / all detections (false positives of the detector count against it);
* **tracking**: CLEAR-MOT (MOTA, MOTP, identity switches) of the confirmed tracks against the people in
  view, matched within ``match_m`` (1 m); tracks and people outside every camera's view are left out;
  velocity error of tracks matched to a person (m/s);
* **cost**: milliseconds per robot step of rendering + detector model, network and tracker (keypoint
  extraction is shared by all robots and reported separately).
"""

from __future__ import annotations

import argparse
import json
import os
import time
from collections import defaultdict
from pathlib import Path
from typing import Any

import numpy as np
from scipy.optimize import linear_sum_assignment

from navzoo.perception.dataset import EVAL_SCENES
from navzoo.perception.monoloco import wrap_angle
from navzoo.perception.pipeline import RobotPerception, people_ground_truth
from navzoo.perception.tracker import clear_mot

__all__ = ["DISTANCE_BINS", "add_arguments", "evaluate", "run_cli"]

DISTANCE_BINS = (0.0, 2.0, 4.0, 6.0, 8.0, 10.0, 20.0)


def _in_view(perception: RobotPerception, pose: np.ndarray, xy: np.ndarray, height: float = 0.9) -> np.ndarray:
    pts = np.column_stack([xy, np.full(len(xy), height)]) if len(xy) else np.zeros((0, 3))
    ok = np.zeros(len(xy), dtype=bool)
    for cam in perception.cameras:
        ok |= cam.fov_contains(pts, pose)
    return ok


def evaluate_scene(scene: str, steps: int, seed: int, model_dir: str | None = None, range_m: float = 10.0,
                   match_m: float = 1.0, crowd_model: str = "orca", occlusion: str = "render",
                   n_humans: int | None = None) -> dict[str, Any]:
    """Raw per-detection and per-frame records of one scene (aggregated by :func:`summarise`)."""
    import navzoo
    from navzoo.agents.baselines import make_policy
    from navzoo.perception.monoloco import load_estimator

    kw: dict[str, Any] = {"scene": scene, "crowd_model": crowd_model, "n_robots": 1}
    if n_humans is not None:
        kw["n_humans"] = int(n_humans)
    env = navzoo.make(None, **kw)
    nav = env.unwrapped
    perception = RobotPerception(estimator=load_estimator(model_dir), occlusion=occlusion, seed=seed)
    policy = make_policy("orca")
    rec: dict[str, list] = defaultdict(list)
    gt_frames: list[dict] = []
    hyp_frames: list[dict] = []
    episode = 0
    obs, _ = env.reset(seed=seed * 1000)
    perception.reset(nav)
    policy.reset(nav)
    n_gt = n_seen = n_det = n_det_real = 0
    try:
        for _ in range(steps):
            if not env.agents:
                episode += 1
                # A new episode is a new sequence for CLEAR-MOT: ids are never reused across trackers.
                rec["mot"].append(clear_mot(gt_frames, hyp_frames, threshold=match_m).as_dict() if gt_frames else None)
                gt_frames, hyp_frames = [], []
                obs, _ = env.reset(seed=seed * 1000 + episode)
                perception.reset(nav)
                policy.reset(nav)
            frame = perception.step(nav, [0])[0]
            gt = people_ground_truth(nav)
            pose = np.array([nav.pos[0, 0], nav.pos[0, 1], nav.yaw[0]])
            dist_robot = np.linalg.norm(gt["pelvis"][:, :2] - pose[:2], axis=1)
            in_view = _in_view(perception, pose, gt["pelvis"][:, :2]) & (dist_robot <= range_m)
            gt_ids = gt["index"][in_view]
            seen = set()
            for o in frame.observations:
                seen |= set(int(j) for j in o.person if j >= 0)
            n_gt += len(gt_ids)
            n_seen += len(set(gt_ids.tolist()) & seen)
            # Detections within range (by their true person, or by the estimate for false positives).
            est_d = np.linalg.norm(frame.position - pose[:2], axis=1) if len(frame.position) else np.zeros(0)
            real = frame.person >= 0
            rows = np.searchsorted(gt["index"], np.where(real, frame.person, 0))
            true_xy = gt["pelvis"][rows, :2]
            true_d_robot = np.linalg.norm(true_xy - pose[:2], axis=1)
            in_range = np.where(real, true_d_robot <= range_m, est_d <= range_m)
            n_det += int(in_range.sum())
            n_det_real += int((in_range & real).sum())
            sel = real & in_range
            if sel.any():
                cams = [perception.cameras[c] for c in frame.camera_index[sel]]
                centres = np.array([c.extrinsics(pose)[1][:2] for c in cams])
                rec["err"].append(np.linalg.norm(frame.position[sel] - true_xy[sel], axis=1))
                rec["dist"].append(np.linalg.norm(true_xy[sel] - centres, axis=1))
                rec["ori"].append(np.abs(wrap_angle(frame.yaw[sel] - gt["yaw"][rows[sel]])))
            # Tracking, restricted to what the cameras can see.
            gt_frames.append({int(j): gt["pelvis"][k, :2] for k, j in enumerate(gt["index"]) if in_view[k]})
            tr = [t for t in frame.tracks]
            t_xy = np.array([t.position for t in tr]).reshape(-1, 2)
            t_ok = _in_view(perception, pose, t_xy) & (np.linalg.norm(t_xy - pose[:2], axis=1) <= range_m)
            hyp_frames.append({t.id: t.position for t, ok in zip(tr, t_ok, strict=True) if ok})
            if len(tr) and in_view.any():
                g_xy = gt["pelvis"][in_view, :2]
                cost = np.linalg.norm(t_xy[:, None] - g_xy[None], axis=2)
                r, c = linear_sum_assignment(cost)
                good = cost[r, c] <= match_m
                if good.any():
                    v_t = np.array([tr[k].velocity for k in r[good]])
                    v_g = gt["velocity"][in_view][c[good]]
                    rec["vel"].append(np.linalg.norm(v_t - v_g, axis=1))
            obs, *_ = env.step(policy.act(obs, nav))
    finally:
        env.close()
    if gt_frames:
        rec["mot"].append(clear_mot(gt_frames, hyp_frames, threshold=match_m).as_dict())
    cat = {k: (np.concatenate(v) if v else np.zeros(0)) for k, v in rec.items() if k != "mot"}
    return {"scene": scene, "steps": steps, **cat, "mot": [m for m in rec["mot"] if m],
            "n_gt": n_gt, "n_seen": n_seen, "n_det": n_det, "n_det_real": n_det_real,
            "timing": dict(perception.timing), "calls": perception.calls}


def summarise(parts: list[dict[str, Any]]) -> dict[str, Any]:
    """Aggregate the records of :func:`evaluate_scene` into the reported metrics."""
    cat = {k: np.concatenate([p.get(k, np.zeros(0)) for p in parts]) for k in ("err", "dist", "ori", "vel")}
    err, dist = cat["err"], cat["dist"]
    bins = []
    for lo, hi in zip(DISTANCE_BINS[:-1], DISTANCE_BINS[1:], strict=True):
        m = (dist >= lo) & (dist < hi)
        bins.append({"bin_m": [lo, hi], "n": int(m.sum()),
                     "mean_abs_m": float(err[m].mean()) if m.any() else None,
                     "mean_rel": float((err[m] / dist[m]).mean()) if m.any() else None})
    mots = [m for p in parts for m in p["mot"]]
    keys = ("fn", "fp", "idsw", "num_gt", "matches")
    tot = {k: sum(m.get(k, 0) for m in mots) for k in keys}
    motp_num = sum(m["motp"] * m["matches"] for m in mots if m["matches"])
    mota = 1.0 - (tot["fn"] + tot["fp"] + tot["idsw"]) / max(tot["num_gt"], 1)
    timing: dict[str, float] = defaultdict(float)
    calls = sum(p["calls"] for p in parts)
    for p in parts:
        for k, v in p["timing"].items():
            timing[k] += v
    ms = {k: 1000.0 * v / max(calls, 1) for k, v in timing.items()}
    n_gt, n_seen = sum(p["n_gt"] for p in parts), sum(p["n_seen"] for p in parts)
    n_det, n_real = sum(p["n_det"] for p in parts), sum(p["n_det_real"] for p in parts)
    return {
        "localization_error_m": float(err.mean()) if err.size else None,
        "relative_localization_error": float((err / dist).mean()) if err.size else None,
        "by_distance": bins,
        "orientation_error_rad": float(cat["ori"].mean()) if cat["ori"].size else None,
        "recall": n_seen / max(n_gt, 1),
        "precision": n_real / max(n_det, 1),
        "mota": float(mota),
        "motp_m": motp_num / max(tot["matches"], 1),
        "id_switches": int(tot["idsw"]),
        "id_switches_per_100_gt": 100.0 * tot["idsw"] / max(tot["num_gt"], 1),
        "tracking_false_negatives": int(tot["fn"]),
        "tracking_false_positives": int(tot["fp"]),
        "velocity_error_mps": float(cat["vel"].mean()) if cat["vel"].size else None,
        "ms_per_robot_step": float(sum(ms.values())),
        "ms_breakdown": ms,
        "detections": int(err.size),
        "frames": int(calls),
        "scenes": [p["scene"] for p in parts],
    }


def evaluate(scenes: tuple[str, ...] = EVAL_SCENES, steps: int = 600, seed: int = 0, workers: int = 1,
             **kw: Any) -> dict[str, Any]:
    """Run :func:`evaluate_scene` on ``scenes`` (one process per scene with ``workers > 1``) and summarise."""
    from navzoo.benchmark.pedestrians import _pool_map

    t0 = time.perf_counter()
    if kw:
        parts = [evaluate_scene(s, steps, seed + k, **kw) for k, s in enumerate(scenes)]
    else:
        parts = _pool_map(evaluate_scene, [(s, steps, seed + k) for k, s in enumerate(scenes)], workers)
    out = summarise(parts)
    out["per_scene"] = {p["scene"]: {k: v for k, v in summarise([p]).items() if k not in ("by_distance", "scenes")}
                        for p in parts}
    out["steps_per_scene"] = steps
    out["wall_s"] = round(time.perf_counter() - t0, 1)
    from navzoo.machine import cpu_model

    out["machine"] = f"{cpu_model()}, {os.cpu_count()} cores"
    return out


def add_arguments(ap: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The options of ``navzoo eval perception``."""
    ap.add_argument("--quick", action="store_true", help="one scene, 150 steps (a smoke test)")
    ap.add_argument("--scenes", default=",".join(EVAL_SCENES), help="comma-separated scenes (default: held out)")
    ap.add_argument("--steps", type=int, default=600, help="env steps per scene")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--workers", type=int, default=1)
    ap.add_argument("--model", default=None, help="Monoloco model folder (default: policies/monoloco)")
    ap.add_argument("--nav-episodes", type=int, default=10,
                    help="navigation comparison: episodes per scene and method, with ground truth and perceived "
                         "(0: skip)")
    ap.add_argument("--nav-methods", default="orca,dwa", help="robot methods of the navigation comparison")
    ap.add_argument("--nav-scenes", default="lobby,doorway,hospital_corridor",
                    help="scenes of the navigation comparison")
    ap.add_argument("--json", action="store_true", help="print JSON")
    ap.add_argument("--out", default=None, help="also write the JSON here")
    return ap


def run_cli(args: argparse.Namespace, error=None) -> int:
    """Run ``navzoo eval perception`` from parsed options."""
    from navzoo.world.library import list_scenes

    scenes = tuple(s.strip() for s in args.scenes.split(",") if s.strip())
    unknown = [s for s in scenes if s not in list_scenes()]
    if unknown or not scenes:
        msg = f"unknown scene(s) {unknown}; available: {', '.join(list_scenes())}"
        if error is not None:
            error(msg)
        raise SystemExit(msg)
    if args.steps < 1 or args.workers < 1 or args.nav_episodes < 0:
        msg = "--steps and --workers must be >= 1, --nav-episodes >= 0"
        if error is not None:
            error(msg)
        raise SystemExit(msg)
    steps = args.steps
    if args.quick:
        scenes, steps = scenes[:1], min(steps, 150)
    kw = {"model_dir": args.model} if args.model else {}
    result = evaluate(scenes, steps, args.seed, args.workers, **kw)
    nav_methods = tuple(m.strip() for m in args.nav_methods.split(",") if m.strip())
    nav_scenes = tuple(s.strip() for s in args.nav_scenes.split(",") if s.strip())
    nav_episodes = args.nav_episodes
    if args.quick:
        nav_methods, nav_scenes, nav_episodes = nav_methods[:1], nav_scenes[:1], min(nav_episodes, 2)
    if nav_episodes:
        from navzoo.perception.navigation import compare

        t0 = time.perf_counter()
        result["navigation"] = compare(nav_methods, nav_scenes, nav_episodes, args.seed, args.workers, **kw)
        result["navigation"]["wall_s"] = round(time.perf_counter() - t0, 1)
    if args.out:
        Path(args.out).parent.mkdir(parents=True, exist_ok=True)
        Path(args.out).write_text(json.dumps(result, indent=2) + "\n")
    if args.json:
        print(json.dumps(result))
        return 0
    print(f"scenes {', '.join(result['scenes'])}: {result['frames']} robot steps, {result['detections']} detections")
    print(f"localisation error {result['localization_error_m']:.3f} m (relative "
          f"{result['relative_localization_error']:.3f}), orientation error {result['orientation_error_rad']:.3f} rad")
    for b in result["by_distance"]:
        if b["n"]:
            print(f"  {b['bin_m'][0]:4.0f}-{b['bin_m'][1]:<4.0f} m  n={b['n']:6d}  {b['mean_abs_m']:.3f} m  "
                  f"{100 * b['mean_rel']:.1f} %")
    print(f"recall {result['recall']:.3f}, precision {result['precision']:.3f}, MOTA {result['mota']:.3f}, "
          f"ID switches {result['id_switches']}, velocity error {result['velocity_error_mps']:.3f} m/s")
    print("ms per robot step: " + ", ".join(f"{k} {v:.1f}" for k, v in result["ms_breakdown"].items())
          + f", total {result['ms_per_robot_step']:.1f}")
    if "navigation" in result:
        print("navigation (ground truth -> perceived): success, collision, timeout, min distance (m)")
        for m, modes in result["navigation"]["methods"].items():
            g, p = modes["ground_truth"], modes["perceived"]
            print(f"  {m:12s} {g['success']:.2f} -> {p['success']:.2f}   {g['collision']:.2f} -> {p['collision']:.2f}"
                  f"   {g['timeout']:.2f} -> {p['timeout']:.2f}   {g['min_distance_m']:.2f} -> {p['min_distance_m']:.2f}")
    return 0
