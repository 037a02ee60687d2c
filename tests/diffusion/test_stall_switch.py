"""The hybrid diffusion walker's switch: who ORCA holds still walks with social force for a while."""

from __future__ import annotations

import numpy as np
import pytest

from navzoo.agents.diffusion.crowd import StallSwitch

DT = 0.1


def run(switch: StallSwitch, v_orca: np.ndarray, pref: np.ndarray, steps: int, t0: float = 0.0) -> list[np.ndarray]:
    return [switch.update(t0 + k * DT, DT, v_orca, pref) for k in range(steps)]


def test_a_person_held_still_switches_after_patience_and_back_after_hold():
    sw = StallSwitch(3, stall_frac=0.3, min_pref=0.3, patience=1.0, hold=2.0)
    pref = np.array([[1.0, 0.0], [1.0, 0.0], [0.0, 0.0]])
    v = np.array([[0.0, 0.0], [0.5, 0.0], [0.0, 0.0]])  # 0 held still, 1 slowed but moving, 2 wants to stand
    use = np.array(run(sw, v, pref, 20))
    first = int(np.argmax(use[:, 0]))
    assert 9 <= first <= 10  # 1 s of stalled steps at 0.1 s
    assert use[first:, 0].all() and not use[:, 1].any() and not use[:, 2].any()
    # ORCA frees the person: social force for `hold` s after the last stalled-long-enough step, then ORCA again
    last_t = sw.last_t
    free = np.array([sw.update(last_t + (k + 1) * DT, DT, pref.copy(), pref) for k in range(30)])
    assert free[:19, 0].all() and not free[21:, 0].any()


def test_stalled_time_restarts_when_orca_lets_the_person_move():
    sw = StallSwitch(1, patience=1.0)
    pref = np.array([[1.2, 0.0]])
    for k in range(30):  # stalled 0.8 s, free 0.1 s, again and again: never 1 s in a row
        v = pref if k % 9 == 8 else np.zeros((1, 2))
        assert not sw.update(k * DT, DT, v, pref).any()


def test_repeated_and_earlier_times():
    sw = StallSwitch(1, patience=0.5)
    pref, v = np.array([[1.0, 0.0]]), np.zeros((1, 2))
    run(sw, v, pref, 5)
    before = sw.stalled_s.copy()
    sw.update(sw.last_t, DT, v, pref)  # the same step asked twice: the timers do not move
    np.testing.assert_allclose(sw.stalled_s, before)
    assert run(sw, v, pref, 2, t0=0.5)[-1].all()
    assert not sw.update(0.0, DT, v, pref).any() and sw.stalled_s[0] == pytest.approx(DT)  # a new episode


def test_bad_settings_and_shapes_are_refused():
    with pytest.raises(ValueError, match="patience"):
        StallSwitch(2, patience=float("nan"))
    with pytest.raises(ValueError, match="stall_frac"):
        StallSwitch(2, stall_frac=-0.1)
    with pytest.raises(ValueError, match=r"2 people.*\(3, 2\)"):
        StallSwitch(2).update(0.0, DT, np.zeros((3, 2)), np.zeros((2, 2)))
