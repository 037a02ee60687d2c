"""Door turns for rule-based crowds: one direction at a time through doors that take one person at a time.

:class:`~navzoo.agents.yielding.TurnTaking` resolves a head-on meeting in a door after it has happened:
two people stand stuck for ``patience`` seconds, one steps back and waits. In a door crossed from both
sides all the time (the ``doorway`` scene: 13 people and one 1.0 m door) that costs about five seconds
per meeting, and people keep walking into the door from both sides, so most trips time out
(docs/crowd_models.md). People at a real door look first: whoever sees someone coming through waits
beside the door, and those going the same way follow each other through.

:class:`DoorTurns` adds that convention by editing the preferred velocities a crowd model is given, as
turn-taking does:

* **doors** are the short narrow passages of the people's A* paths
  (:func:`navzoo.envs.doors.path_doors`); each person knows the doors of its path in order, and which
  way it crosses each;
* a person within ``approach`` of the next door on its path, not yet through it, **asks** for it. The
  door is **granted** when nobody holds it, or when those who hold it go the same way (people then
  follow each other through), unless somebody on the other side has waited ``platoon_s`` or longer:
  then the door changes direction once those inside are through. Requests are served first come,
  first served;
* a person who asks and is not granted **waits** in a queue of spots beside the door on its own side
  (:meth:`DoorTurns.spots`: ``wait`` back from the door's centre along its axis, ``side_step`` or more
  to the waiting person's right so that people coming through pass on its left), and comes forward as
  the queue moves, until its turn comes;
* a grant ends when its holder is ``passed`` beyond the door's centre, stops taking part (fell,
  arrived), gets a new path, or has held it ``grant_max_s`` seconds without getting through (it then
  asks again, last in the queue), so a person stuck elsewhere does not close a door for good (with
  ``DoorParams.grant_stall_s``, also when its holder has not come closer to the door for that long while
  someone else asks for it; off by default, ``amp_humans.DOOR_GRANT_STALL_S`` for AMP pedestrians);
* someone already in a door (within ``throat`` of its centre) holds it, granted or not, and so does
  one who asks from a side with no waiting spot out of the door's lane (a door off a narrow corridor,
  where a waiting person would block the corridor): the other side waits for it. With
  ``DoorParams.no_room_waits`` the latter takes the door only while nobody holds it the other way, and else
  stops ``wait`` short of it, in the corridor (off by default; ``amp_humans.DOOR_NO_ROOM_WAITS`` for AMP
  pedestrians);
* with ``DoorParams.line_up``, a holder still before its door and too far to the side of the door's axis for a
  straight way into it (outside a cone round the axis) heads first for a point on the axis before the door (off by
  default; ``amp_humans.DOOR_LINE_UP`` for AMP pedestrians).

Everything is deterministic and vectorised over people where it matters. Kinematic pedestrians get
the edited preferred velocity at every step; the target rollouts of AMP pedestrians apply it at the
rolled-out positions (the grants frozen at the time of the plan: a person who will reach a door that
is held against it waits there), and a new grant triggers a replan. ``NavConfig.human_door_turns``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["DoorParams", "DoorTurns"]

# DoorParams.spot_passage_only: a narrow point on the way back to a waiting spot is a passage when both points
# PASSAGE_PROBE_M to either side of it across the door's axis are within PASSAGE_WALL_M of an obstacle (m)
PASSAGE_PROBE_M = 0.6
PASSAGE_WALL_M = 0.3


@dataclass(frozen=True)
class DoorParams:
    """Parameters of :class:`DoorTurns` (chosen on the ``doorway`` and ``home`` scenes, docs/crowd_models.md).

    Attributes:
        approach: a person asks for the next door on its path within this distance of its centre (m).
        wait: the waiting spot's distance from the door's centre along the door's axis (m).
        side_step: the waiting spot's offset to the waiting person's right (m).
        passed: a person is through a door once it is this far beyond the centre along its crossing (m).
        throat: a person within this distance of a door's centre, not yet through, is in the door (m).
        platoon_s: no new grant the door's current way once somebody on the other side has waited this long (s).
        grant_max_s: a grant that has not got its holder through within this long ends (s).
        grant_stall_s: a grant whose holder has not come ``grant_stall_gain`` closer to the door's centre within
            this long ends while someone else asks for the door (s; None: off, grants end only by
            ``grant_max_s``). The holder asks anew, last in the queue.
        grant_stall_gain: how much closer to the door's centre (m) counts as coming on, for ``grant_stall_s``.
        merge: doors found on different paths whose centres are closer than this are one door (m).
        spot_clearance: the waiting spot keeps at least this distance from walls (m).
        no_room_waits: a person coming from a side with no waiting spot (a door off a narrow passage) takes the
            door at once only while nobody holds it the other way; otherwise it stops ``wait`` from the door's
            centre, in the passage, until the door is free (False: it always takes the door at once, so the
            passage stays clear and the two ways may meet in the door).
        spot_passage_only: the way back to a waiting spot is refused for running into a second narrow passage
            (:meth:`DoorTurns.spots`) only where the narrow point has obstacles within ``PASSAGE_WALL_M`` of both
            points ``PASSAGE_PROBE_M`` to either side of it across the door's axis (a door across a corridor), not
            where one piece of furniture stands beside the way (False: any point under 0.5 m from an obstacle after
            the way got out in the open refuses the spot; the home's kitchen door then has no waiting spot on its
            living-room side, beside the dining table, and people from there always take it at once).
        passed_lateral: a person counts as through a door (``passed`` beyond its centre) only while it is within this
            distance of the door's axis line (m; None: anywhere beside the door, the default). Without it, a person
            pushed a metre aside, to where the door's far side lies along the axis, is taken as through a door it has
            not crossed: it stops asking for that door and holds the next one on its route instead.
        line_up: a person who holds its next door and is still before it heads first for the door's axis when it
            lies more than this times its distance before the door's centre to either side of the axis (a slope; None:
            off, the default). It then walks toward the point ``line_up_back`` before the centre on the axis until it
            is inside that cone, and from there as its own velocity says. Without it a holder that comes off its
            waiting spot (``wait`` back, ``side_step`` aside: a slope of about 0.7) heads for the door's middle on a
            line that meets the wall beside the opening, and a physics body stands pressed against that wall.
        line_up_back: how far before the door's centre, on its axis, the line-up point lies (m).
    """

    approach: float = 2.5
    wait: float = 1.4
    side_step: float = 1.0
    passed: float = 0.5
    throat: float = 0.6
    platoon_s: float = 10.0
    grant_max_s: float = 10.0
    grant_stall_s: float | None = None
    grant_stall_gain: float = 0.3
    merge: float = 0.6
    spot_clearance: float = 0.35
    no_room_waits: bool = False
    spot_passage_only: bool = False
    passed_lateral: float | None = None
    line_up: float | None = None
    line_up_back: float = 1.0

    def __post_init__(self) -> None:
        for name in ("approach", "wait", "passed", "throat", "platoon_s", "grant_max_s", "grant_stall_gain", "merge",
                     "spot_clearance", "line_up_back"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ValueError(f"DoorParams.{name} must be a finite number > 0, got {v!r}")
        v = self.grant_stall_s
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"DoorParams.grant_stall_s must be None (off) or a finite number > 0, got {v!r}")
        v = self.passed_lateral
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"DoorParams.passed_lateral must be None (off) or a finite number > 0, got {v!r}")
        v = self.line_up
        if v is not None and not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
            raise ValueError(f"DoorParams.line_up must be None (off) or a finite slope > 0, got {v!r}")
        if not (isinstance(self.side_step, (int, float)) and math.isfinite(self.side_step) and self.side_step >= 0):
            raise ValueError(f"DoorParams.side_step must be a finite number >= 0, got {self.side_step!r}")
        if self.wait >= self.approach:
            raise ValueError(f"DoorParams.wait ({self.wait}) must be below approach ({self.approach}): people ask "
                             "for a door before they reach its waiting spot")
        if self.throat >= self.wait:
            raise ValueError(f"DoorParams.throat ({self.throat}) must be below wait ({self.wait})")


class DoorTurns:
    """Door requests, grants and waiting spots for ``n`` people (see the module doc).

    Args:
        n: number of people.
        distance_at: ``(M, 2) points -> (M,)`` distance to the nearest obstacle (m), e.g.
            :meth:`navzoo.world.occupancy.OccupancyGrid.distance_at`; places the waiting spots.
        params: :class:`DoorParams`.

    Per step: :meth:`set_route` for every person whose path changed, then :meth:`update`, then
    :meth:`apply` on the preferred velocities.
    """

    def __init__(self, n: int, distance_at, params: DoorParams | None = None) -> None:
        self.params = params or DoorParams()
        self.n = int(n)
        self._distance_at = distance_at
        self.centres = np.zeros((0, 2))
        self.axes = np.zeros((0, 2))  # canonical axis of each door
        self._spots: list[dict[int, np.ndarray]] = []  # per door: {sign of the crossing: waiting spots}
        self.routes: list[list[tuple[int, int]]] = [[] for _ in range(self.n)]  # (door, +-1 along its axis)
        self.k = np.zeros(self.n, dtype=int)  # index of each person's next door in its route
        self.granted = np.full(self.n, -1)  # the door each person holds (-1: none)
        self.grant_t = np.full(self.n, -np.inf)
        # for grant_stall_s: the holder's closest distance to its door so far (by grant_stall_gain steps) and when
        self.close_d = np.full(self.n, np.inf)
        self.close_t = np.full(self.n, -np.inf)
        self.request_t = np.full(self.n, np.inf)  # since when each person has asked (inf: not asking)
        self._cur = np.full(self.n, -1)  # next door after the last update (-1: none)
        self._sign = np.zeros(self.n, dtype=int)

    # ------------------------------------------------------------------ doors and routes
    @property
    def n_doors(self) -> int:
        return len(self.centres)

    def door_id(self, centre: np.ndarray, axis: np.ndarray) -> tuple[int, int]:
        """The door at ``centre`` (registered on first sight) and the sign of a crossing along ``axis``."""
        centre = np.asarray(centre, dtype=np.float64).reshape(2)
        axis = np.asarray(axis, dtype=np.float64).reshape(2)
        if self.n_doors:
            d = np.linalg.norm(self.centres - centre, axis=1)
            i = int(np.argmin(d))
            if d[i] < self.params.merge:
                return i, 1 if float(axis @ self.axes[i]) >= 0 else -1
        self.centres = np.concatenate([self.centres, centre[None]])
        self.axes = np.concatenate([self.axes, axis[None] / max(float(np.linalg.norm(axis)), 1e-12)])
        self._spots.append({})
        return self.n_doors - 1, 1

    def set_route(self, j: int, doors: list[tuple[np.ndarray, np.ndarray]]) -> None:
        """Person ``j``'s new path crosses ``doors`` (centre, axis along the crossing), in this order; any
        grant or request it had ends."""
        self.routes[j] = [self.door_id(c, a) for c, a in doors]
        self.k[j] = 0
        self._release(np.array([j]))

    def spots(self, door: int, sign: int) -> np.ndarray:
        """Waiting spots (S, 2) of ``door`` for people crossing it with ``sign``, in queue order. They lie on
        the side the people come from, out of the door's lane: ``wait`` back from the centre along the
        axis and ``side_step`` or more to the waiting person's right (so people coming through pass on its
        left), the queue going on along the wall, then further back, then to the left; only spots
        ``spot_clearance`` from walls."""
        spots = self._spots[door]
        if sign not in spots:
            p = self.params
            c, u = self.centres[door], sign * self.axes[door]  # u: the way the waiting person will go
            right = np.array([u[1], -u[0]])
            gap = 0.7  # m between queued people
            grid = [(along, side * lat)
                    for side in (1.0, -1.0)
                    for along in (p.wait, p.wait + gap, p.wait + 2 * gap)
                    for lat in p.side_step + gap * np.arange(6)]
            along = np.array([g[0] for g in grid])[:, None]
            lat = np.array([g[1] for g in grid])[:, None]
            axis_pt = c[None, :] - along * u[None, :]
            arr = axis_pt + lat * right[None, :]
            ok = self._distance_at(arr) >= p.spot_clearance
            # reached from the door's mouth straight back along the axis, then sideways, without touching a
            # wall: on the door's own side, not seen through a wall or through another door
            mouth = c - p.throat * u
            f = np.linspace(0.0, 1.0, 12)[None, :, None]
            back = mouth[None, None, :] + f * (axis_pt[:, None, :] - mouth[None, None, :])
            aside = axis_pt[:, None, :] + f * (arr[:, None, :] - axis_pt[:, None, :])
            legs = np.concatenate([back, aside], axis=1)
            d_legs = self._distance_at(legs.reshape(-1, 2)).reshape(len(arr), -1)
            ok &= (d_legs > 0.15).all(axis=1)
            # and the way back does not run into a second narrow passage (doors facing each other across a
            # corridor): once out in the open (0.55 m from walls), it stays 0.5 m from them
            d_back = d_legs[:, : back.shape[1]]
            out_in_open = np.maximum.accumulate(d_back > 0.55, axis=1)
            narrow_again = out_in_open & (d_back < 0.5)
            if p.spot_passage_only and narrow_again.any():  # ... a passage: obstacles close on both sides
                pts = back.reshape(-1, 2)
                lat = PASSAGE_PROBE_M * right
                both = (self._distance_at(pts + lat) < PASSAGE_WALL_M) & (self._distance_at(pts - lat) < PASSAGE_WALL_M)
                narrow_again &= both.reshape(d_back.shape)
            ok &= ~narrow_again.any(axis=1)
            spots[sign] = arr[ok]
        return spots[sign]

    def can_queue(self, door: int, sign: int) -> bool:
        """Whether people crossing ``door`` with ``sign`` have anywhere to wait out of its lane (a door from a
        narrow corridor has not: there a waiting person would block the corridor, so people from that side
        never wait, and those on the other side wait for them)."""
        return len(self.spots(door, sign)) > 0

    def spot(self, door: int, sign: int, rank: int = 0) -> np.ndarray:
        """The ``rank``-th waiting spot (2,) of :meth:`spots` (the last one for longer queues)."""
        s = self.spots(door, sign)
        if not len(s):
            raise ValueError(f"door {door} has no waiting spot for crossings of sign {sign} (see can_queue)")
        return s[min(int(rank), len(s) - 1)]

    # ------------------------------------------------------------------ per step
    def _release(self, who: np.ndarray) -> None:
        self.granted[who] = -1
        self.grant_t[who] = -np.inf
        self.close_d[who] = np.inf
        self.close_t[who] = -np.inf
        self.request_t[who] = np.inf

    def _held_ways(self, sign: np.ndarray) -> np.ndarray:
        """(n_doors,) the way each door is held (the sign of its holders' crossing; 0: free), given each person's
        ``sign`` of crossing its next door."""
        held = np.zeros(self.n_doors, dtype=int)
        holders = np.flatnonzero(self.granted >= 0)
        held[self.granted[holders]] = sign[holders]
        return held

    def _next_door(self, pos: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Advance every route past the doors already crossed; (next door or -1, sign of its crossing)."""
        cur = np.full(self.n, -1)
        sign = np.zeros(self.n, dtype=int)
        lateral = self.params.passed_lateral
        for j in range(self.n):
            route = self.routes[j]
            while self.k[j] < len(route):
                d, g = route[self.k[j]]
                rel = pos[j] - self.centres[d]
                along = float(rel @ self.axes[d]) * g
                beside = lateral is not None and abs(float(rel[0] * self.axes[d][1] - rel[1] * self.axes[d][0])) > lateral
                if along > self.params.passed and not beside:  # through: next door
                    if self.granted[j] == d:
                        self._release(np.array([j]))
                    self.k[j] += 1
                    continue
                cur[j], sign[j] = d, g
                break
        return cur, sign

    def update(self, t: float, pos: np.ndarray, active: np.ndarray | None = None) -> np.ndarray:
        """Requests, grants and their ends at time ``t`` for positions ``pos`` (n, 2); ``active`` (n,)
        bool: who takes part (default everybody). Returns (n,) bool: who was granted a door now."""
        p = self.params
        active = np.ones(self.n, dtype=bool) if active is None else np.asarray(active, dtype=bool)
        pos = np.asarray(pos, dtype=np.float64).reshape(self.n, 2)
        cur, sign = self._next_door(pos)
        self._cur, self._sign = cur, sign
        dist = np.where(cur >= 0, np.linalg.norm(pos - self.centres[np.maximum(cur, 0)], axis=1), np.inf) \
            if self.n_doors else np.full(self.n, np.inf)
        # grants end when their holder stops taking part, is past the door, or lapses (it then asks anew,
        # last in the queue, below)
        gone = (self.granted >= 0) & (~active | (self.granted != cur) | (t - self.grant_t > p.grant_max_s))
        if p.grant_stall_s is not None and self.n_doors:
            held = self.granted >= 0
            closer = held & (dist < self.close_d - p.grant_stall_gain)
            self.close_d[closer], self.close_t[closer] = dist[closer], t
            # ... or their holder has not come on for grant_stall_s while someone else asks for the door (not one
            # in the door: it holds it anyway)
            asked = np.zeros(self.n_doors, dtype=bool)
            asked[cur[self.waiting() & active & (cur >= 0)]] = True
            gone |= held & (t - self.close_t > p.grant_stall_s) & asked[np.maximum(self.granted, 0)] \
                & (dist >= p.throat)
        self._release(np.flatnonzero(gone))
        # who asks: within reach of its next door, or already asking (a queue may stretch beyond reach)
        near = active & (cur >= 0) & ((dist < p.approach) | np.isfinite(self.request_t))
        self.request_t[~near & (self.granted < 0)] = np.inf
        asking = near & (self.granted < 0)
        self.request_t[asking & ~np.isfinite(self.request_t)] = t
        new = np.zeros(self.n, dtype=bool)
        # someone in the door holds it, and so does one who has nowhere to wait
        no_room = np.array([cur[j] >= 0 and not self.can_queue(int(cur[j]), int(sign[j])) for j in range(self.n)],
                           dtype=bool)
        if p.no_room_waits and no_room.any():
            way = self._held_ways(sign)[np.maximum(cur, 0)]
            no_room &= (way == 0) | (way == sign)
        inside = asking & ((dist < p.throat) | no_room)
        self.granted[inside], self.grant_t[inside] = cur[inside], t
        new |= inside
        for d in np.unique(cur[asking & ~inside]):
            holders = np.flatnonzero(self.granted == d)
            way = int(sign[holders[0]]) if holders.size else 0
            queue = np.flatnonzero(asking & ~inside & (cur == d))
            queue = queue[np.argsort(self.request_t[queue], kind="stable")]
            for q in queue:
                other = queue[(sign[queue] != sign[q])]
                oldest_other = float(self.request_t[other].min()) if other.size else np.inf
                if way == 0 or (sign[q] == way and t - oldest_other < p.platoon_s):
                    self.granted[q], self.grant_t[q], way = d, t, int(sign[q])
                    new[q] = True
        self.request_t[self.granted >= 0] = np.inf
        self.close_d[new], self.close_t[new] = dist[new], t
        return new

    def _lining_up(self, pos: np.ndarray, has: np.ndarray, c: np.ndarray, along: np.ndarray) -> np.ndarray:
        """(n,) whether each person holds its next door, is still before it (not in its throat) and lies outside
        the cone ``|across| <= line_up x (distance before the centre)`` round the door's axis (``DoorParams.line_up``)."""
        p = self.params
        holds = has & (self.granted == self._cur)
        ax = self.axes[np.maximum(self._cur, 0)]
        across = np.abs(ax[:, 0] * (pos[:, 1] - c[:, 1]) - ax[:, 1] * (pos[:, 0] - c[:, 0]))
        before = -along
        return holds & (before > 0.0) & (np.linalg.norm(pos - c, axis=1) >= p.throat) & (across > p.line_up * before)

    def waiting(self) -> np.ndarray:
        """(n,) bool: who asked for a door at the last update and was not granted it."""
        return np.isfinite(self.request_t) & (self.granted < 0)

    def holder_waiter_pairs(self) -> np.ndarray:
        """(n, n) bool, at the last update: True at (i, j) where i holds the door that j waits for (asked for it,
        not granted). A waiting person stands aside on purpose, at a spot out of the door's lane; the AMP target
        rollouts can let the holders pass such people without their repulsion (``amp_humans.DOOR_PASS_WAITERS``)."""
        waits = self.waiting() & (self._cur >= 0)
        return (self.granted[:, None] >= 0) & waits[None, :] & (self.granted[:, None] == self._cur[None, :])

    def apply(self, pos: np.ndarray, pref: np.ndarray, v_pref: np.ndarray) -> np.ndarray:
        """Preferred velocities (n, 2) with the door turns applied at positions ``pos`` (n, 2): a person
        who waits for its next door, or who is near a door held the other way and does not hold it,
        walks to the door's waiting spot on its side and stands there; others keep ``pref``.

        ``pos`` may be rolled-out positions (AMP target rollouts): the grants are those of the last
        :meth:`update`."""
        if not self.n_doors:
            return pref
        p = self.params
        pos = np.asarray(pos, dtype=np.float64).reshape(self.n, 2)
        cur, sign = self._cur, self._sign
        has = cur >= 0
        c = self.centres[np.maximum(cur, 0)]
        dist = np.linalg.norm(pos - c, axis=1)
        along = np.einsum("ij,ij->i", pos - c, self.axes[np.maximum(cur, 0)]) * sign
        near = has & (dist < p.approach) & (along < p.passed) & (self.granted < 0)
        held_way = self._held_ways(sign)
        idx = np.maximum(cur, 0)
        against = (held_way[idx] != 0) & (held_way[idx] != sign)
        queued = self.waiting() & has
        wait = (queued | (near & against)) & (dist >= p.throat)
        room = np.array([w and self.can_queue(int(cur[j]), int(sign[j])) for j, w in enumerate(wait)], dtype=bool)
        # no_room_waits: one with nowhere to queue stops short of a door held against it, in the passage
        stop = wait & ~room & (dist <= p.wait) if p.no_room_waits else np.zeros(self.n, dtype=bool)
        wait &= room
        lining = self._lining_up(pos, has, c, along) if p.line_up is not None else np.zeros(self.n, dtype=bool)
        if not (wait.any() or stop.any() or lining.any()):
            return pref
        out = np.array(pref, dtype=np.float64, copy=True)
        out[stop] = 0.0
        for j in np.flatnonzero(lining):  # holders off the door's axis: to the line-up point first
            ax = self.axes[int(cur[j])] * sign[j]
            to = c[j] - ax * p.line_up_back - pos[j]
            d = float(np.linalg.norm(to))
            out[j] = to / max(d, 1e-9) * float(v_pref[j]) * min(1.0, d / 0.6)
        for j in np.flatnonzero(wait):
            d_j, s_j = int(cur[j]), int(sign[j])
            line = queued & (cur == d_j) & (sign == s_j)
            # place in the queue: those who asked earlier; one who would join it goes to its end
            rank = int((line & (self.request_t < self.request_t[j])).sum()) if queued[j] else int(line.sum())
            to = self.spot(d_j, s_j, rank) - pos[j]
            d = float(np.linalg.norm(to))
            speed = float(v_pref[j]) * min(1.0, d / 0.6) if d > 0.1 else 0.0
            out[j] = to / max(d, 1e-9) * speed
        return out
