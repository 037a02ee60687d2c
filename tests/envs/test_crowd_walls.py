"""NavConfig's crowd_wall_* fields: the wall potential of the kinematic social-force crowd, from the config."""

import numpy as np
import pytest

from navzoo.agents.crowd import CrowdPolicy
from navzoo.agents.sfm import SocialForceParams
from navzoo.envs.config import NavConfig
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents


def _walk(seconds: float, policy: CrowdPolicy | None = None, **cfg) -> np.ndarray:
    """People of the doorway on the social-force crowd for ``seconds``: their positions over time."""
    env = NavEnv(scene="doorway", n_robots=0, n_humans=6, crowd_model="sfm", time_limit=seconds, **cfg)
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy or CrowdPolicy("sfm"))
    try:
        wrapped.reset(seed=0)
        track = []
        while not env._needs_reset:
            wrapped.step({})
            track.append(env.pos.copy())
        return np.asarray(track)
    finally:
        wrapped.close()


def test_defaults_are_the_social_force_defaults():
    env = NavEnv(scene="doorway", n_robots=0, n_humans=2, crowd_model="sfm")
    try:
        assert env.crowd_sfm_params == SocialForceParams()
        env.config = env.config.replace(crowd_wall_strength=0.3, crowd_wall_near_range=1.5)
        assert env.crowd_sfm_params == SocialForceParams(A_wall=0.3, wall_near_range=1.5, A_wall_near=0.3)
        env.config = env.config.replace(crowd_wall_near_ramp=1.0)
        assert env.crowd_sfm_params.wall_near_ramp == 1.0
    finally:
        env.close()


def test_the_config_walls_move_the_crowd_and_own_parameters_win():
    default = _walk(20.0)
    soft = _walk(20.0, crowd_wall_strength=0.3)
    near = _walk(20.0, crowd_wall_near_range=1.5)
    assert not np.array_equal(default, soft) and not np.array_equal(default, near) and not np.array_equal(soft, near)
    # a policy with parameters of its own keeps them, whatever the config says
    own = _walk(20.0, CrowdPolicy("sfm", sfm_params=SocialForceParams()), crowd_wall_strength=0.3)
    np.testing.assert_array_equal(own, default)
    # the same walls given to the policy or through the config walk the same
    given = _walk(20.0, CrowdPolicy("sfm", sfm_params=SocialForceParams(A_wall=0.3)))
    np.testing.assert_array_equal(given, soft)


@pytest.mark.parametrize("field,value,msg", [
    ("crowd_wall_strength", 0.0, "a finite number > 0"),
    ("crowd_wall_strength", float("nan"), "a finite number > 0"),
    ("crowd_wall_near_strength", -1.0, "a finite number > 0"),
    ("crowd_wall_near_range", -0.5, ">= 0"),
    ("crowd_wall_near_range", True, ">= 0"),
    ("crowd_wall_near_ramp", -1.0, ">= 0"),
])
def test_bad_crowd_walls_are_refused_by_name(field, value, msg):
    with pytest.raises(ValueError, match=f"NavConfig.{field} must be .*{msg}"):
        NavConfig(**{field: value})
