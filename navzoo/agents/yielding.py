"""Turn-taking for rule-based crowds: who yields when people block each other in a bottleneck.

Social force and ORCA are local, reactive models. When two flows meet in a passage that takes one
person at a time (a 0.9 m door, a narrow aisle), the forces balance and everybody stands still in
front of the door for ever: a deadlock that real people resolve by one of them stepping aside and
waiting. Without it, a crowd in a home or at a doorway freezes within a minute (in the ``home`` scene
all five social-force pedestrians stood still from t = 40 s on, docs/crowd_models.md).

:class:`TurnTaking` adds that social convention on top of any crowd model, by changing only the
preferred velocities that the model is given:

* a person is *stuck* when it wants to move (preferred speed above ``min_pref_speed``) but has made
  less than ``stuck_speed`` of progress along its preferred direction for ``patience`` seconds
  (jostling sideways in a jam is no progress);
* two stuck people *conflict* when they are closer than ``reach`` and do not want to go the same way
  (their preferred directions differ by more than ``same_way_deg``);
* in every conflict the person of lower priority yields: it steps back, against its preferred
  direction, at ``back_speed`` for ``back_time`` seconds, then waits in place for ``wait_time``
  seconds, then goes on. Priority: whoever has yielded more often goes first (so nobody yields for
  ever), ties broken by a fixed per-person order.
* with ``hold_max`` > 0 the one who yields also *holds* its wait until the person it yielded to
  (the nearest winner of its conflicts) has passed it or moved away, for at most ``hold_max`` more
  seconds: otherwise a head-on pair in a door can trade yields without either getting through. Its
  wait then ends early, and :meth:`TurnTaking.update` reports that as an event (for replanning).

Everything is deterministic and vectorised over people. The same rules serve kinematic pedestrians
(every control step) and the target trajectories of AMP pedestrians (rolled out ahead in time with
:meth:`TurnTaking.apply` at future times).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["TurnTaking", "YieldParams"]


@dataclass(frozen=True)
class YieldParams:
    """Parameters of :class:`TurnTaking` (defaults chosen on the home and doorway scenes,
    docs/crowd_models.md).

    Attributes:
        patience: seconds a person is stuck before it may yield.
        stuck_speed: below this speed along the preferred direction (m/s) a person makes no progress.
        min_pref_speed: only people who want to move faster than this (m/s) can be stuck.
        reach: stuck people closer than this (centre distance, m) can conflict.
        same_way_deg: people whose preferred directions differ by less than this (degrees) queue
            behind each other instead of conflicting.
        back_speed: speed of the step back (m/s).
        back_time: duration of the step back (s).
        wait_time: time spent waiting in place after the step back (s).
        hold_max: longest extra wait (s) while the person one yielded to has not passed yet; 0: off.
        hold_pass: the other has passed once it is this far (m) beyond the one waiting, along its
            own preferred direction.
    """

    patience: float = 2.0
    stuck_speed: float = 0.15
    min_pref_speed: float = 0.3
    reach: float = 1.6
    same_way_deg: float = 60.0
    back_speed: float = 0.4
    back_time: float = 1.2
    wait_time: float = 1.5
    hold_max: float = 0.0
    hold_pass: float = 0.3

    def __post_init__(self) -> None:
        for name in ("patience", "stuck_speed", "min_pref_speed", "reach", "back_time"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"YieldParams.{name} must be a finite number > 0, got {v!r}")
        for name in ("back_speed", "wait_time", "hold_max", "hold_pass"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ValueError(f"YieldParams.{name} must be a finite number >= 0, got {v!r}")
        if not (isinstance(self.same_way_deg, (int, float)) and 0 <= self.same_way_deg <= 180):
            raise ValueError(f"YieldParams.same_way_deg must be in [0, 180], got {self.same_way_deg!r}")


class TurnTaking:
    """Stuck detection and yielding for ``n`` people (see the module doc).

    Call :meth:`update` once per control step with the people's actual velocities and their preferred
    velocities (from the crowd model's goal term), then give the crowd model ``apply(t, pref)``.
    """

    def __init__(self, n: int, params: YieldParams | None = None) -> None:
        self.params = params or YieldParams()
        self.n = int(n)
        self.stuck_time = np.zeros(self.n)
        self.yields = np.zeros(self.n, dtype=int)
        self.back_until = np.full(self.n, -np.inf)
        self.wait_until = np.full(self.n, -np.inf)
        self.back_dir = np.zeros((self.n, 2))
        self.partner = np.full(self.n, -1)  # whom a holding person yielded to (-1: none)
        self.hold_until = np.full(self.n, -np.inf)
        # Fixed tie-break order: a permutation that does not favour low indices.
        self._order = (np.arange(self.n) * 7919) % max(self.n, 1) if self.n else np.zeros(0, dtype=int)

    def yielding(self, t: float) -> np.ndarray:
        """(n,) bool: who is stepping back, waiting or holding at time ``t``."""
        return t < np.maximum(self.wait_until, self.hold_until)

    def update(self, t: float, dt: float, pos: np.ndarray, vel: np.ndarray, pref: np.ndarray,
               active: np.ndarray | None = None) -> np.ndarray:
        """Advance the stuck timers by ``dt`` and start new yields at time ``t``.

        Args:
            t: current time (s).
            dt: time since the last update (s).
            pos, vel, pref: (n, 2) positions, actual velocities and preferred velocities (the goal
                term, before :meth:`apply`).
            active: (n,) bool, who takes part (e.g. not fallen); default everybody.

        Returns:
            (n,) bool: who started yielding now, or stopped holding early (the other passed).
        """
        p = self.params
        active = np.ones(self.n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        pref_speed = np.linalg.norm(pref, axis=1)
        u_all = pref / np.maximum(pref_speed, 1e-9)[:, None]
        released = self._release_holds(t, pos, u_all, active)
        progress = (vel * u_all).sum(axis=1)  # speed toward where one wants to go (jostling sideways is none)
        busy = self.yielding(t)
        stuck_now = active & ~busy & (progress < p.stuck_speed) & (pref_speed > p.min_pref_speed)
        self.stuck_time = np.where(stuck_now, self.stuck_time + dt, 0.0)
        stuck = self.stuck_time >= p.patience
        started = np.zeros(self.n, dtype=bool)
        if stuck.sum() < 2:
            return started | released
        idx = np.flatnonzero(stuck)
        d = np.linalg.norm(pos[idx, None, :] - pos[None, idx, :], axis=2)
        u = u_all[idx]
        conflict = (d < p.reach) & (u @ u.T < math.cos(math.radians(p.same_way_deg)))
        np.fill_diagonal(conflict, False)
        prio = self.yields[idx] * (self.n + 1) + self._order[idx]
        loses = (conflict & (prio[None, :] > prio[:, None])).any(axis=1)
        who = idx[loses]
        if who.size:
            started[who] = True
            self.yields[who] += 1
            self.back_until[who] = t + p.back_time
            self.wait_until[who] = t + p.back_time + p.wait_time
            self.back_dir[who] = -u[loses]
            self.stuck_time[who] = 0.0
            if p.hold_max > 0:
                # the nearest person each loser conflicts with and yields to
                beaten = conflict & (prio[None, :] > prio[:, None])  # the ones it loses to
                dist = np.where(beaten, d, np.inf)[loses]
                self.partner[who] = idx[np.argmin(dist, axis=1)]
                self.hold_until[who] = self.wait_until[who] + p.hold_max
        return started | released

    def _release_holds(self, t: float, pos: np.ndarray, u_all: np.ndarray, active: np.ndarray) -> np.ndarray:
        """End the holds whose other person has passed, moved away, stopped taking part, or whose
        ``hold_max`` ran out; returns who was released before the end of its hold."""
        released = np.zeros(self.n, dtype=bool)
        holders = np.flatnonzero(self.partner >= 0)
        if not holders.size:
            return released
        j = self.partner[holders]
        gap = pos[j] - pos[holders]
        passed = (gap * u_all[j]).sum(axis=1) > self.params.hold_pass
        away = np.linalg.norm(gap, axis=1) > 1.5 * self.params.reach
        over = t >= self.hold_until[holders]
        end = passed | away | ~active[j] | ~active[holders] | over
        done = holders[end]
        early = done[t < self.hold_until[done]]
        # a hold ends, the step back and the plain wait keep their times
        self.hold_until[done] = -np.inf
        self.partner[done] = -1
        released[early] = t >= self.wait_until[early]  # only a wait that was being extended changes anything
        return released

    def apply(self, t: float | np.ndarray, pref: np.ndarray) -> np.ndarray:
        """Preferred velocities (n, 2) at time ``t`` (scalar or per person) with the yields applied:
        stepping back, then zero while waiting, else ``pref`` unchanged."""
        t = np.broadcast_to(np.asarray(t, dtype=float), (self.n,))
        back = (t < self.back_until)[:, None]
        wait = (t < np.maximum(self.wait_until, self.hold_until))[:, None]
        return np.where(back, self.params.back_speed * self.back_dir, np.where(wait, 0.0, pref))
