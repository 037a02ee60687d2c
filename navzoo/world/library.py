"""The packaged scene library (``navzoo/world/scenes/*.yaml``)."""

from __future__ import annotations

import functools
from importlib import resources
from typing import Any

import yaml

from navzoo.world.scene import Scene, SceneError, scene_from_dict

__all__ = ["get_scene", "list_scenes", "scene_info"]

_PACKAGE = "navzoo.world"
_DIR = "scenes"


def _scene_files() -> dict[str, Any]:
    root = resources.files(_PACKAGE) / _DIR
    return {f.name.rsplit(".", 1)[0]: f for f in root.iterdir() if f.name.endswith((".yaml", ".yml"))}


@functools.cache
def _names() -> tuple[str, ...]:
    return tuple(sorted(_scene_files()))


def list_scenes() -> list[str]:
    """Names of the packaged scenes, sorted."""
    return list(_names())


@functools.cache
def _load(name: str) -> Scene:
    files = _scene_files()
    if name not in files:
        from navzoo.world.procedural import from_name

        scene = from_name(name)
        if scene is not None:
            return scene
        if name.startswith("replay_"):  # the open scene of an ETH/UCY recording (navzoo.agents.replay)
            from navzoo.agents.replay import scene_from_name

            return scene_from_name(name)
        raise ValueError(
            f"unknown scene {name!r}; valid scenes: {', '.join(sorted(files))} "
            "(and procedural_rooms_<seed>, procedural_aisles_<seed>, replay_<recording>)"
        )
    data = yaml.safe_load(files[name].read_text(encoding="utf-8"))
    if not isinstance(data, dict):
        raise SceneError("expected a mapping at the top level", scene=name)
    scene = scene_from_dict(data, default_name=name)
    if scene.name != name:
        raise SceneError(f"name must match the file name '{name}', got '{scene.name}'", scene=name, path="name")
    scene.validate_reachability()
    return scene


def get_scene(name: str) -> Scene:
    """The packaged scene ``name`` (validated, including reachability; cached, immutable).

    Names ``procedural_rooms_<seed>`` and ``procedural_aisles_<seed>`` (``<seed>`` a non-negative integer)
    give the scenes of :mod:`navzoo.world.procedural` for that seed with default parameters; names
    ``replay_<recording>`` (``replay_eth``, ``replay_zara1``, ...) the open scene of that ETH/UCY recording
    (:func:`navzoo.agents.replay.replay_scene`, needs the trajectory data). Neither is listed by
    :func:`list_scenes`.

    Raises:
        ValueError: for an unknown name, listing the valid ones.
    """
    if not isinstance(name, str):
        raise ValueError(f"scene name must be a string, got {name!r}")
    return _load(name)


def scene_info(name: str) -> dict[str, Any]:
    """Summary of a packaged scene: name, description, size_m ``[w, h]``, free_area_m2 (radius 0),
    n_obstacles, default_humans, time_limit and protocol (its type, e.g. ``"regions"``)."""
    scene = get_scene(name)
    w, h = scene.size
    return {
        "name": scene.name,
        "description": scene.description,
        "size_m": [round(w, 3), round(h, 3)],
        "free_area_m2": round(scene.free_area(0.0), 1),
        "n_obstacles": len(scene.obstacles),
        "default_humans": scene.default_humans,
        "time_limit": scene.time_limit,
        "protocol": scene.protocol.type,
    }
