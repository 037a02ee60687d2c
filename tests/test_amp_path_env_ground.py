"""The path env's box ground reaches every patch, however many envs one process holds."""

from __future__ import annotations

import numpy as np
import pybullet as p
import pytest

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.sim import GROUND_HALF_SIZE
from navzoo.agents.amp.train import grounded_locomotion_reference


@pytest.fixture(scope="module")
def ref():
    return grounded_locomotion_reference()


def _ground_half_side(env: AmpPathEnv) -> float:
    lo, hi = p.getAABB(env.bodies.ground_id, physicsClientId=env.client)
    assert np.allclose(lo[:2], [-hi[0], -hi[1]])  # centred on the origin
    return float(hi[0])


def test_a_large_patch_grid_still_stands_on_ground(ref):
    """180 envs make a 14 x 13 grid 520 m wide: before the fix the last columns had no floor and fell at once
    (240 envs in one process: episodes of 0.73 s against 2.56 s with 16 envs, measured 2026-11-29)."""
    env = AmpPathEnv(180, ref, PathTaskConfig(), seed=0)
    try:
        assert env.origins.max() > GROUND_HALF_SIZE
        assert _ground_half_side(env) >= env.origins.max() + 0.5 * env.cfg.spacing
        env.reset()
        xy = env.bodies.read_state()["root_pos"][:, :2]
        assert np.abs(xy).max() < _ground_half_side(env)
    finally:
        env.close()


def test_a_small_grid_keeps_the_default_ground(ref):
    env = AmpPathEnv(16, ref, PathTaskConfig(), seed=0)
    try:
        assert _ground_half_side(env) == pytest.approx(GROUND_HALF_SIZE)
    finally:
        env.close()
