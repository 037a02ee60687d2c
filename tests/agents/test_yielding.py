"""Turn-taking (navzoo.agents.yielding): deadlocks at a door resolve, queues do not yield, fairness."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.policy import preferred_velocity
from navzoo.agents.sfm import SocialForceParams, social_force_velocities
from navzoo.agents.yielding import TurnTaking, YieldParams

# A wall along x = 0 with a 0.8 m door (y in [-0.4, 0.4]).
WALL = np.array([[[0.0, -5.0], [0.0, -0.4]], [[0.0, 0.4], [0.0, 5.0]]])


def _door_crossing(yielding: bool, seconds: float = 40.0, dt: float = 0.1,
                   yield_params: YieldParams | None = None) -> tuple[np.ndarray, float | None]:
    """Two people meeting head-on in the door; returns final positions and when both had passed."""
    pos = np.array([[-1.0, 0.02], [1.0, -0.02]])
    vel = np.zeros((2, 2))
    goal = np.array([[4.0, 0.0], [-4.0, 0.0]])
    v_pref = np.array([1.2, 1.2])
    tt = TurnTaking(2, yield_params) if yielding else None
    params = SocialForceParams()
    t = 0.0
    for _ in range(int(seconds / dt)):
        # Each aims at the door centre first, then at its goal (an A* path through the door).
        before = np.sign(pos[:, 0]) == -np.sign(goal[:, 0])
        wp = np.where(before[:, None] & (np.abs(pos[:, 0]) > 0.3)[:, None], np.zeros((2, 2)), goal)
        pref = preferred_velocity(pos, wp, goal, v_pref)
        if tt is not None:
            pref = tt.apply(t, pref)
        vel = social_force_velocities(pos, vel, pref, 0.3, 2.0, dt, params, WALL)
        pos = pos + dt * vel
        t += dt
        if tt is not None:
            base = preferred_velocity(pos, wp, goal, v_pref)
            tt.update(t, dt, pos, vel, base)
        if pos[0, 0] > 1.0 and pos[1, 0] < -1.0:
            return pos, t
    return pos, None


def test_head_on_at_a_door_deadlocks_without_turn_taking():
    pos, passed = _door_crossing(yielding=False)
    assert passed is None, "social force alone should deadlock here (else this test checks nothing)"
    assert np.all(np.abs(pos[:, 0]) < 1.5)


def test_turn_taking_resolves_the_door_deadlock():
    pos, passed = _door_crossing(yielding=True)
    assert passed is not None and passed < 20.0, (pos, passed)


def test_people_going_the_same_way_queue_instead_of_yielding():
    tt = TurnTaking(2, YieldParams(patience=0.5))
    pos = np.array([[0.0, 0.0], [-0.7, 0.0]])
    pref = np.array([[1.0, 0.0], [1.0, 0.0]])
    for k in range(20):
        started = tt.update(0.1 * (k + 1), 0.1, pos, np.zeros((2, 2)), pref)
        assert not started.any()
    assert np.all(tt.stuck_time >= 0.5)


def test_lower_priority_yields_steps_back_then_waits_and_priority_rotates():
    p = YieldParams(patience=0.5, back_time=1.0, wait_time=1.0, back_speed=0.4)
    tt = TurnTaking(2, p)
    pos = np.array([[-0.4, 0.0], [0.4, 0.0]])
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    t, started = 0.0, np.zeros(2, dtype=bool)
    while not started.any():
        t += 0.1
        started = tt.update(t, 0.1, pos, np.zeros((2, 2)), pref)
    assert started.sum() == 1, "exactly one of two people in a conflict yields"
    loser = int(np.flatnonzero(started)[0])
    out = tt.apply(t + 0.5, pref)
    np.testing.assert_allclose(out[loser], -0.4 * pref[loser])  # stepping back
    np.testing.assert_allclose(out[1 - loser], pref[1 - loser])  # the other goes on
    np.testing.assert_allclose(tt.apply(t + 1.5, pref)[loser], 0.0)  # waiting
    np.testing.assert_allclose(tt.apply(t + 2.5, pref)[loser], pref[loser])  # back on its way
    # Next conflict: the one who yielded has priority now.
    t += 2.5
    started[:] = False
    while not started.any():
        t += 0.1
        started = tt.update(t, 0.1, pos, np.zeros((2, 2)), pref)
    assert int(np.flatnonzero(started)[0]) == 1 - loser


def test_inactive_people_never_yield_and_params_are_validated():
    tt = TurnTaking(2, YieldParams(patience=0.2))
    pos = np.array([[-0.4, 0.0], [0.4, 0.0]])
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    for k in range(10):
        assert not tt.update(0.1 * k, 0.1, pos, np.zeros((2, 2)), pref, active=np.array([True, False])).any()
    with pytest.raises(ValueError, match="patience"):
        YieldParams(patience=0.0)
    with pytest.raises(ValueError, match="same_way_deg"):
        YieldParams(same_way_deg=270.0)


def _first_yield(tt: TurnTaking, pos: np.ndarray, pref: np.ndarray) -> tuple[float, int]:
    t, started = 0.0, np.zeros(2, dtype=bool)
    while not started.any():
        t += 0.1
        started = tt.update(t, 0.1, pos, np.zeros((2, 2)), pref)
    return t, int(np.flatnonzero(started)[0])


def test_a_yielder_holds_until_the_other_has_passed():
    p = YieldParams(patience=0.5, back_time=1.0, wait_time=1.0, hold_max=5.0, hold_pass=0.3)
    tt = TurnTaking(2, p)
    pos = np.array([[-0.4, 0.0], [0.4, 0.0]])
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    t, loser = _first_yield(tt, pos, pref)
    winner = 1 - loser
    assert tt.partner[loser] == winner
    # past the plain wait, the other has not passed yet: the yielder still waits (and its rollouts wait too)
    for _ in range(25):
        t += 0.1
        assert not tt.update(t, 0.1, pos, np.zeros((2, 2)), pref)[loser]
    np.testing.assert_allclose(tt.apply(t, pref)[loser], 0.0)
    np.testing.assert_allclose(tt.apply(t + 2.0, pref)[loser], 0.0)  # the hold shapes the rollout ahead
    assert tt.yielding(t)[loser]
    # the other walks past the yielder: the hold ends now, reported as an event
    moved = pos.copy()
    moved[winner] = pos[loser] + 0.5 * pref[winner]
    t += 0.1
    released = tt.update(t, 0.1, moved, np.zeros((2, 2)), pref)
    assert released[loser] and tt.partner[loser] == -1
    np.testing.assert_allclose(tt.apply(t, pref)[loser], pref[loser])


def test_a_hold_ends_after_hold_max_and_is_off_by_default():
    p = YieldParams(patience=0.5, back_time=1.0, wait_time=1.0, hold_max=1.0)
    tt = TurnTaking(2, p)
    pos = np.array([[-0.4, 0.0], [0.4, 0.0]])
    pref = np.array([[1.0, 0.0], [-1.0, 0.0]])
    t0, loser = _first_yield(tt, pos, pref)
    np.testing.assert_allclose(tt.apply(t0 + 2.5, pref)[loser], 0.0)  # held past the plain wait
    np.testing.assert_allclose(tt.apply(t0 + 3.1, pref)[loser], pref[loser])  # but not past hold_max
    t = t0
    while t < t0 + 3.2:
        t += 0.1
        tt.update(t, 0.1, pos, np.zeros((2, 2)), pref, active=np.array([loser == 0, loser == 1]))
    assert tt.partner[loser] == -1
    plain = TurnTaking(2, YieldParams(patience=0.5, back_time=1.0, wait_time=1.0))
    t0, loser = _first_yield(plain, pos, pref)
    assert plain.partner[loser] == -1
    np.testing.assert_allclose(plain.apply(t0 + 2.1, pref)[loser], pref[loser])
    with pytest.raises(ValueError, match="hold_max"):
        YieldParams(hold_max=-1.0)


def test_holding_gets_a_head_on_pair_through_the_door():
    pos, passed = _door_crossing(yielding=True, yield_params=YieldParams(hold_max=6.0))
    assert passed is not None and passed < 20.0, (pos, passed)
