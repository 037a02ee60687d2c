"""Perception video: the robot's camera views with detected keypoints and track ids, beside the top-down view.

``python -m navzoo.perception.video --scene lobby --steps 150 --out runs/perception_video`` writes
``perception.mp4`` and a poster ``perception.png``. Each frame shows

* left: each robot camera (rendered by PyBullet) with the detector's keypoints and skeletons (green:
  a real person, red: a false positive), the Monoloco distance next to each detection, and the id of
  the track it was associated with;
* right: the env's top-down view with the robot's field of view, the true people (orange), the
  tracks (blue crosses with ids and velocity arrows) and the detections (small dots).
"""

from __future__ import annotations

import argparse
from pathlib import Path

import cv2
import numpy as np

from navzoo.perception.pipeline import PerceptionFrame, RobotPerception
from navzoo.sensors.camera_model import COCO_SKELETON

__all__ = ["compose_frame", "main", "write_video"]

_TRACK_BGR = (200, 80, 20)


def _draw_camera(rgb: np.ndarray, frame: PerceptionFrame, cam_index: int) -> np.ndarray:
    img = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR)
    o = frame.observations[cam_index]
    sel = np.flatnonzero(frame.camera_index == cam_index)
    tracks = frame.tracks
    t_xy = np.array([t.position for t in tracks]).reshape(-1, 2)
    for j, d in enumerate(sel):
        uv, det = o.uv[j], o.detected[j]
        color = (40, 180, 40) if o.person[j] >= 0 else (40, 40, 220)
        for a, b in COCO_SKELETON:
            if det[a] and det[b]:
                cv2.line(img, tuple(np.round(uv[a]).astype(int)), tuple(np.round(uv[b]).astype(int)), color, 2,
                         cv2.LINE_AA)
        for k in np.flatnonzero(det):
            cv2.circle(img, tuple(np.round(uv[k]).astype(int)), 3, color, -1, cv2.LINE_AA)
        top = uv[det][np.argmin(uv[det][:, 1])]
        label = f"{frame.distance[d]:.1f}m"
        if len(t_xy):
            k = int(np.argmin(np.linalg.norm(t_xy - frame.position[d], axis=1)))
            if np.linalg.norm(t_xy[k] - frame.position[d]) < 1.0:
                label = f"#{tracks[k].id} " + label
        cv2.putText(img, label, (int(top[0]) - 20, max(12, int(top[1]) - 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (0, 0, 0), 2, cv2.LINE_AA)
        cv2.putText(img, label, (int(top[0]) - 20, max(12, int(top[1]) - 8)), cv2.FONT_HERSHEY_SIMPLEX, 0.45,
                    (255, 255, 255), 1, cv2.LINE_AA)
    cv2.putText(img, o.camera.name, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.5, (0, 0, 0), 1, cv2.LINE_AA)
    return img


def _draw_topdown(env, frame: PerceptionFrame, perception: RobotPerception, max_px: int) -> np.ndarray:
    from navzoo.envs.render import _frame_geometry, draw_topdown

    img = cv2.cvtColor(draw_topdown(env, max_px), cv2.COLOR_RGB2BGR)
    scale, corner, _ = _frame_geometry(env, max_px)

    def px(xy):
        xy = np.asarray(xy, float)
        return (int(round((xy[0] - corner[0]) * scale)), int(round((corner[1] - xy[1]) * scale)))

    i = frame.robot_index
    x, y, yaw = env.pos[i, 0], env.pos[i, 1], env.yaw[i]
    for cam in perception.cameras:
        half = np.radians(cam.hfov_deg) / 2
        for side in (-half, half):
            a = yaw + cam.mount_yaw + side
            cv2.line(img, px((x, y)), px((x + 6 * np.cos(a), y + 6 * np.sin(a))), (160, 160, 160), 1, cv2.LINE_AA)
    for p in frame.position:
        cv2.circle(img, px(p), 2, (120, 120, 120), -1, cv2.LINE_AA)
    for t in frame.tracks:
        c = px(t.position)
        cv2.drawMarker(img, c, _TRACK_BGR, cv2.MARKER_CROSS, 10, 2)
        cv2.arrowedLine(img, c, px(np.asarray(t.position) + np.asarray(t.velocity)), _TRACK_BGR, 1, cv2.LINE_AA)
        cv2.putText(img, f"#{t.id}", (c[0] + 5, c[1] - 5), cv2.FONT_HERSHEY_SIMPLEX, 0.4, _TRACK_BGR, 1, cv2.LINE_AA)
    return img


def compose_frame(env, frame: PerceptionFrame, perception: RobotPerception, camera_images: list,
                  height: int = 480) -> np.ndarray:
    """One video frame (BGR): the camera views stacked on the left, the top-down view on the right."""
    cams = [_draw_camera(im.rgb, frame, c) for c, im in enumerate(camera_images)]
    w_cam = int(round(cams[0].shape[1] * (height / len(cams)) / cams[0].shape[0]))
    left = np.vstack([cv2.resize(c, (w_cam, height // len(cams))) for c in cams])
    top = _draw_topdown(env, frame, perception, height)
    top = cv2.resize(top, (int(round(top.shape[1] * left.shape[0] / top.shape[0])), left.shape[0]))
    return np.hstack([left, top])


def write_video(scene: str = "lobby", steps: int = 150, seed: int = 0, out: str | Path = "runs/perception_video",
                n_humans: int | None = None, model_dir: str | None = None, method: str = "orca") -> Path:
    """Drive a robot (``method``, ground truth) through ``scene`` and film its perception."""
    import navzoo
    from navzoo.agents.baselines import make_policy
    from navzoo.perception.monoloco import load_estimator
    from navzoo.sensors.render import render_robot_cameras

    kw = {"scene": scene, "n_robots": 1, "crowd_model": "orca"}
    if n_humans is not None:
        kw["n_humans"] = n_humans
    env = navzoo.make(None, **kw)
    nav = env.unwrapped
    perception = RobotPerception(estimator=load_estimator(model_dir), seed=seed)
    policy = make_policy(method)
    obs, _ = env.reset(seed=seed)
    perception.reset(nav)
    policy.reset(nav)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    path = out / "perception.mp4"
    writer = None
    last = None
    try:
        for _ in range(steps):
            if not env.agents:
                break
            frame = perception.step(nav, [0])[0]
            images = render_robot_cameras(nav, 0, perception.cameras)
            img = compose_frame(nav, frame, perception, images)
            if writer is None:
                writer = cv2.VideoWriter(str(path), cv2.VideoWriter_fourcc(*"mp4v"),
                                         max(1, int(round(1 / nav.config.dt))), (img.shape[1], img.shape[0]))
            writer.write(img)
            last = img
            obs, *_ = env.step(policy.act(obs, nav))
    finally:
        if writer is not None:
            writer.release()
        env.close()
    if last is not None:
        cv2.imwrite(str(out / "perception.png"), last)
    return path


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m navzoo.perception.video", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="lobby")
    ap.add_argument("--steps", type=int, default=150)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--humans", type=int, default=None)
    ap.add_argument("--model", default=None)
    ap.add_argument("--out", default="runs/perception_video")
    args = ap.parse_args(argv)
    if args.steps < 1:
        ap.error("--steps must be >= 1")
    print(write_video(args.scene, args.steps, args.seed, args.out, args.humans, args.model))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
