"""navzoo.envs.amp_humans.corner_steer and NavConfig.amp_corner_margin: exposed corners push the target rollouts
sideways, never back."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.envs.amp_humans import corner_steer

KW = {"a_wall": 1.0, "b_wall": 0.1, "tau": 0.5}


def test_no_margin_or_no_corner_changes_nothing():
    pos, pref = np.array([[0.0, 0.4]]), np.array([[1.0, 0.0]])
    corner = np.array([[0.0, 0.0]])
    np.testing.assert_array_equal(corner_steer(pos, pref, corner, np.array([0.4]), 0.0, **KW), pref)
    np.testing.assert_array_equal(corner_steer(pos, pref, np.zeros((0, 2)), np.array([0.4]), 0.15, **KW), pref)
    far = corner_steer(np.array([[0.0, 1.5]]), pref, corner, np.array([0.4]), 0.15, **KW)  # beyond CORNER_REACH
    np.testing.assert_array_equal(far, pref)


def test_a_corner_steers_sideways_away_from_itself_and_never_brakes():
    corner = np.array([[0.0, 0.0]])
    pref = np.array([[1.0, 0.0], [1.0, 0.0]])
    pos = np.array([[-0.3, 0.45], [-0.3, -0.45]])  # passing left of the corner, and right of it
    out = corner_steer(pos, pref, corner, np.array([0.4, 0.4]), 0.15, **KW)
    np.testing.assert_allclose(np.linalg.norm(out, axis=1), 1.0)  # the preferred speed is kept
    assert out[0, 0] > 0.0 and out[1, 0] > 0.0  # still forward: turned, not sent back
    assert out[0, 1] > 0.0 > out[1, 1]  # away from the corner, to each side
    assert out[0, 1] == pytest.approx(-out[1, 1])
    closer = corner_steer(np.array([[-0.3, 0.35]]), pref[:1], corner, np.array([0.4]), 0.15, **KW)
    assert closer[0, 1] > out[0, 1]  # stronger nearer the corner
    wider = corner_steer(pos[:1], pref[:1], corner, np.array([0.4]), 0.3, **KW)
    assert wider[0, 1] > out[0, 1]  # and with more margin
    standing = corner_steer(pos[:1], np.zeros((1, 2)), corner, np.array([0.4]), 0.15, **KW)
    np.testing.assert_array_equal(standing, np.zeros((1, 2)))


def test_between_two_jambs_the_pushes_centre_the_disc():
    jambs = np.array([[0.0, -0.45], [0.0, 0.45]])  # a 0.9 m door, walked along +x
    pref = np.array([[1.0, 0.0]] * 3)
    pos = np.array([[-0.2, 0.0], [-0.2, 0.1], [-0.2, -0.1]])
    out = corner_steer(pos, pref, jambs, np.full(3, 0.35), 0.15, **KW)
    assert out[0, 1] == pytest.approx(0.0, abs=1e-12)
    assert out[1, 1] < 0.0 < out[2, 1]


def test_the_corner_margin_is_a_config_field_and_widens_the_targets_round_corners():
    from navzoo.envs import amp_humans
    from navzoo.envs.config import NavConfig
    from tests.test_amp_env import DT, _raw

    near = {}
    for margin in (None, 0.2):
        near[margin] = []
        for seed in (1, 2, 3):  # the targets planned at reset, through the home's doors and round its furniture
            env = _raw(n_robots=0, n_humans=5, scene="home", amp_corner_margin=margin)
            env.reset(seed=seed)
            assert env.amp.corner_margin == (amp_humans.CORNER_MARGIN if margin is None else 0.2)
            corners = env.scene.exposed_corners()
            pts = env.amp.paths.reshape(-1, 2)
            near[margin].append(np.linalg.norm(pts[:, None] - corners[None], axis=2).min(axis=1))
            env.close()
    assert np.quantile(np.concatenate(near[0.2]), 0.02) > np.quantile(np.concatenate(near[None]), 0.02) + 0.02
    for bad in (-0.1, float("nan"), float("inf"), True, "0.2"):
        with pytest.raises(ValueError, match="amp_corner_margin must be None or a finite number >= 0"):
            NavConfig(human_model="amp", dt=DT, amp_corner_margin=bad)
