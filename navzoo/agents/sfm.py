"""Vectorised social force model (SFM) for pedestrians.

The model follows Helbing & Molnár (1995) ("Social force model for pedestrian dynamics",
Phys. Rev. E 51, 4282) with the *elliptical specification II* of the person-person potential
(Johansson, Helbing & Shukla 2007, "Specification of the social force pedestrian model by
evolutionary adjustment to video tracking data"), which makes the repulsion depend on the
relative velocity so that people start avoiding each other before they are close. Two
practical changes, documented in ``docs/crowd_models.md``:

* body radii: the potentials are shifted by the contact distance (sum of radii for people,
  own radius for walls), as in Helbing, Farkas & Vicsek (2000), so that the default
  parameters keep bodies apart instead of letting point particles overlap;
* a deterministic keep-right tie-breaking term for people straight ahead, because a perfectly
  symmetric head-on encounter otherwise produces purely longitudinal forces and the two
  people brake to a stand-still in front of each other.

Everything is pure numpy, vectorised over people (N up to ~100), with no random numbers: the
same inputs always give the same outputs.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields, replace
from typing import NamedTuple

import numpy as np

__all__ = [
    "SocialForceParams",
    "SocialForces",
    "social_forces",
    "social_force_velocities",
]

# Guards against divisions by ~0 (coincident centres, degenerate ellipses, zero headings).
_EPS = 1e-9
# Smallest semi-minor axis used in the potential gradient. The gradient of b diverges as
# b -> 0 (the other person would pass through us within the step width); the force is then
# already far above max_accel, so bounding b only removes the infinities.
_B_MIN = 0.05


@dataclass(frozen=True)
class SocialForceParams:
    """Parameters of the social force model.

    Defaults are those of Helbing & Molnár (1995) -- also the defaults of the ``socialforce``
    package (S. Kreiss) and of PySocialForce's ``ped_repulsive_force`` /
    ``space_repulsive_force`` -- unless noted otherwise.

    Attributes:
        tau: Relaxation time towards the preferred velocity (s). HM1995: 0.5 s.
        A: Person-person potential strength V0 (m^2/s^2); the repulsion at contact is
            ``A / B`` (m/s^2). HM1995: 2.1.
        B: Person-person potential range sigma (m). HM1995: 0.3.
        lambda_: Anisotropy: weight of a force from a person straight behind (1 = isotropic).
            Smooth form ``lambda + (1 - lambda)(1 + cos phi)/2`` (Helbing & Johansson 2009);
            0.5 matches HM1995's out-of-view weight c = 0.5.
        A_wall: Wall potential strength U0 (m^2/s^2); repulsion at contact is
            ``A_wall / B_wall``. navzoo choice: 1.0 (HM1995: 10, measured from the centre).
        B_wall: Wall potential range R (m). navzoo choice: 0.1 (HM1995: 0.2).
            HM1995's wall potential, once measured from the body's edge and summed per obstacle,
            stops a person of preferred speed 1.37 m/s in front of a 0.9 m door (the two jambs'
            backward push balances the 2.7 m/s^2 goal force). The softer, shorter-ranged wall
            (contact push 10 m/s^2, 0.4 m/s^2 at 0.3 m) lets people through 0.9 m doors while
            keeping them off walls; chosen by sweeping (A_wall, B_wall) over the home, doorway,
            grocery and lobby scenes (goals reached and mean speed; docs/crowd_models.md).
        step_time: Time (s) over which the relative displacement defines the ellipse of
            elliptical specification II. 0.4 s, the step width used by ``socialforce``.
        side_bias: Keep-right tie-breaking gain: fraction of the repulsion from a person
            ahead that is added towards one's right (0 disables it). navzoo choice.
        neighbor_dist: People/robots farther than this (centre distance, m) are ignored.
        max_accel: Bound on the norm of the total force (m/s^2). A numerical safeguard: the
            exponential potentials are stiff when bodies touch and explicit integration with
            dt ~ 0.1 s would otherwise overshoot. navzoo choice.
        max_substep: Longest integration sub-step (s); longer control periods are split,
            because explicit Euler on these potentials overshoots into bodies beyond ~0.1 s.
            navzoo choice.
        keep_apart: Room (m) each person keeps beyond its radius from others (people and robots),
            held by a short-range repulsion ``(A / keep_range) exp(-(d - r_i - r_j - 2 keep_apart) /
            keep_range)`` along the line between the centres, added to the social repulsion, which
            stays that of the bare radii. Widening the radii instead also doubles the social
            repulsion at every distance (``exp(2 margin / B)``) and slows a whole crowd down. 0 = off
            (the default). navzoo choice, for the target rollouts of physics pedestrians, whose
            swinging limbs reach beyond their discs.
        keep_range: Range (m) of the keep-apart repulsion. navzoo choice: 0.05.
        pass_margin: Room (m) each person keeps beyond its radius from others that it *passes*: the
            contact distance of a pair grows by ``2 pass_margin min(1, |v_j - v_i| / pass_speed)``, so
            people who meet, cross or overtake fast keep the room, and people walking together (behind
            or beside one another at the same velocity) keep their bare radii. 0 = off (the default).
            navzoo choice, for the target rollouts of physics pedestrians (``navzoo.envs.amp_humans``
            ``PASS_MARGIN``), whose swinging limbs catch when they pass each other close.
        pass_speed: Relative speed (m/s) at which the full ``pass_margin`` applies. navzoo choice: 1.0.
        wall_near_range: With > 0, a person who has another person within this distance (m, centre to centre)
            feels the walls with ``A_wall_near`` instead of ``A_wall``: softer walls only where people meet,
            queue or pass one another, the full walls for a person alone (at corners, along walls). 0 = off
            (the default).
        A_wall_near: Wall potential strength for people within ``wall_near_range`` of another person.
        wall_near_ramp: With > 0 (m), the softer walls phase in linearly instead of switching: a person whose
            nearest other is at ``wall_near_range + wall_near_ramp`` feels ``A_wall``, at ``wall_near_range`` or
            nearer ``A_wall_near``, in between a linear blend (the wall force is linear in the strength). 0 = the
            switch at ``wall_near_range`` (the default).
    """

    tau: float = 0.5
    A: float = 2.1
    B: float = 0.3
    lambda_: float = 0.5
    A_wall: float = 1.0
    B_wall: float = 0.1
    step_time: float = 0.4
    side_bias: float = 0.1
    neighbor_dist: float = 5.0
    max_accel: float = 10.0
    max_substep: float = 0.1
    keep_apart: float = 0.0
    keep_range: float = 0.05
    pass_margin: float = 0.0
    pass_speed: float = 1.0
    wall_near_range: float = 0.0
    A_wall_near: float = 1.0
    wall_near_ramp: float = 0.0

    def __post_init__(self) -> None:
        positive = ("tau", "B", "B_wall", "neighbor_dist", "max_accel", "max_substep", "keep_range", "pass_speed")
        non_negative = ("A", "A_wall", "step_time", "side_bias", "keep_apart", "pass_margin", "wall_near_range",
                        "A_wall_near", "wall_near_ramp")
        for f in fields(self):
            value = getattr(self, f.name)
            if not np.isfinite(value):
                raise ValueError(f"SocialForceParams.{f.name} must be finite, got {value!r}")
            if f.name in positive and value <= 0:
                raise ValueError(f"SocialForceParams.{f.name} must be > 0, got {value!r}")
            if f.name in non_negative and value < 0:
                raise ValueError(f"SocialForceParams.{f.name} must be >= 0, got {value!r}")
        if not 0.0 <= self.lambda_ <= 1.0:
            raise ValueError(f"SocialForceParams.lambda_ must be in [0, 1], got {self.lambda_!r}")


class SocialForces(NamedTuple):
    """Force (acceleration, m/s^2) components acting on each of N people, each (N, 2).

    ``goal + people + robots + walls`` is the total before the ``max_accel`` bound.
    """

    goal: np.ndarray
    people: np.ndarray
    robots: np.ndarray
    walls: np.ndarray

    @property
    def total(self) -> np.ndarray:
        """Sum of all components, (N, 2)."""
        return self.goal + self.people + self.robots + self.walls


def _points(name: str, value: np.ndarray | None, n: int | None) -> np.ndarray:
    """Validate an (n, 2) float array; n=None accepts any length."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim != 2 or arr.shape[1] != 2 or (n is not None and arr.shape[0] != n):
        expected = f"({n if n is not None else 'K'}, 2)"
        raise ValueError(f"{name} must have shape {expected}, got {arr.shape}")
    return arr


def _scalars(name: str, value: np.ndarray | float, n: int) -> np.ndarray:
    """Validate a per-agent (n,) array; a scalar is broadcast."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return np.full(n, float(arr))
    if arr.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},) or be a scalar, got {arr.shape}")
    return arr


def _segments(segments: np.ndarray | None) -> np.ndarray:
    if segments is None:
        return np.zeros((0, 2, 2))
    seg = np.asarray(segments, dtype=float)
    if seg.size == 0:
        return np.zeros((0, 2, 2))
    if seg.ndim != 3 or seg.shape[1:] != (2, 2):
        raise ValueError(f"segments must have shape (M, 2, 2), got {seg.shape}")
    return seg


def _headings(pref_vel: np.ndarray, vel: np.ndarray) -> np.ndarray:
    """Unit walking direction: preferred velocity, else current velocity, else zero."""
    heading = np.where((np.linalg.norm(pref_vel, axis=1) > _EPS)[:, None], pref_vel, vel)
    norm = np.linalg.norm(heading, axis=1, keepdims=True)
    return np.divide(heading, norm, out=np.zeros_like(heading), where=norm > _EPS)


def _ignore(ignore: np.ndarray | None, n: int) -> np.ndarray | None:
    """``ignore`` checked: None, or an (n, n) bool array."""
    if ignore is None:
        return None
    arr = np.asarray(ignore)
    if arr.shape != (n, n) or arr.dtype != bool:
        raise ValueError(f"ignore must be a bool array of shape ({n}, {n}), got {arr.dtype} {arr.shape}")
    return arr


def _interaction(
    pos: np.ndarray,
    vel: np.ndarray,
    heading: np.ndarray,
    radius: np.ndarray,
    pos_j: np.ndarray,
    vel_j: np.ndarray,
    radius_j: np.ndarray,
    params: SocialForceParams,
    exclude_diagonal: bool,
    ignore: np.ndarray | None = None,
) -> np.ndarray:
    """Sum over j of the forces that the bodies j exert on the people i, (N, 2); none where ``ignore[i, j]``."""
    n, k = pos.shape[0], pos_j.shape[0]
    if n == 0 or k == 0:
        return np.zeros((n, 2))

    d = pos[:, None, :] - pos_j[None, :, :]  # (N, K, 2): from j to i
    dist = np.linalg.norm(d, axis=2)
    # Future relative position after step_time if both keep their velocities. The ellipse
    # with foci at the present and future relative positions (spec II) is flattened towards
    # people who approach, so the repulsion grows earlier for closing speeds.
    y = (vel_j[None, :, :] - vel[:, None, :]) * params.step_time
    d_next = d - y
    dist_next = np.linalg.norm(d_next, axis=2)
    y_len = np.linalg.norm(y, axis=2)
    b = 0.5 * np.sqrt(np.maximum((dist + dist_next) ** 2 - y_len**2, 0.0))

    # Unit vectors; a coincident pair gets a fixed direction rather than NaN.
    fallback = np.array([1.0, 0.0])
    u = np.where((dist > _EPS)[..., None], d / np.maximum(dist, _EPS)[..., None], fallback)
    u_next = np.where((dist_next > _EPS)[..., None], d_next / np.maximum(dist_next, _EPS)[..., None], u)
    # grad_b = (|d| + |d - y|) / (4 b) * (u + u_next). When the relative motion would carry
    # j straight through i, u + u_next vanishes; fall back to the radial direction there so
    # the push never disappears at short range.
    s = u + u_next
    s_norm = np.linalg.norm(s, axis=2)
    s = np.where((s_norm > 1e-6)[..., None], s, 2.0 * u)
    grad_b = ((dist + dist_next) / (4.0 * np.maximum(b, _B_MIN)))[..., None] * s

    # Radius-aware potential V = A exp(-(b - R) / B): -dV/db = (A / B) exp(-(b - R) / B).
    contact = radius[:, None] + radius_j[None, :]
    if params.pass_margin > 0.0:  # room kept from those passed, not from those walked with (see SocialForceParams)
        rel_speed = np.linalg.norm(vel_j[None, :, :] - vel[:, None, :], axis=2)
        contact = contact + 2.0 * params.pass_margin * np.minimum(rel_speed / params.pass_speed, 1.0)
    magnitude = (params.A / params.B) * np.exp(np.minimum(-(b - contact) / params.B, 50.0))
    force = magnitude[..., None] * grad_b  # (N, K, 2)

    # Anisotropy: cos(phi) between i's heading and the direction from i towards j (-u).
    cos_phi = -np.einsum("nd,nkd->nk", heading, u)
    has_heading = (np.linalg.norm(heading, axis=1) > 0.5)[:, None]
    weight = np.where(has_heading, params.lambda_ + (1.0 - params.lambda_) * 0.5 * (1.0 + cos_phi), 1.0)
    force *= weight[..., None]

    # Keep-right tie-break: a share of the repulsion from someone ahead pushes i to its right.
    if params.side_bias > 0.0:
        right = np.stack([heading[:, 1], -heading[:, 0]], axis=1)  # heading rotated -90 deg
        ahead = np.clip(cos_phi, 0.0, None)
        side = params.side_bias * np.linalg.norm(force, axis=2) * ahead
        force += side[..., None] * right[:, None, :]

    if params.keep_apart > 0.0:  # a short-range push that holds the extra room (see SocialForceParams)
        kept = contact + 2.0 * params.keep_apart
        push = (params.A / params.keep_range) * np.exp(np.minimum(-(dist - kept) / params.keep_range, 50.0))
        force = force + push[..., None] * u

    mask = dist <= params.neighbor_dist
    if exclude_diagonal:
        mask &= ~np.eye(n, k, dtype=bool)
    if ignore is not None:
        mask &= ~ignore
    return np.einsum("nk,nkd->nd", mask.astype(float), force)


def _wall_forces(
    pos: np.ndarray,
    radius: np.ndarray,
    segments: np.ndarray,
    params: SocialForceParams,
    groups: np.ndarray | None = None,
) -> np.ndarray:
    """Wall repulsion, (N, 2): one term per wall *group* from its nearest point.

    Helbing's wall force is one repulsion per boundary. A scene's obstacle is a polygon of many
    edges (a column is a 24-gon), so summing over edges would push many times too hard; with
    ``groups`` (the obstacle owning each edge, contiguous) each obstacle pushes once, from its
    nearest point. Without ``groups`` every segment counts as its own wall.
    """
    n = pos.shape[0]
    if segments.shape[0] == 0 or n == 0:
        return np.zeros((n, 2))
    if groups is not None:
        from navzoo.world.geometry import nearest_point_per_group

        dist, closest = nearest_point_per_group(pos, segments, groups)  # (N, G), (N, G, 2)
        d = pos[:, None, :] - closest
        u = d / np.maximum(dist, _EPS)[..., None]
        exponent = np.minimum(-(dist - radius[:, None]) / params.B_wall, 50.0)
        magnitude = np.where(dist > _EPS, (params.A_wall / params.B_wall) * np.exp(exponent), 0.0)
        return np.einsum("ng,ngd->nd", magnitude, u)
    a = segments[:, 0, :]  # (M, 2)
    ab = segments[:, 1, :] - a
    ab_sq = np.maximum(np.einsum("md,md->m", ab, ab), _EPS)
    ap = pos[:, None, :] - a[None, :, :]  # (N, M, 2)
    t = np.clip(np.einsum("nmd,md->nm", ap, ab) / ab_sq, 0.0, 1.0)
    d = ap - t[..., None] * ab[None, :, :]  # from closest wall point to the person
    dist = np.linalg.norm(d, axis=2)
    # A centre exactly on the wall has no defined side; use the segment's left normal.
    normal = np.stack([-ab[:, 1], ab[:, 0]], axis=1) / np.sqrt(ab_sq)[:, None]
    u = np.where(
        (dist > _EPS)[..., None],
        d / np.maximum(dist, _EPS)[..., None],
        np.broadcast_to(normal[None], d.shape),
    )
    exponent = np.minimum(-(dist - radius[:, None]) / params.B_wall, 50.0)
    magnitude = (params.A_wall / params.B_wall) * np.exp(exponent)
    return np.einsum("nm,nmd->nd", magnitude, u)


def _wall_contact(
    pos: np.ndarray, vel: np.ndarray, h: float, radius: np.ndarray, segments: np.ndarray, groups: np.ndarray
) -> np.ndarray:
    """Walls are solid: remove the velocity component that would push a body into a wall.

    The wall potential is soft, so a person pressed toward a wall by a strong goal force can reach
    it; at contact (the step would end within one radius of a wall's nearest point) the inward
    normal component of the velocity is removed, as a contact force would, and sliding along the
    wall remains.
    """
    if segments.shape[0] == 0 or pos.shape[0] == 0:
        return vel
    from navzoo.world.geometry import nearest_point_per_group

    nxt = pos + h * vel
    dist, closest = nearest_point_per_group(nxt, segments, groups)  # (N, G)
    touching = dist < radius[:, None]
    if not touching.any():
        return vel
    normal = (nxt[:, None, :] - closest) / np.maximum(dist, _EPS)[..., None]  # wall -> person
    for g in np.flatnonzero(touching.any(axis=0)):
        rows = touching[:, g]
        n_g = normal[rows, g]
        into = np.minimum(np.einsum("nd,nd->n", vel[rows], n_g), 0.0)
        vel[rows] = vel[rows] - into[:, None] * n_g
    return vel


def social_forces(
    pos: np.ndarray,
    vel: np.ndarray,
    pref_vel: np.ndarray,
    radius: np.ndarray | float,
    params: SocialForceParams,
    segments: np.ndarray | None = None,
    others_pos: np.ndarray | None = None,
    others_vel: np.ndarray | None = None,
    others_radius: np.ndarray | float | None = None,
    segment_groups: np.ndarray | None = None,
    wall_radius: np.ndarray | float | None = None,
    ignore: np.ndarray | None = None,
) -> SocialForces:
    """Force components (accelerations) acting on N people.

    Args:
        pos: People positions, (N, 2) m.
        vel: People velocities, (N, 2) m/s.
        pref_vel: Preferred (desired) velocities, (N, 2) m/s: direction to the next waypoint
            times the preferred speed, computed by the caller.
        radius: Body radii, (N,) m or a scalar.
        params: Model parameters.
        segments: Wall segments, (M, 2, 2) m; M may be 0, None means no walls.
        others_pos: Positions of extra bodies (robots) the people react to but that are not
            updated, (K, 2); None or empty for none.
        others_vel: Their velocities, (K, 2); None means standing still.
        others_radius: Their radii, (K,) or a scalar; None means 0.3 m.
        segment_groups: (M,) id of the wall (obstacle) each segment belongs to, contiguous per
            wall; each wall then pushes once, from its nearest point. None: every segment is a wall.
        wall_radius: Radii (N,) or a scalar that walls see, when they differ from ``radius`` (a body
            kept farther from people than from walls); None means ``radius``.
        ignore: (N, N) bool, True where person i feels no force from person j (its people term leaves j
            out; j still feels i unless ``ignore[j, i]``); None: everyone feels everyone.

    Returns:
        The goal, people, robots and walls components, each (N, 2) m/s^2.

    Raises:
        ValueError: On inconsistent shapes.
    """
    pos = _points("pos", pos, None)
    n = pos.shape[0]
    vel = _points("vel", vel, n)
    pref_vel = _points("pref_vel", pref_vel, n)
    radius = _scalars("radius", radius, n)
    seg = _segments(segments)

    heading = _headings(pref_vel, vel)
    goal = (pref_vel - vel) / params.tau
    ignore = _ignore(ignore, n)
    people = _interaction(pos, vel, heading, radius, pos, vel, radius, params, True, ignore)

    if others_pos is None or np.asarray(others_pos).size == 0:
        robots = np.zeros((n, 2))
    else:
        o_pos = _points("others_pos", others_pos, None)
        k = o_pos.shape[0]
        o_vel = np.zeros((k, 2)) if others_vel is None else _points("others_vel", others_vel, k)
        o_rad = _scalars("others_radius", 0.3 if others_radius is None else others_radius, k)
        robots = _interaction(pos, vel, heading, radius, o_pos, o_vel, o_rad, params, False)

    groups = None if segment_groups is None else np.asarray(segment_groups)
    if groups is not None and groups.shape != (seg.shape[0],):
        raise ValueError(f"segment_groups must have shape ({seg.shape[0]},), got {groups.shape}")
    w_rad = radius if wall_radius is None else _scalars("wall_radius", wall_radius, n)
    near = np.zeros(n, dtype=bool)
    if params.wall_near_range > 0.0 and n > 1 and seg.shape[0]:
        gap = np.linalg.norm(pos[:, None, :] - pos[None, :, :], axis=2)
        np.fill_diagonal(gap, np.inf)
        nearest = gap.min(axis=1)
        if params.wall_near_ramp > 0.0:  # blend: the strength is linear in the share of the softer walls
            share = np.clip((params.wall_near_range + params.wall_near_ramp - nearest) / params.wall_near_ramp, 0, 1)
            if params.A_wall > 0.0:
                a_eff = params.A_wall + share * (params.A_wall_near - params.A_wall)
                walls = _wall_forces(pos, w_rad, seg, params, groups) * (a_eff / params.A_wall)[:, None]
            else:
                walls = share[:, None] * _wall_forces(pos, w_rad, seg, replace(params, A_wall=params.A_wall_near), groups)
            return SocialForces(goal=goal, people=people, robots=robots, walls=walls)
        near = nearest < params.wall_near_range
    if near.any():  # other walls for people who meet, queue or pass another; each person's walls computed once
        walls = np.zeros((n, 2))
        walls[~near] = _wall_forces(pos[~near], w_rad[~near], seg, params, groups)
        walls[near] = _wall_forces(pos[near], w_rad[near], seg, replace(params, A_wall=params.A_wall_near), groups)
    else:
        walls = _wall_forces(pos, w_rad, seg, params, groups)
    return SocialForces(goal=goal, people=people, robots=robots, walls=walls)


def social_force_velocities(
    pos: np.ndarray,
    vel: np.ndarray,
    pref_vel: np.ndarray,
    radius: np.ndarray | float,
    max_speed: np.ndarray | float,
    dt: float,
    params: SocialForceParams,
    segments: np.ndarray | None = None,
    others_pos: np.ndarray | None = None,
    others_vel: np.ndarray | None = None,
    others_radius: np.ndarray | float | None = None,
    segment_groups: np.ndarray | None = None,
    wall_radius: np.ndarray | float | None = None,
    ignore: np.ndarray | None = None,
) -> np.ndarray:
    """New velocities of N people after integrating the social force over one step.

    Semi-implicit Euler in ``ceil(dt / params.max_substep)`` sub-steps of length h:
    ``v <- clip_speed(v + h * F)`` with ``|F| <= params.max_accel``, then ``p <- p + h * v``
    (robots advance with their constant velocity). The returned velocity is the mean over
    the sub-steps, so the caller's ``p + dt * v`` lands exactly on the sub-stepped position;
    with a single sub-step (dt <= max_substep) it is simply the new velocity.

    Args:
        pos: People positions, (N, 2) m.
        vel: People velocities, (N, 2) m/s.
        pref_vel: Preferred velocities, (N, 2) m/s, held constant during the step.
        radius: Body radii, (N,) m or a scalar.
        max_speed: Speed limits, (N,) m/s or a scalar.
        dt: Time step (s), > 0.
        params: Model parameters.
        segments: Wall segments, (M, 2, 2) m; None or M = 0 for none.
        others_pos: Robots' positions, (K, 2); None or empty if people ignore robots.
        others_vel: Robots' velocities, (K, 2); None means standing still.
        others_radius: Robots' radii, (K,) or a scalar; None means 0.3 m.
        segment_groups: (M,) wall id of each segment (see :func:`social_forces`).
        wall_radius: Radii seen by the walls (their forces and the contact constraint), (N,) or a
            scalar; None means ``radius`` (see :func:`social_forces`).
        ignore: (N, N) bool, the pairs (i, j) where i feels no force from j (see :func:`social_forces`).

    Returns:
        New velocities, (N, 2) m/s, with speed <= max_speed.

    Raises:
        ValueError: On inconsistent shapes or a non-positive dt.
    """
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0, got {dt!r}")
    pos = _points("pos", pos, None)
    n = pos.shape[0]
    vel = _points("vel", vel, n)
    max_speed = _scalars("max_speed", max_speed, n)
    if np.any(max_speed < 0):
        raise ValueError(f"max_speed must be >= 0, got min {max_speed.min()!r}")
    has_others = others_pos is not None and np.asarray(others_pos).size > 0
    if has_others:
        others_pos = _points("others_pos", others_pos, None)
        if others_vel is not None:
            others_vel = _points("others_vel", others_vel, others_pos.shape[0])

    radius_arr = _scalars("radius", radius, n)
    wall_radius_arr = radius_arr if wall_radius is None else _scalars("wall_radius", wall_radius, n)
    seg = _segments(segments)
    groups = np.arange(seg.shape[0]) if segment_groups is None else np.asarray(segment_groups)
    # The exponential potentials are stiff at body contact (range B = 0.3 m against closing
    # speeds of ~2.4 m/s), so long control periods are split into sub-steps.
    n_sub = max(1, math.ceil(dt / params.max_substep - 1e-9))
    h = dt / n_sub
    displacement = np.zeros_like(vel)
    for _ in range(n_sub):
        forces = social_forces(
            pos, vel, pref_vel, radius, params, segments, others_pos, others_vel, others_radius,
            segment_groups, wall_radius_arr, ignore,
        )
        total = forces.total
        norm = np.linalg.norm(total, axis=1, keepdims=True)
        total = total * np.minimum(1.0, params.max_accel / np.maximum(norm, _EPS))
        vel = vel + h * total
        speed = np.linalg.norm(vel, axis=1, keepdims=True)
        vel = vel * np.minimum(1.0, max_speed[:, None] / np.maximum(speed, _EPS))
        vel = _wall_contact(pos, vel, h, wall_radius_arr, seg, groups)
        if n_sub > 1:
            pos = pos + h * vel
            if has_others and others_vel is not None:
                others_pos = others_pos + h * others_vel
        displacement += h * vel
    return vel if n_sub == 1 else displacement / dt
