"""Static world of navzoo: scene format, geometry, occupancy grid, A* planner, task sampler, PyBullet builder,
scene library and plotting.

The modules that pull in heavy dependencies (``builder``: pybullet, ``plot``: matplotlib) are imported lazily
on first attribute access, so ``import navzoo.world`` stays cheap.
"""

from __future__ import annotations

import importlib
from typing import Any

from navzoo.world.library import get_scene, list_scenes, scene_info
from navzoo.world.occupancy import OccupancyGrid
from navzoo.world.planner import AStarPlanner, path_length
from navzoo.world.scene import (
    BoxObstacle,
    CircleObstacle,
    PolygonObstacle,
    Protocol,
    Region,
    Scene,
    SceneError,
    WallObstacle,
    load_scene,
)
from navzoo.world.tasks import TaskSampler

_LAZY = {
    "build_scene": "navzoo.world.builder",
    "SceneBodies": "navzoo.world.builder",
    "GROUP_STATIC": "navzoo.world.builder",
    "GROUP_ROBOT": "navzoo.world.builder",
    "GROUP_HUMAN": "navzoo.world.builder",
    "plot_scene": "navzoo.world.plot",
    "contact_sheet": "navzoo.world.plot",
}

__all__ = [
    "AStarPlanner",
    "BoxObstacle",
    "CircleObstacle",
    "GROUP_HUMAN",
    "GROUP_ROBOT",
    "GROUP_STATIC",
    "OccupancyGrid",
    "PolygonObstacle",
    "Protocol",
    "Region",
    "Scene",
    "SceneBodies",
    "SceneError",
    "TaskSampler",
    "WallObstacle",
    "build_scene",
    "contact_sheet",
    "get_scene",
    "list_scenes",
    "load_scene",
    "path_length",
    "plot_scene",
    "scene_info",
]


def __getattr__(name: str) -> Any:
    if name in _LAZY:
        value = getattr(importlib.import_module(_LAZY[name]), name)
        globals()[name] = value
        return value
    raise AttributeError(f"module 'navzoo.world' has no attribute {name!r}")
