"""Stage-3 replans of the AMP task: synchronised across an env's humanoids, and rolled out against the
walls of the planned humanoids' own patches only (both for collection speed, same targets)."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.amp.path_env import AmpPathEnv, PathTaskConfig
from navzoo.agents.amp.sim import ACTION_DIM
from navzoo.agents.amp.train import locomotion_reference


@pytest.fixture(scope="module")
def walled_env():
    cfg = PathTaskConfig(stage=3, crowd_prob=1.0, obstacle_obs=True, boxes_per_patch=4, pair_patches=True,
                         door_prob=1.0)
    env = AmpPathEnv(6, locomotion_reference(), cfg, seed=3)
    env.reset(seed=3)
    yield env
    env.close()


def test_rollout_walls_are_the_own_patches_and_give_the_same_paths(walled_env):
    env = walled_env
    idx = np.array([0, 3])
    segs = env._rollout_segments(idx)
    own = np.concatenate([env._patch_segments[q] for q in sorted({int(env.patch[0]), int(env.patch[3])})])
    np.testing.assert_array_equal(segs, own)
    assert len(segs) < len(env._segments) and len(segs) % 4 == 0
    state = env.bodies.read_state()
    env._replan(idx, state)
    cropped = env.paths[idx].copy()
    env._rollout_segments = lambda _idx: env._segments  # every patch's walls, as before
    try:
        env._replan(idx, state)
    finally:
        del env._rollout_segments
    np.testing.assert_allclose(env.paths[idx], cropped, atol=1e-9)
    # the walls of the own patch do shape the paths: without them the rollout differs somewhere
    env._rollout_segments = lambda _idx: np.zeros((0, 2, 2))
    try:
        env._replan(np.arange(env.num_envs), state)
        bare = env.paths.copy()
        del env._rollout_segments
        env._replan(np.arange(env.num_envs), state)
    finally:
        env.__dict__.pop("_rollout_segments", None)
    assert np.abs(bare - env.paths).max() > 1e-3


@pytest.mark.parametrize("sync", [True, False])
def test_periodic_replans_fall_on_the_env_clock_when_synchronised(sync):
    cfg = PathTaskConfig(stage=3, crowd_prob=1.0, replan_seconds=0.5, episode_seconds=1.0, max_path_error=100.0,
                         replan_sync=sync)
    env = AmpPathEnv(4, locomotion_reference(), cfg, seed=0)
    env.reset(seed=0)
    every = int(round(cfg.replan_seconds * cfg.control_hz))
    zero = np.zeros((4, ACTION_DIM))
    phases = set()
    try:
        for _ in range(3 * every):
            env.step(zero)
            due = env._clock + (env._next_plan - env.t)  # the env clock at each humanoid's next replan
            phases |= set((due % every).tolist())
    finally:
        env.close()
    if sync:
        assert phases == {0}
    else:
        assert len(phases) > 1  # falls and resets put the humanoids out of step


def test_a_planned_partner_is_not_also_a_constant_velocity_obstacle(monkeypatch):
    """Both humanoids of a patch planned in one rollout: each is a simulated person, and neither appears
    again among the constant-velocity others (a copy on its own start would push it away)."""
    import navzoo.agents.amp.path_env as path_env

    cfg = PathTaskConfig(stage=3, crowd_prob=1.0, obstacle_obs=True, boxes_per_patch=0, pair_patches=True)
    env = AmpPathEnv(4, locomotion_reference(), cfg, seed=0)
    env.reset(seed=0)
    seen = []
    real = path_env.sfm_rollout

    def spy(pos, vel, pref, steps, dt, **kw):
        seen.append((np.asarray(pos).copy(), np.asarray(kw["others_pos"]).copy()))
        return real(pos, vel, pref, steps, dt, **kw)

    monkeypatch.setattr(path_env, "sfm_rollout", spy)
    state = env.bodies.read_state()
    try:
        env._replan(np.array([0, 1]), state)  # a pair: no body among the others
        env._replan(np.array([2]), state)  # alone: its partner 3 is a constant-velocity other
    finally:
        env.close()
    (pos_pair, others_pair), (_, others_one) = seen
    d = np.linalg.norm(others_pair[:, None] - pos_pair[None], axis=2)
    assert d.min() > 1e-6
    assert np.isclose(np.linalg.norm(others_one - state["root_pos"][3, :2], axis=1), 0.0).any()
