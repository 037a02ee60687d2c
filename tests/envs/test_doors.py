"""Door entries: A* paths cross doors on their axis (navzoo.envs.doors)."""

from __future__ import annotations

import numpy as np

from navzoo.envs.doors import door_axis, door_entries
from navzoo.envs.nav_env import NavEnv


def test_a_slanted_path_crosses_the_doorway_on_its_axis():
    env = NavEnv(scene="doorway", n_robots=0, n_humans=1, human_model="kinematic")  # door: x = 8, y 3.5-4.5
    env.reset(seed=0, options={"human_starts": [[5.0, 1.5]], "human_goals": [[11.0, 6.5]]})
    path = env.paths[0]
    assert abs(door_axis(env.grid, np.array([8.0, 4.0]), 0.5) @ [1.0, 0.0]) > 0.99
    new = door_entries(path, env.pos[0], env.grid, 0.3)
    at = np.flatnonzero(np.linalg.norm(new - [8.0, 4.0], axis=1) < 0.2)
    assert at.size == 1
    entry, centre, exit_ = new[at[0] - 1], new[at[0]], new[at[0] + 1]
    np.testing.assert_allclose(entry, centre - [0.7, 0.0], atol=0.05)  # straight across, west to east
    np.testing.assert_allclose(exit_, centre + [0.7, 0.0], atol=0.05)
    assert np.allclose(new[0], path[0]) and np.allclose(new[-1], path[-1])
    assert env.grid.distance_at(new).min() >= 0.3
    # a path that does not pass a door, and one that ends in the door, stay as they are
    open_path = np.array([[2.0, 2.0], [4.0, 2.0], [4.0, 6.0]])
    np.testing.assert_array_equal(door_entries(open_path, [1.0, 2.0], env.grid, 0.3), open_path)
    to_door = np.array([[7.0, 4.0], [8.0, 4.0]])
    np.testing.assert_array_equal(door_entries(to_door, [6.0, 4.0], env.grid, 0.3), to_door)
    env.close()


def test_amp_pedestrians_get_door_entries_only_when_asked():
    opts = {"human_starts": [[5.0, 1.5]], "human_goals": [[11.0, 6.5]]}
    paths = {}
    for flag in (False, True):
        env = NavEnv(scene="doorway", n_robots=0, n_humans=1, human_model="amp", dt=1 / 30,
                     max_episode_steps_override=5, human_door_entries=flag)
        env.reset(seed=0, options=opts)
        paths[flag] = env.paths[0].copy()
        env.close()
    on_axis = [np.linalg.norm(p - [7.3, 4.0], axis=1).min() < 0.1 for p in (paths[False], paths[True])]
    assert on_axis == [False, True]
