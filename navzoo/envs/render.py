"""Rendering: a top-down view drawn with OpenCV and a 3D camera view from PyBullet."""

from __future__ import annotations

from typing import TYPE_CHECKING

import cv2
import numpy as np
import pybullet as p

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

ROBOT_BGR = (200, 90, 30)
HUMAN_BGR = (40, 120, 230)
OBSTACLE_BGR = (90, 90, 90)
PATH_BGR = (220, 170, 120)
GOAL_BGR = (40, 160, 40)


def _frame_geometry(env: NavEnv, max_px: int) -> tuple[float, np.ndarray, tuple[int, int]]:
    xmin, ymin, xmax, ymax = env.scene.bounds
    w, h = xmax - xmin, ymax - ymin
    scale = max_px / max(w, h)
    size = (int(round(h * scale)) + 1, int(round(w * scale)) + 1)
    return scale, np.array([xmin, ymax]), size


def draw_topdown(env: NavEnv, max_px: int = 640) -> np.ndarray:
    """An RGB top-down image of the world: scene, paths, goals, people with headings, robots."""
    scale, corner, (hgt, wid) = _frame_geometry(env, max_px)
    ss = 4  # draw at 1/4-pixel precision (cv2 shift) for smooth shapes

    def px(xy: np.ndarray) -> np.ndarray:
        xy = np.asarray(xy, dtype=np.float64)
        u = (xy[..., 0] - corner[0]) * scale
        v = (corner[1] - xy[..., 1]) * scale
        return np.round(np.stack([u, v], axis=-1) * ss).astype(np.int32)

    img = np.full((hgt, wid, 3), 255, dtype=np.uint8)
    for poly in env.scene.obstacle_polygons():
        cv2.fillPoly(img, [px(poly)], OBSTACLE_BGR, lineType=cv2.LINE_AA, shift=2)
    R = env.n_robots
    # Robot paths, trails and goals.
    for i in range(env.n_total):
        is_robot = i < R
        if is_robot and env.paths[i] is not None:
            pts = px(np.vstack([env.trail[0][i][None], env.paths[i]]))
            cv2.polylines(img, [pts], False, PATH_BGR, 1, cv2.LINE_AA, shift=2)
    # Trails: each robot's whole episode, the last 3 s of each person.
    history = np.asarray(env.trail)
    present = np.asarray(getattr(env, "trail_present", np.ones(history.shape[:2], dtype=bool)))
    recent = max(1, int(round(3.0 / env.config.dt)))
    for i in range(env.n_total):
        pts = history[:, i] if i < R else history[-recent:, i]
        if i >= R:  # only the stretch since an absent (replay: parked) person last appeared
            here = present[-recent:, i]
            if not here[-1]:
                continue
            gone = np.flatnonzero(~here)
            pts = pts[gone[-1] + 1:] if gone.size else pts
        trail = px(pts)
        color = ROBOT_BGR if i < R else HUMAN_BGR
        if len(trail) > 1:
            cv2.polylines(img, [trail], False, tuple(int(0.5 * c + 127) for c in color), 2 if i < R else 1,
                          cv2.LINE_AA, shift=2)
    for i in range(R):
        g = px(env.goal[i])
        r = int(max(3, env.goal_tolerance * scale) * ss)
        cv2.circle(img, tuple(g), r, GOAL_BGR, 2, cv2.LINE_AA, shift=2)
        cv2.drawMarker(img, tuple((g // ss).tolist()), GOAL_BGR, cv2.MARKER_CROSS, 8, 2)
    shown = env.alive & env.present if hasattr(env, "human_active") else env.alive
    for i in range(env.n_total):
        if not shown[i]:
            continue
        color = ROBOT_BGR if i < R else HUMAN_BGR
        c = px(env.pos[i])
        r = int(env.radius[i] * scale * ss)
        cv2.circle(img, tuple(c), r, color, -1 if i < R else 2, cv2.LINE_AA, shift=2)
        tip = px(env.pos[i] + env.radius[i] * 1.6 * np.array([np.cos(env.yaw[i]), np.sin(env.yaw[i])]))
        cv2.line(img, tuple(c), tuple(tip), (0, 0, 0) if i < R else color, 2, cv2.LINE_AA, shift=2)
    label = f"{env.scene.name}  t={env.sim_time:5.1f}s  robots={int(env.alive[:R].sum())}/{R}  people={int(shown[R:].sum())}"
    cv2.putText(img, label, (6, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def camera_view(env: NavEnv, height: int = 480, width: int | None = None) -> np.ndarray:
    """An RGB image from a 3D camera behind and above the first robot (PyBullet TinyRenderer)."""
    width = width or int(height * 4 / 3)
    i = 0
    x, y = env.pos[i] if env.n_robots else np.zeros(2)
    yaw = env.yaw[i] if env.n_robots else 0.0
    eye = [x - 3.5 * np.cos(yaw), y - 3.5 * np.sin(yaw), 2.6]
    target = [x + 1.5 * np.cos(yaw), y + 1.5 * np.sin(yaw), 0.6]
    view = p.computeViewMatrix(eye, target, [0, 0, 1], physicsClientId=env.client)
    proj = p.computeProjectionMatrixFOV(70.0, width / height, 0.05, 60.0, physicsClientId=env.client)
    _, _, rgba, _, _ = p.getCameraImage(
        width, height, view, proj, renderer=p.ER_TINY_RENDERER, physicsClientId=env.client
    )
    return np.asarray(rgba, dtype=np.uint8).reshape(height, width, 4)[:, :, :3].copy()
