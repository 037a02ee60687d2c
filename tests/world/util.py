from __future__ import annotations

from typing import Any


def base_scene(**overrides: Any) -> dict[str, Any]:
    """A small valid two-room scene (10 x 6 m, 1 m door in the middle wall) as a plain dict."""
    data: dict[str, Any] = {
        "name": "test_rooms",
        "description": "two rooms",
        "bounds": [0, 0, 10, 6],
        "obstacles": [
            {"type": "wall", "start": [5, 0], "end": [5, 2.5], "thickness": 0.2, "height": 2.5},
            {"type": "wall", "start": [5, 3.5], "end": [5, 6], "thickness": 0.2, "height": 2.5},
            {"type": "box", "center": [2, 3], "size": [1, 0.6], "yaw": 0.3, "height": 0.8, "name": "table"},
            {"type": "circle", "center": [8, 1.5], "radius": 0.4, "height": 1.0},
            {"type": "polygon", "points": [[7, 4], [9, 4], [9, 5.5], [8.4, 5.5], [8.4, 4.6], [7, 4.6]], "height": 0.9},
        ],
        "regions": {
            "west": {"rect": [0.2, 0.2, 4.5, 5.8]},
            "east": {"polygon": [[5.5, 0.2], [9.8, 0.2], [9.8, 5.8], [5.5, 5.8]]},
        },
        "robot_spawn": ["west"],
        "robot_goal": ["east"],
        "human_spawn": ["west", "east"],
        "human_goal": ["west", "east"],
        "waypoints": {"door": [5, 3]},
        "protocol": {"type": "regions"},
        "default_humans": 4,
        "time_limit": 30.0,
    }
    data.update(overrides)
    return data
