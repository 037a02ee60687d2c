"""scripts/diffusion_end_target_probe.py: counts the end targets the old clip would have pulled off the path."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.script_modules import load_script

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def script():
    return load_script("diffusion_end_target_probe")


def test_the_probe_counts_plans_and_leaves_the_crowd_as_it_was(script):
    import navzoo.agents.diffusion.crowd as dc

    before, init = dc._end_targets, dc.DiffusionCrowd.__init__
    row = script.probe("home", 3, 2.5)
    assert dc._end_targets is before and dc.DiffusionCrowd.__init__ is init  # the spies are removed again
    assert row["targets"] >= 3  # everyone is planned at the start
    assert 0 <= row["moved"] <= row["on_path"] <= row["targets"]
    assert 0 <= row["nearest_hidden"] <= row["targets"] and row["path_in_sight"] is True
    assert (row["median_move_m"] is None) == (row["moved"] == 0)
    assert script.probe("home", 3, 2.5, path_in_sight=False)["path_in_sight"] is False
    assert dc.DiffusionCrowd.__init__ is init


def test_a_hidden_nearest_path_point_is_noticed(script):
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="home", n_robots=0, n_humans=1)
    env.reset(seed=0)
    # under the home's wall at y = 6: a path whose later leg runs just above the wall, its first leg far to the east
    env.pos[0] = [9.3, 5.45]
    env.paths[0] = np.array([[11.3, 3.0], [11.3, 5.0], [10.9, 6.3], [10.6, 6.75], [5.0, 6.75]])
    env.wp_index[0] = 1
    assert script._nearest_hidden(env, 0)
    env.pos[0] = [11.0, 4.5]  # beside its first leg
    assert not script._nearest_hidden(env, 0)
    env.close()


def test_bad_scenes_are_named(script):
    with pytest.raises(SystemExit):
        script.main(["--scenes", "home"])
