"""Matplotlib drawing of scenes (top-down) and a contact sheet of several scenes.

Example:
    >>> from navzoo.world.plot import contact_sheet
    >>> contact_sheet(["home", "station"], "scenes.png")
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import Any

# No matplotlib.use() here: the caller's backend is respected (matplotlib falls back to Agg when headless).
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.collections import PatchCollection
from matplotlib.patches import Circle, Polygon, Rectangle

from navzoo.world.scene import CircleObstacle, Scene

__all__ = ["contact_sheet", "plot_scene"]

_OBSTACLE_FACE = {"wall": "#555555", "box": "#a0785a", "polygon": "#8c6446", "circle": "#7a7a7a"}
_REGION_COLORS = plt.get_cmap("tab10").colors


def plot_scene(
    scene: Scene,
    ax: Any = None,
    show_regions: bool = True,
    show_waypoints: bool = True,
    path: np.ndarray | None = None,
    title: str | None = None,
) -> Any:
    """Draw a scene top-down on ``ax`` (a new figure's axes when None) and return the axes.

    Obstacles are filled (circles as true circles), the bounds drawn as a thin frame, regions outlined and
    labelled, waypoints marked with crosses, crossing protocols shown by their circle/square. Coordinates
    are world metres with equal aspect, so trajectories can be drawn on top with ``ax.plot(x, y)``.

    Args:
        scene: the scene.
        ax: matplotlib axes to draw into.
        show_regions: outline and label the named regions (and the crossing-protocol geometry).
        show_waypoints: mark the named waypoints.
        path: optional ``(K, 2)`` polyline (e.g. an A* path) drawn in blue.
        title: axes title (default: the scene name).
    """
    if ax is None:
        _, ax = plt.subplots(figsize=(6, 6 * scene.size[1] / max(scene.size[0], 1e-9)))
    x0, y0, x1, y1 = scene.bounds
    ax.add_patch(Rectangle((x0, y0), x1 - x0, y1 - y0, facecolor="#f7f7f4", edgecolor="black", linewidth=0.8, zorder=0))

    patches = []
    colors = []
    for obs, poly in zip(scene.obstacles, scene.obstacle_polygons(), strict=True):
        if isinstance(obs, CircleObstacle):
            patches.append(Circle(obs.center, obs.radius))
        else:
            patches.append(Polygon(poly, closed=True))
        colors.append(_OBSTACLE_FACE[obs.type])
    if patches:
        ax.add_collection(PatchCollection(patches, facecolors=colors, edgecolors="none", zorder=2))

    if show_regions:
        for k, (name, region) in enumerate(scene.regions.items()):
            color = _REGION_COLORS[k % len(_REGION_COLORS)]
            verts = region.vertices()
            ax.add_patch(Polygon(verts, closed=True, fill=False, edgecolor=color, linestyle="--", linewidth=1.0, zorder=3))
            cx, cy = verts.mean(axis=0)
            ax.text(cx, cy, name, color=color, fontsize=6, ha="center", va="center", zorder=4,
                    bbox={"facecolor": "white", "alpha": 0.6, "edgecolor": "none", "pad": 0.5})
        proto = scene.protocol
        if proto.type == "circle_crossing":
            ax.add_patch(Circle((0, 0), proto.radius, fill=False, edgecolor="tab:purple", linestyle="--", zorder=3))
            ax.text(0, proto.radius + proto.noise + 0.3, f"circle r={proto.radius:g} m", color="tab:purple",
                    fontsize=7, ha="center", zorder=4)
        elif proto.type == "square_crossing":
            w = proto.width
            ax.add_patch(Rectangle((-w / 2, -w / 2), w, w, fill=False, edgecolor="tab:purple", linestyle="--", zorder=3))
            ax.text(0, w / 2 + 0.3, f"square w={w:g} m", color="tab:purple", fontsize=7, ha="center", zorder=4)
        if proto.type != "regions":
            r = proto.radius
            ax.plot([0, 0], [-r, r], color="tab:green", marker="o", markersize=3, linewidth=0, zorder=4)

    if show_waypoints and scene.waypoints:
        pts = np.array(list(scene.waypoints.values()))
        ax.scatter(pts[:, 0], pts[:, 1], marker="x", s=14, color="tab:red", linewidths=1.0, zorder=5)

    if path is not None and len(path):
        pth = np.asarray(path)
        ax.plot(pth[:, 0], pth[:, 1], color="tab:blue", linewidth=1.5, zorder=6)
        ax.plot(pth[0, 0], pth[0, 1], "o", color="tab:blue", markersize=4, zorder=6)
        ax.plot(pth[-1, 0], pth[-1, 1], "*", color="tab:blue", markersize=8, zorder=6)

    margin = 0.02 * max(x1 - x0, y1 - y0)
    ax.set_xlim(x0 - margin, x1 + margin)
    ax.set_ylim(y0 - margin, y1 + margin)
    ax.set_aspect("equal")
    ax.set_title(scene.name if title is None else title, fontsize=9)
    ax.tick_params(labelsize=6)
    return ax


def sample_robot_path(scene: Scene, seed: int = 0, radius: float = 0.3) -> np.ndarray | None:
    """An A* path for one robot task sampled with ``seed`` (used to illustrate scenes)."""
    from navzoo.world.planner import AStarPlanner
    from navzoo.world.tasks import TaskSampler

    grid = scene.occupancy()
    starts, goals = TaskSampler(scene, grid, radius).sample(np.random.default_rng(seed), 1, "robot")
    return AStarPlanner(grid, radius).plan(starts[0], goals[0])


def contact_sheet(names: Sequence[str], path: str | Path, cols: int = 4, seed: int = 0) -> Path:
    """Save a grid of packaged scenes (with a sampled robot A* path each) to a PNG and return its path."""
    from navzoo.world.library import get_scene

    rows = math.ceil(len(names) / cols)
    fig, axes = plt.subplots(rows, cols, figsize=(4.2 * cols, 3.9 * rows), squeeze=False)
    for ax, name in zip(axes.ravel(), names, strict=False):
        scene = get_scene(name)
        w, h = scene.size
        plot_scene(scene, ax=ax, path=sample_robot_path(scene, seed),
                   title=f"{name}  ({w:g} x {h:g} m, {scene.default_humans} people)")
    for ax in axes.ravel()[len(names):]:
        ax.axis("off")
    fig.tight_layout()
    return save_figure(fig, path, dpi=130)


def save_figure(fig: Any, path: str | Path, dpi: int = 110) -> Path:
    """Write ``fig`` to ``path`` (parent folders created), close it, and return the path."""
    out = Path(path)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=dpi)
    plt.close(fig)
    return out
