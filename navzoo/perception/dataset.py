"""Training data for the Monoloco network, generated in navzoo scenes.

A robot drives through a scene among a crowd (ORCA robot toward random goals, social-force people by
default) and, every ``every`` steps, its two cameras take a picture: the humanoids' COCO keypoints
are projected, tested for occlusion against a rendered depth image, and passed through the detector
noise model (:class:`navzoo.sensors.KeypointNoise`) ``draws`` times. Every detected real person gives
one sample: the network input (:func:`navzoo.perception.monoloco.keypoint_features`) and the targets
-- distance from the optical centre to the pelvis, the pelvis's normalised image coordinates, and the
allocentric body orientation.

The scenes used for training are :data:`TRAIN_SCENES`; :data:`EVAL_SCENES` are kept out for the
evaluation (``navzoo eval perception``), which also uses a different crowd model (ORCA).
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from navzoo.perception.monoloco import bearing_of, keypoint_features, wrap_angle
from navzoo.perception.pipeline import people_ground_truth, visible_keypoints
from navzoo.sensors.camera_model import KeypointNoise, PinholeCamera, default_robot_cameras

__all__ = ["EVAL_SCENES", "TRAIN_SCENES", "generate", "generate_scene", "load_dataset", "save_dataset"]

TRAIN_SCENES: tuple[str, ...] = (
    "station", "home", "grocery", "corridor", "apartment", "cafe", "campus_plaza", "office_floor",
    "shopping_mall", "train_platform", "warehouse_aisles", "museum_hall",
)
EVAL_SCENES: tuple[str, ...] = ("lobby", "doorway", "hospital_corridor", "library_stacks")
FIELDS = ("features", "distance", "xi", "eta", "allocentric", "person_depth", "scene")


def sample_targets(gt: dict[str, np.ndarray], person: np.ndarray, camera: PinholeCamera,
                   robot_pose: np.ndarray) -> dict[str, np.ndarray]:
    """Targets of the detections ``person`` (pedestrian indices) of one camera."""
    rows = np.searchsorted(gt["index"], person)
    pelvis = gt["pelvis"][rows]
    pc = camera.world_to_camera(pelvis, robot_pose)
    rot, t = camera.extrinsics(robot_pose)
    allo = wrap_angle(gt["yaw"][rows] - bearing_of(pelvis, t))
    z = np.maximum(pc[:, 2], 1e-6)
    return {"distance": np.linalg.norm(pc, axis=1), "xi": pc[:, 0] / z, "eta": pc[:, 1] / z,
            "allocentric": allo, "person_depth": pc[:, 2]}


def generate_scene(scene: str, steps: int, seed: int, every: int = 2, draws: int = 2,
                   crowd_model: str = "sfm", n_humans: int | None = None,
                   cameras: Sequence[PinholeCamera] | None = None, noise: KeypointNoise | None = None,
                   occlusion_downscale: int = 4) -> dict[str, np.ndarray]:
    """Samples from one scene: ``steps`` env steps, pictures every ``every`` steps.

    Episodes restart (next seed) when the robot's episode ends. People in the scene's default number
    (or ``n_humans``).
    """
    import navzoo
    from navzoo.agents.baselines import make_policy

    cams = list(cameras) if cameras is not None else list(default_robot_cameras())
    noise = noise if noise is not None else KeypointNoise()
    kw: dict[str, Any] = {"scene": scene, "crowd_model": crowd_model, "n_robots": 1}
    if n_humans is not None:
        kw["n_humans"] = int(n_humans)
    env = navzoo.make(None, **kw)
    nav = env.unwrapped
    rng = np.random.default_rng(seed)
    policy = make_policy("orca")
    out: dict[str, list] = {k: [] for k in FIELDS}
    episode = 0
    obs, _ = env.reset(seed=seed * 1000 + episode)
    policy.reset(nav)
    try:
        for step in range(steps):
            if step % every == 0 and nav.alive[0]:
                gt = people_ground_truth(nav)
                for cam in cams:
                    # The rendering is the slow part: the detector runs `draws` times on one occlusion test.
                    v = visible_keypoints(nav, 0, cam, gt, "render", occlusion_downscale)
                    seen = v.visible.any(axis=1)
                    if not seen.any():
                        continue
                    people, uv, depth, vis = v.people[seen], v.uv[seen], v.depth[seen], v.visible[seen]
                    for _ in range(draws):
                        det = noise.apply(uv, depth, vis, rng, image_size=cam)
                        keep = det.person_detected
                        if not keep.any():
                            continue
                        tg = sample_targets(gt, people[keep], cam, v.robot_pose)
                        ok = tg["person_depth"] > 0.3
                        out["features"].append(keypoint_features(det.uv[keep], det.detected[keep], cam)[ok])
                        for k in ("distance", "xi", "eta", "allocentric", "person_depth"):
                            out[k].append(tg[k][ok])
                        out["scene"].append(np.full(int(ok.sum()), scene))
            if not env.agents:
                episode += 1
                obs, _ = env.reset(seed=seed * 1000 + episode)
                policy.reset(nav)
                continue
            obs, *_ = env.step(policy.act(obs, nav))
    finally:
        env.close()
    if not out["features"]:
        return {k: np.zeros((0, 51) if k == "features" else 0) for k in FIELDS}
    return {k: np.concatenate(v) for k, v in out.items()}


def generate(scenes: Sequence[str] = TRAIN_SCENES, steps_per_scene: int = 1500, seed: int = 0, workers: int = 1,
             **kw: Any) -> dict[str, np.ndarray]:
    """:func:`generate_scene` over ``scenes`` (one process per scene with ``workers > 1``), concatenated."""
    from navzoo.benchmark.pedestrians import _pool_map

    jobs = [(s, steps_per_scene, seed + 17 * k) for k, s in enumerate(scenes)]
    if kw:
        parts = [generate_scene(*j, **kw) for j in jobs]
    else:
        parts = _pool_map(generate_scene, jobs, workers)
    return {k: np.concatenate([p[k] for p in parts]) for k in FIELDS}


def save_dataset(data: dict[str, np.ndarray], path: str | Path) -> None:
    """Write a dataset as a compressed ``.npz`` (no pickles)."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(path.name + ".tmp.npz")
    np.savez_compressed(tmp, **{k: np.asarray(v) for k, v in data.items()})
    tmp.replace(path)


def load_dataset(path: str | Path) -> dict[str, np.ndarray]:
    """Read a dataset written by :func:`save_dataset`, checking its fields."""
    with np.load(path, allow_pickle=False) as z:
        missing = [k for k in FIELDS if k not in z.files]
        if missing:
            raise ValueError(f"{path} is not a perception dataset: missing {missing}")
        return {k: z[k] for k in FIELDS}
