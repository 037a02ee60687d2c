"""The target rollouts of physics pedestrians toward diffusion plans walk with NavConfig.diffusion_walker."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs import amp_humans
from tests.fixed_plans import straight_plans


def _meeting_rollouts(walker: str, monkeypatch, **config) -> tuple[np.ndarray, np.ndarray]:
    """Two bodies whose plans lead straight through each other at 1 m/s: their rolled-out target paths."""
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", crowd_model="diffusion",
                 diffusion_walker=walker, dt=1 / 30, time_limit=10.0, **config)
    env.reset(seed=0)
    amp, crowd = env.amp, env.diffusion
    crowd.plan_now(env)
    pos = amp.planar()[0]
    toward = pos[::-1] - pos
    toward /= np.linalg.norm(toward, axis=1, keepdims=True)
    straight_plans(monkeypatch, crowd, pos, 1.0 * toward)
    amp.plan_all()
    paths = amp.paths.copy()
    env.close()
    return paths, pos


@pytest.mark.parametrize("walker", ["orca", "hybrid"])
def test_orca_walked_targets_keep_the_planning_discs_apart(walker, monkeypatch):
    paths, pos = _meeting_rollouts(walker, monkeypatch)
    gap = np.linalg.norm(paths[0] - paths[1], axis=1)
    assert gap[0] == pytest.approx(np.linalg.norm(pos[0] - pos[1]))  # the rollouts start at the bodies
    # ORCA passes with the discs (0.3 m + the 0.1 m planning margin) just touching; social force with the pass
    # margin keeps more room between people who meet (why the bodies touch more with ORCA-walked targets)
    assert gap.min() > 2 * (0.3 + amp_humans.PLAN_MARGIN) - 0.02
    sfm, _ = _meeting_rollouts("sfm", monkeypatch)
    assert np.linalg.norm(sfm[0] - sfm[1], axis=1).min() > gap.min() + 0.1
    # each ends up past the meeting point, on the other's side: the two pass rather than stand face to face
    mid = 0.5 * (pos[0] + pos[1])
    passed = [np.dot(paths[j, -1] - mid, pos[j] - mid) < 0 for j in range(2)]
    assert all(passed)


def test_a_stronger_keep_right_gain_turns_the_social_force_rollouts_aside_earlier(monkeypatch):
    def meeting(bias: float) -> tuple[int, float]:
        """When the first body's rollout is 0.2 m off the line between the two (control step; -1: never), and
        how close the two rollouts come."""
        monkeypatch.setattr(amp_humans, "SFM_SIDE_BIAS", bias)
        paths, pos = _meeting_rollouts("sfm", monkeypatch)
        axis = (pos[1] - pos[0]) / np.linalg.norm(pos[1] - pos[0])
        off = np.abs((paths[0] - pos[0]) @ np.array([-axis[1], axis[0]]))
        aside = np.flatnonzero(off > 0.2)
        return (int(aside[0]) if aside.size else -1), float(np.linalg.norm(paths[0] - paths[1], axis=1).min())

    assert amp_humans.SFM_SIDE_BIAS == 0.4  # the default since 2026-12-06 (the kinematic crowd keeps 0.1)
    (t0, gap0), (t1, gap1), (t4, gap4) = meeting(0.0), meeting(0.1), meeting(0.4)
    assert t0 == -1  # no tie-break: a perfectly head-on pair brakes and stands face to face
    assert 0 < t4 < t1 and gap4 > gap1 > gap0  # the stronger gain steps aside earlier and passes wider


def test_the_keep_right_gain_is_a_config_field(monkeypatch):
    """``NavConfig.amp_side_bias`` sets the gain of both social-force parameter sets of the target rollouts (None: the
    module's SFM_SIDE_BIAS) and gives the same rollouts as the constant; bad values are refused by name."""
    from navzoo.envs.config import NavConfig

    by_field, _ = _meeting_rollouts("sfm", monkeypatch, amp_side_bias=0.4)
    monkeypatch.setattr(amp_humans, "SFM_SIDE_BIAS", 0.4)
    by_constant, _ = _meeting_rollouts("sfm", monkeypatch)
    np.testing.assert_allclose(by_field, by_constant)
    monkeypatch.setattr(amp_humans, "SFM_SIDE_BIAS", 0.1)
    assert not np.allclose(by_field, _meeting_rollouts("sfm", monkeypatch)[0])
    np.testing.assert_allclose(_meeting_rollouts("sfm", monkeypatch, amp_side_bias=0.4)[0], by_field)
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene="circle_crossing", n_robots=0, n_humans=2, human_model="amp", amp_side_bias=0.25)
    assert env.amp.sfm.side_bias == env.amp.sfm_keep.side_bias == 0.25
    env.close()
    for bad in (-0.1, float("nan"), float("inf"), True, "0.4"):
        with pytest.raises(ValueError, match="amp_side_bias must be None or a finite number >= 0"):
            NavConfig(human_model="amp", amp_side_bias=bad)


def test_the_keep_right_gain_near_narrow_doors(monkeypatch):
    """Within ``amp_side_narrow_reach`` of a narrow point of its A* path a person of the social-force target rollouts
    keeps right with ``amp_side_bias_narrow``: in the doorway (every path passes its 1.0 m door), a reach that covers
    the whole scene gives the rollouts of that gain everywhere, reach 0 (or the same gain near doors) those of
    ``amp_side_bias`` everywhere, and the default reach (1.5 m) or a 1 m reach something between (each person switches
    gain where it comes near the door); bad values are refused by name."""
    from navzoo.envs.config import NavConfig
    from navzoo.envs.nav_env import NavEnv

    def rollouts(**config) -> np.ndarray:
        env = NavEnv(scene="doorway", n_robots=0, n_humans=6, human_model="amp", crowd_model="sfm", dt=1 / 30,
                     time_limit=10.0, **config)
        env.reset(seed=0)
        h = np.flatnonzero(~env.is_robot)
        assert all(len(pts) for pts, _ in env.amp.narrow_passages([env.paths[i] for i in h], env.radius[h]))
        env.amp.plan_all()
        paths = env.amp.paths.copy()
        env.close()
        return paths

    assert amp_humans.SFM_SIDE_NARROW_REACH == 1.5 and amp_humans.SFM_SIDE_BIAS_NARROW == 0.1  # the defaults
    default = rollouts(amp_side_narrow_reach=0.0)  # the gain 0.4 everywhere
    low = rollouts(amp_side_bias=0.1)
    assert np.abs(default - low).max() > 0.01  # the gain matters in this scene
    np.testing.assert_array_equal(rollouts(amp_side_bias_narrow=0.4), default)  # the same gain near doors: no switch
    assert np.abs(rollouts() - default).max() > 1e-3  # by default the gain near the door is 0.1
    np.testing.assert_array_equal(rollouts(amp_side_narrow_reach=100.0), low)  # narrow gain 0.1 (the constant)
    np.testing.assert_array_equal(rollouts(amp_side_narrow_reach=100.0, amp_side_bias_narrow=0.4), default)
    near_door = rollouts(amp_side_narrow_reach=1.0)
    assert np.abs(near_door - default).max() > 1e-3 and np.abs(near_door - low).max() > 1e-3
    monkeypatch.setattr(amp_humans, "SFM_SIDE_NARROW_REACH", 100.0)  # the constants where the fields are None
    monkeypatch.setattr(amp_humans, "SFM_SIDE_BIAS_NARROW", 0.1)
    np.testing.assert_array_equal(rollouts(), low)
    # the rule's doors are those of the default wall margin: a wider amp_wall_margin finds more narrow points (grocery
    # aisles) for its graded margin, not more doors for the keep-right rule
    def narrow_counts(**config) -> tuple[int, int]:
        env = NavEnv(scene="grocery", n_robots=0, n_humans=6, human_model="amp", dt=1 / 30, time_limit=10.0, **config)
        env.reset(seed=1)
        h = np.flatnonzero(~env.is_robot)
        paths, radius = [env.paths[i] for i in h], env.radius[h]
        counts = (sum(len(p) for p, _ in env.amp.narrow_passages(paths, radius)),
                  sum(len(p) for p, _ in env.amp.narrow_passages(paths, radius, amp_humans.WALL_PLAN_MARGIN)))
        env.close()
        return counts

    default_graded, default_doors = narrow_counts()
    wide_graded, wide_doors = narrow_counts(amp_wall_margin=0.25)
    assert default_graded == default_doors == wide_doors < wide_graded
    for name in ("amp_side_narrow_reach", "amp_side_bias_narrow"):
        for bad in (-0.1, float("nan"), float("inf"), True, "1.0"):
            with pytest.raises(ValueError, match=f"{name} must be None or a finite number >= 0"):
                NavConfig(human_model="amp", **{name: bad})
