"""Optimal Reciprocal Collision Avoidance (ORCA) for pedestrians, in numpy.

A port of the logic of RVO2's ``Agent::computeNewVelocity`` (van den Berg, Guy, Lin & Manocha
2011, "Reciprocal n-body collision avoidance"; RVO2 library, Apache-2.0), written from the
published algorithm:

* one ORCA half-plane per neighbouring agent (nearest ``max_neighbors`` within
  ``neighbor_dist``), responsibility shared half/half between two active agents;
* one ORCA half-plane per nearby wall segment (the obstacle velocity obstacle, truncated at
  ``time_horizon_obst``), skipping segments already covered by previous obstacle lines;
* the incremental 2-D linear programs ``linearProgram1/2/3``: the new velocity is the one
  closest to the preferred velocity that satisfies all half-planes within the speed disc;
  when infeasible, the agent-agent constraints are relaxed as little as possible while
  obstacle constraints stay hard.

What is vectorised: neighbour selection (distance matrix + ``argpartition``), the agent ORCA
lines and the obstacle ORCA lines for all (agent, neighbour/segment) pairs, and a pre-check
that skips the linear program for agents whose clipped preferred velocity is already
feasible. The linear program itself is sequential per agent and runs on Python floats.

Differences from RVO2 (see ``docs/crowd_models.md``):

* obstacles are free wall segments: each is a two-vertex obstacle whose both endpoints are
  convex, and the side that faces the agent is used (RVO2 uses counter-clockwise polygons);
  an agent exactly collinear with a segment still sees it (RVO2 would skip it);
* agents ``[n_active, N)`` are passive (robots): active agents avoid them and take the full
  responsibility for doing so, passive agents are not updated;
* ``right_bias`` (default 0.3 rad): when an agent's preferred velocity is infeasible, the
  linear program aims slightly to its right. This breaks exactly symmetric encounters
  (head-on from rest), where RVO2 stays on the cut-off circle and never passes, and makes
  dense crowds settle on passing right;
* ``one_step_safety`` (default on): RVO2 relaxes all agent lines when the program is
  infeasible and bodies then interpenetrate; here the lines for the next time step stay
  hard in that case, and a final filter slows down agents that would still overlap within
  the next step;
* float64 instead of float32; no k-d tree (N <= ~100 makes the brute-force matrix cheaper).

With ``right_bias=0`` and ``one_step_safety=False`` the result equals RVO2's (checked against
the RVO2 library through the ``pyrvo`` bindings, see ``docs/crowd_models.md``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["OrcaParams", "orca_velocities"]

# RVO_EPSILON in RVO2: tolerance for parallel lines and coverage tests.
_RVO_EPS = 1e-5
_TINY = 1e-12


@dataclass(frozen=True)
class OrcaParams:
    """ORCA parameters.

    The first four defaults are CrowdNav's ``ORCA`` policy defaults (Chen et al. 2019,
    ``crowd_sim/envs/policy/orca.py``); the last two are navzoo additions.

    Attributes:
        neighbor_dist: Only agents closer than this (centre to centre, m) are considered.
        max_neighbors: At most this many nearest agents are considered.
        time_horizon: Agent velocities are collision-free for this long (s) w.r.t. agents.
        time_horizon_obst: Same w.r.t. wall segments (s); segments farther than
            ``time_horizon_obst * max_speed + radius`` are ignored.
        right_bias: When the preferred velocity is infeasible, the linear program aims at
            the preferred velocity turned clockwise (to the agent's right) by this angle (rad).
            navzoo addition: it breaks exactly symmetric encounters (two agents head-on from
            rest, an agent walking straight at a standing robot), which otherwise keep ORCA
            on the cut-off circle forever, and it makes crowds settle on passing right
            instead of pushing into each other. 0 restores RVO2.
        one_step_safety: navzoo addition. RVO2 guarantees no collision only while every
            agent's linear program is feasible; in dense knots it relaxes all agent lines
            and bodies interpenetrate (5 cm in the 20-agent circle test, reproduced with RVO2
            itself). When True, an infeasible program keeps the one-step lines (horizon dt)
            hard, and a final filter slows agents that would still overlap during the next
            step. False restores RVO2.
    """

    neighbor_dist: float = 10.0
    max_neighbors: int = 10
    time_horizon: float = 5.0
    time_horizon_obst: float = 5.0
    right_bias: float = 0.3
    one_step_safety: bool = True

    def __post_init__(self) -> None:
        for name in ("neighbor_dist", "time_horizon", "time_horizon_obst"):
            value = getattr(self, name)
            if not (np.isfinite(value) and value > 0):
                raise ValueError(f"OrcaParams.{name} must be finite and > 0, got {value!r}")
        if isinstance(self.max_neighbors, bool) or not isinstance(self.max_neighbors, int | np.integer):
            raise ValueError(
                f"OrcaParams.max_neighbors must be an int, got {type(self.max_neighbors).__name__}"
            )
        if not (np.isfinite(self.right_bias) and 0.0 <= self.right_bias < 0.5 * math.pi):
            raise ValueError(f"OrcaParams.right_bias must be in [0, pi/2) rad, got {self.right_bias!r}")
        if not isinstance(self.one_step_safety, bool | np.bool_):
            raise ValueError(
                f"OrcaParams.one_step_safety must be a bool, got {type(self.one_step_safety).__name__}"
            )
        if self.max_neighbors < 0:
            raise ValueError(f"OrcaParams.max_neighbors must be >= 0, got {self.max_neighbors!r}")


# --------------------------------------------------------------------------------------------
# Small vector helpers on (..., 2) arrays.


def _det(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 1] - a[..., 1] * b[..., 0]


def _dot(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1]


def _perp(a: np.ndarray) -> np.ndarray:
    """Rotate by +90 degrees: (x, y) -> (-y, x)."""
    return np.stack([-a[..., 1], a[..., 0]], axis=-1)


def _normalize(a: np.ndarray, fallback: np.ndarray) -> np.ndarray:
    norm = np.sqrt(_dot(a, a))[..., None]
    return np.where(norm > _TINY, a / np.maximum(norm, _TINY), fallback)


# --------------------------------------------------------------------------------------------
# ORCA lines. A line is (point, direction); the permitted half-plane is on its left.


def _agent_lines(
    pos: np.ndarray,
    vel: np.ndarray,
    radius: np.ndarray,
    n_active: int,
    params: OrcaParams,
    dt: float,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """ORCA lines of every active agent w.r.t. its nearest neighbours (sorted by distance).

    Returns:
        ``(point, direction, valid, step_point, step_direction, step_valid)``: the ORCA lines
        for ``time_horizon`` (n, K, 2), (n, K, 2), (n, K), and the same construction with
        the horizon shortened to ``dt`` (one-step lines), defined only for pairs that do not
        overlap yet.
    """
    n_total = pos.shape[0]
    k = min(params.max_neighbors, n_total - 1)
    if k <= 0 or n_active == 0:
        empty = np.zeros((n_active, 0, 2))
        none = np.zeros((n_active, 0), dtype=bool)
        return empty, empty, none, empty, empty, none

    p_a = pos[:n_active]
    diff = pos[None, :, :] - p_a[:, None, :]  # (n, N, 2)
    dist_sq = _dot(diff, diff)
    dist_sq[np.arange(n_active), np.arange(n_active)] = np.inf
    dist_sq[dist_sq >= params.neighbor_dist**2] = np.inf
    if k < n_total:
        nbr = np.argpartition(dist_sq, k - 1, axis=1)[:, :k]
    else:
        nbr = np.broadcast_to(np.arange(n_total), (n_active, n_total)).copy()
    rows = np.arange(n_active)[:, None]
    # RVO2 keeps neighbours sorted by distance, and the linear program is order dependent.
    nbr = np.take_along_axis(nbr, np.argsort(dist_sq[rows, nbr], axis=1, kind="stable"), axis=1)
    valid = np.isfinite(dist_sq[rows, nbr])

    rel_pos = pos[nbr] - p_a[:, None, :]
    rel_vel = vel[:n_active, None, :] - vel[nbr]
    d_sq = _dot(rel_pos, rel_pos)
    comb_r = radius[:n_active, None] + radius[nbr]
    comb_r_sq = comb_r**2
    inv_dt = 1.0 / dt

    # Legs of the velocity obstacle (independent of the horizon).
    leg = np.sqrt(np.maximum(d_sq - comb_r_sq, 0.0))
    x, y = rel_pos[..., 0], rel_pos[..., 1]
    inv_d_sq = (1.0 / np.maximum(d_sq, _TINY))[..., None]
    left_leg = np.stack([x * leg - y * comb_r, x * comb_r + y * leg], axis=-1) * inv_d_sq
    right_leg = -np.stack([x * leg + y * comb_r, -x * comb_r + y * leg], axis=-1) * inv_d_sq

    def free_lines(inv_horizon: float) -> tuple[np.ndarray, np.ndarray]:
        """(direction, u) when not colliding; w: cut-off centre -> relative velocity."""
        w = rel_vel - inv_horizon * rel_pos
        w_len_sq = _dot(w, w)
        dot1 = _dot(w, rel_pos)
        on_cutoff = ((dot1 < 0.0) & (dot1**2 > comb_r_sq * w_len_sq))[..., None]
        w_len = np.sqrt(w_len_sq)
        unit_w = w / np.maximum(w_len, _TINY)[..., None]
        cut_dir = np.stack([unit_w[..., 1], -unit_w[..., 0]], axis=-1)
        cut_u = (comb_r * inv_horizon - w_len)[..., None] * unit_w
        leg_dir = np.where((_det(rel_pos, w) > 0.0)[..., None], left_leg, right_leg)
        leg_u = _dot(rel_vel, leg_dir)[..., None] * leg_dir - rel_vel
        return np.where(on_cutoff, cut_dir, leg_dir), np.where(on_cutoff, cut_u, leg_u)

    # Collision: project on the cut-off circle of one time step so that the overlap is
    # resolved within dt.
    w_c = rel_vel - inv_dt * rel_pos
    w_c_len = np.sqrt(_dot(w_c, w_c))
    # w_c = 0 (relative velocity exactly undoing the overlap in one step) or coincident
    # centres: push away from the neighbour, or along +-x by index order for coincident ones.
    away = -rel_pos * np.sqrt(inv_d_sq)
    sign = np.where(np.arange(n_active)[:, None] < nbr, 1.0, -1.0)
    axis_dir = np.stack([sign, np.zeros_like(sign)], axis=-1)
    away = np.where((d_sq > _TINY)[..., None], away, axis_dir)
    unit_wc = np.where((w_c_len > _TINY)[..., None], w_c / np.maximum(w_c_len, _TINY)[..., None], away)
    col_dir = np.stack([unit_wc[..., 1], -unit_wc[..., 0]], axis=-1)
    col_u = (comb_r * inv_dt - w_c_len)[..., None] * unit_wc

    collide = d_sq <= comb_r_sq
    # Reciprocity: half of the correction when the neighbour is active (it does the other
    # half), all of it when it is passive (a robot that will not react).
    share = np.where(nbr < n_active, 0.5, 1.0)[..., None]
    v_a = vel[:n_active, None, :]

    free_dir, free_u = free_lines(1.0 / params.time_horizon)
    direction = np.where(collide[..., None], col_dir, free_dir)
    point = v_a + share * np.where(collide[..., None], col_u, free_u)

    step_dir, step_u = free_lines(inv_dt)
    step_point = v_a + share * step_u
    return point, direction, valid, step_point, step_dir, valid & ~collide


def _obstacle_lines(
    pos: np.ndarray,
    vel: np.ndarray,
    radius: np.ndarray,
    max_speed: np.ndarray,
    segments: np.ndarray,
    params: OrcaParams,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """ORCA lines of n agents w.r.t. M wall segments, RVO2's obstacle branch vectorised.

    Returns:
        point (n, K, 2), direction (n, K, 2) and accepted (n, K) for the K <= M segments in
        range, in the order in which RVO2 adds them (nearest first); entries that are not
        accepted are padding.
    """
    n = pos.shape[0]
    inv_tho = 1.0 / params.time_horizon_obst
    p = pos[:, None, :]
    v = vel[:, None, :]
    r = radius[:, None]
    r_sq = r**2

    # Neighbouring segments (RVO2: point-segment distance below the range, nearest first).
    # Everything below runs on the (n, K) in-range pairs only, K = max count per agent.
    seg_a, seg_ab = segments[None, :, 0, :], segments[None, :, 1, :] - segments[None, :, 0, :]
    s_all = np.clip(_dot(p - seg_a, seg_ab) / _dot(seg_ab, seg_ab), 0.0, 1.0)
    closest = seg_a + s_all[..., None] * seg_ab - p
    dist_sq_seg = _dot(closest, closest)
    range_sq = (params.time_horizon_obst * max_speed + radius) ** 2
    in_range_all = dist_sq_seg < range_sq[:, None]
    k_max = int(in_range_all.sum(axis=1).max(initial=0))
    if k_max == 0:
        return np.zeros((n, 0, 2)), np.zeros((n, 0, 2)), np.zeros((n, 0), dtype=bool)
    order = np.argsort(np.where(in_range_all, dist_sq_seg, np.inf), axis=1, kind="stable")[:, :k_max]
    rows = np.arange(n)[:, None]
    in_range = in_range_all[rows, order]
    m = k_max

    a = segments[order, 0, :]  # (n, K, 2)
    b = segments[order, 1, :]
    # RVO2 only uses the polygon edge that has the agent on its right; for a free segment
    # that is the orientation facing the agent (a collinear agent keeps a -> b).
    flip = (_det(a - p, b - a) > 0.0)[..., None]
    p1 = np.where(flip, b, a)  # (n, K, 2)
    p2 = np.where(flip, a, b)
    edge = p2 - p1
    unit_dir = edge / np.sqrt(_dot(edge, edge))[..., None]

    rel1 = p1 - p
    rel2 = p2 - p
    dist_sq1 = _dot(rel1, rel1)
    dist_sq2 = _dot(rel2, rel2)
    s = _dot(-rel1, edge) / _dot(edge, edge)
    foot = -rel1 - s[..., None] * edge
    dist_sq_line = _dot(foot, foot)

    point = np.zeros((n, m, 2))
    direction = np.zeros((n, m, 2))
    has_line = np.zeros((n, m), dtype=bool)

    # --- Already colliding with a vertex or the segment itself.
    col_left = (s < 0.0) & (dist_sq1 <= r_sq)
    col_right = ~col_left & (s > 1.0) & (dist_sq2 <= r_sq)
    col_seg = ~col_left & ~col_right & (s >= 0.0) & (s <= 1.0) & (dist_sq_line <= r_sq)
    fallback = unit_dir
    direction = np.where(col_left[..., None], _normalize(_perp(rel1), fallback), direction)
    has_line |= col_left
    # The right vertex is skipped when the neighbouring edge (the reversed segment) handles it.
    take_right = col_right & (_det(rel2, -unit_dir) >= 0.0)
    direction = np.where(take_right[..., None], _normalize(_perp(rel2), fallback), direction)
    has_line |= take_right
    direction = np.where(col_seg[..., None], -unit_dir, direction)
    has_line |= col_seg
    collide = col_left | col_right | col_seg

    # --- No collision: legs of the truncated velocity obstacle. Viewed obliquely, both legs
    # come from a single vertex ("same").
    free = ~collide
    only_left = free & (s < 0.0) & (dist_sq_line <= r_sq)
    only_right = free & ~only_left & (s > 1.0) & (dist_sq_line <= r_sq)
    same = only_left | only_right

    def legs(rel: np.ndarray, dist_sq: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        leg = np.sqrt(np.maximum(dist_sq - r_sq, 0.0))
        x, y = rel[..., 0], rel[..., 1]
        inv = (1.0 / np.maximum(dist_sq, _TINY))[..., None]
        left = np.stack([x * leg - y * r, x * r + y * leg], axis=-1) * inv
        right = np.stack([x * leg + y * r, -x * r + y * leg], axis=-1) * inv
        return left, right

    left1, right1 = legs(rel1, dist_sq1)
    left2, right2 = legs(rel2, dist_sq2)
    ol = only_left[..., None]
    orr = only_right[..., None]
    left_leg = np.where(orr, left2, left1)
    right_leg = np.where(ol, right1, right2)
    o1_point = np.where(orr, p2, p1)
    o2_point = np.where(ol, p1, p2)
    o1_dir = np.where(orr, -unit_dir, unit_dir)  # unitDir of "obstacle1" after the swap
    o2_dir = np.where(ol, unit_dir, -unit_dir)  # unitDir of "obstacle2" after the swap
    # Both vertices are convex, so a leg pointing into the neighbouring (reversed) edge is
    # replaced by that edge's direction; it is then "foreign" and adds no constraint.
    left_nb = np.where(orr, -unit_dir, unit_dir)  # -prevObstacle->unitDir of obstacle1
    left_foreign = _det(left_leg, left_nb) >= 0.0
    left_leg = np.where(left_foreign[..., None], left_nb, left_leg)
    right_foreign = _det(right_leg, o2_dir) <= 0.0
    right_leg = np.where(right_foreign[..., None], o2_dir, right_leg)

    left_cut = inv_tho * (o1_point - p)
    right_cut = inv_tho * (o2_point - p)
    cut_vec = right_cut - left_cut
    t = np.where(same, 0.5, _dot(v - left_cut, cut_vec) / np.maximum(_dot(cut_vec, cut_vec), _TINY))
    t_left = _dot(v - left_cut, left_leg)
    t_right = _dot(v - right_cut, right_leg)
    rr = (r * inv_tho)[..., None]

    proj_left = free & (((t < 0.0) & (t_left < 0.0)) | (same & (t_left < 0.0) & (t_right < 0.0)))
    proj_right = free & ~proj_left & (t > 1.0) & (t_right < 0.0)
    unit_wl = _normalize(v - left_cut, _normalize(-left_cut, fallback))
    unit_wr = _normalize(v - right_cut, _normalize(-right_cut, fallback))
    for mask, unit_w, cut in ((proj_left, unit_wl, left_cut), (proj_right, unit_wr, right_cut)):
        mk = mask[..., None]
        direction = np.where(mk, np.stack([unit_w[..., 1], -unit_w[..., 0]], axis=-1), direction)
        point = np.where(mk, cut + rr * unit_w, point)
        has_line |= mask

    rest = free & ~proj_left & ~proj_right
    inf = np.inf
    d_cut = np.where(
        (t < 0.0) | (t > 1.0) | same,
        inf,
        _dot(v - (left_cut + t[..., None] * cut_vec), v - (left_cut + t[..., None] * cut_vec)),
    )
    q_left = v - (left_cut + t_left[..., None] * left_leg)
    q_right = v - (right_cut + t_right[..., None] * right_leg)
    d_left = np.where(t_left < 0.0, inf, _dot(q_left, q_left))
    d_right = np.where(t_right < 0.0, inf, _dot(q_right, q_right))
    use_cut = rest & (d_cut <= d_left) & (d_cut <= d_right)
    use_left = rest & ~use_cut & (d_left <= d_right)
    use_right = rest & ~use_cut & ~use_left
    for mask, line_dir, cut, ok in (
        (use_cut, -o1_dir, left_cut, use_cut),
        (use_left, left_leg, left_cut, use_left & ~left_foreign),
        (use_right, -right_leg, right_cut, use_right & ~right_foreign),
    ):
        mk = mask[..., None]
        direction = np.where(mk, line_dir, direction)
        point = np.where(mk, cut + rr * _perp(line_dir), point)
        has_line |= ok

    # --- RVO2 skips an obstacle whose two endpoints are already behind (by >= radius) an
    # obstacle line added before it; segments are processed nearest first. covered[i, k, j]:
    # segment k is covered by the line of segment j.
    # det(e_k - point_j, dir_j) = e_k . (dir_j.y, -dir_j.x) - det(point_j, dir_j), done as a
    # batched matrix product rather than an (n, K, K, 2) temporary.
    normal = np.stack([direction[..., 1], -direction[..., 0]], axis=1)  # (n, 2, K)
    offset = _det(point, direction)[:, None, :]  # (n, 1, K)
    tol = (r * inv_tho)[..., None] - _RVO_EPS  # (n, 1, 1)
    covered_by = (inv_tho * rel1 @ normal - offset >= tol) & (inv_tho * rel2 @ normal - offset >= tol)

    covered = np.zeros((n, m), dtype=bool)
    accepted = np.zeros((n, m), dtype=bool)
    idx = np.arange(n)
    for k in range(m):  # columns are already sorted nearest first
        acc = in_range[:, k] & ~covered[:, k] & has_line[:, k]
        accepted[:, k] = acc
        covered |= acc[:, None] & covered_by[idx, :, k]
    return point, direction, accepted


# --------------------------------------------------------------------------------------------
# Linear programs (RVO2's linearProgram1/2/3) on Python floats: per agent there are only a
# few lines, and scalar float arithmetic is far cheaper than numpy calls at this size.


def _lp1(
    px: list[float],
    py: list[float],
    dx: list[float],
    dy: list[float],
    no: int,
    radius: float,
    ox: float,
    oy: float,
    direction_opt: bool,
) -> tuple[float, float] | None:
    """Optimum on line ``no`` subject to lines ``[0, no)`` and the speed disc; None if empty."""
    lpx, lpy, ldx, ldy = px[no], py[no], dx[no], dy[no]
    dot = lpx * ldx + lpy * ldy
    disc = dot * dot + radius * radius - (lpx * lpx + lpy * lpy)
    if disc < 0.0:
        return None  # the speed disc fully invalidates this line
    sq = math.sqrt(disc)
    t_left = -dot - sq
    t_right = -dot + sq
    for i in range(no):
        denom = ldx * dy[i] - ldy * dx[i]
        numer = dx[i] * (lpy - py[i]) - dy[i] * (lpx - px[i])
        if abs(denom) <= _RVO_EPS:
            if numer < 0.0:
                return None  # parallel and on the wrong side
            continue
        t = numer / denom
        if denom >= 0.0:
            t_right = min(t_right, t)
        else:
            t_left = max(t_left, t)
        if t_left > t_right:
            return None
    if direction_opt:
        t = t_right if ox * ldx + oy * ldy > 0.0 else t_left
    else:
        t = ldx * (ox - lpx) + ldy * (oy - lpy)
        t = min(max(t, t_left), t_right)
    return lpx + t * ldx, lpy + t * ldy


def _lp2(
    px: list[float],
    py: list[float],
    dx: list[float],
    dy: list[float],
    radius: float,
    ox: float,
    oy: float,
    direction_opt: bool,
) -> tuple[int, float, float]:
    """Incremental LP; returns (index of the first infeasible line or len, x, y)."""
    if direction_opt:
        rx, ry = ox * radius, oy * radius
    else:
        norm_sq = ox * ox + oy * oy
        if norm_sq > radius * radius:
            scale = radius / math.sqrt(norm_sq)
            rx, ry = ox * scale, oy * scale
        else:
            rx, ry = ox, oy
    for i in range(len(px)):
        if dx[i] * (py[i] - ry) - dy[i] * (px[i] - rx) > 0.0:
            res = _lp1(px, py, dx, dy, i, radius, ox, oy, direction_opt)
            if res is None:
                return i, rx, ry
            rx, ry = res
    return len(px), rx, ry


def _lp3(
    px: list[float],
    py: list[float],
    dx: list[float],
    dy: list[float],
    n_obst: int,
    begin: int,
    radius: float,
    rx: float,
    ry: float,
) -> tuple[float, float]:
    """Infeasible case: minimise the largest violation of agent lines, obstacles stay hard."""
    distance = 0.0
    for i in range(begin, len(px)):
        if dx[i] * (py[i] - ry) - dy[i] * (px[i] - rx) > distance:
            qpx, qpy, qdx, qdy = px[:n_obst], py[:n_obst], dx[:n_obst], dy[:n_obst]
            for j in range(n_obst, i):
                det = dx[i] * dy[j] - dy[i] * dx[j]
                if abs(det) <= _RVO_EPS:
                    if dx[i] * dx[j] + dy[i] * dy[j] > 0.0:
                        continue  # same direction: line j is implied
                    lx = 0.5 * (px[i] + px[j])
                    ly = 0.5 * (py[i] + py[j])
                else:
                    f = (dx[j] * (py[i] - py[j]) - dy[j] * (px[i] - px[j])) / det
                    lx = px[i] + f * dx[i]
                    ly = py[i] + f * dy[i]
                ddx = dx[j] - dx[i]
                ddy = dy[j] - dy[i]
                norm = math.hypot(ddx, ddy)
                qpx.append(lx)
                qpy.append(ly)
                qdx.append(ddx / norm)
                qdy.append(ddy / norm)
            fail, nx, ny = _lp2(qpx, qpy, qdx, qdy, radius, -dy[i], dx[i], True)
            # Failure can only come from rounding (the current result is feasible); keep it.
            if fail >= len(qpx):
                rx, ry = nx, ny
            distance = dx[i] * (py[i] - ry) - dy[i] * (px[i] - rx)
    return rx, ry


def _solve_agent(
    point: np.ndarray,
    direction: np.ndarray,
    regular: np.ndarray,
    valid: np.ndarray,
    n_obst: int,
    n_step: int,
    max_speed: float,
    target: list[float],
    one_step_safety: bool,
) -> tuple[float, float]:
    """New velocity of one agent from its lines laid out as [obstacle | one-step | agent].

    RVO2: linearProgram2 on the obstacle and agent lines; if infeasible, linearProgram3
    keeps obstacle lines hard and minimises the largest agent-line violation. With
    ``one_step_safety`` the infeasible case is solved again with the one-step lines added to
    the hard prefix, or, if even those conflict, by minimising their violation instead.
    """
    px, py = point[regular, 0].tolist(), point[regular, 1].tolist()
    dx, dy = direction[regular, 0].tolist(), direction[regular, 1].tolist()
    tx, ty = target
    fail, rx, ry = _lp2(px, py, dx, dy, max_speed, tx, ty, False)
    if fail == len(px):
        return rx, ry
    if not one_step_safety:
        return _lp3(px, py, dx, dy, n_obst, fail, max_speed, rx, ry)
    px, py = point[valid, 0].tolist(), point[valid, 1].tolist()
    dx, dy = direction[valid, 0].tolist(), direction[valid, 1].tolist()
    n_hard = n_obst + n_step
    fail, rx, ry = _lp2(px, py, dx, dy, max_speed, tx, ty, False)
    if fail >= n_hard:  # obstacle + one-step lines are jointly feasible
        return _lp3(px, py, dx, dy, n_hard, fail, max_speed, rx, ry)
    return _lp3(px[:n_hard], py[:n_hard], dx[:n_hard], dy[:n_hard], n_obst, fail, max_speed, rx, ry)


def _safety_filter(
    pos: np.ndarray, vel: np.ndarray, new_vel: np.ndarray, radius: np.ndarray, dt: float
) -> np.ndarray:
    """Scale active velocities down so that no new overlap appears during the next step."""
    n_active, n_total = new_vel.shape[0], pos.shape[0]
    p = pos[None, :, :] - pos[:n_active, None, :]  # (n, N, 2): from active i to j
    comb_r = radius[:n_active, None] + radius[None, :]
    c = _dot(p, p) - comb_r**2
    pair = np.ones(c.shape, dtype=bool)
    pair[np.arange(n_active), np.arange(n_active)] = False
    passive = np.arange(n_total)[None, :] >= n_active

    def conflicts(v_active: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        v_all = vel.copy()
        v_all[:n_active] = v_active
        v = v_all[None, :, :] - v_all[:n_active, None, :]  # velocity of j relative to i
        a = _dot(v, v)
        b = 2.0 * _dot(p, v)
        disc = b * b - 4.0 * a * c
        t_hit = (-b - np.sqrt(np.maximum(disc, 0.0))) / np.maximum(2.0 * a, _TINY)
        hit = pair & (b < 0.0) & ((c <= 0.0) | ((disc > 0.0) & (t_hit < dt)))
        return hit, np.where(c > 0.0, np.clip(t_hit / dt, 0.0, 1.0), 0.0)

    # A passive agent that would hit i even if i stood still cannot be helped by slowing i.
    hit_if_still, _ = conflicts(np.zeros_like(new_vel))
    pair &= ~(passive & hit_if_still)

    scale = np.ones(n_active)
    for _ in range(8):
        hit, frac = conflicts(new_vel * scale[:, None])
        if not hit.any():
            return new_vel * scale[:, None]
        # Slowing both members of a pair by t_hit/dt delays the contact to the end of the step.
        factor = np.where(hit, 0.999 * frac, 1.0)
        f_j = np.ones(n_total)
        np.minimum.at(f_j, np.nonzero(hit)[1], factor[hit])
        scale *= np.minimum(factor.min(axis=1), f_j[:n_active])
    # Rare dense knots: stop whoever is still involved (relative motion among stopped
    # active agents is zero, so this terminates).
    for _ in range(n_active):
        hit, _ = conflicts(new_vel * scale[:, None])
        if not hit.any():
            break
        involved = hit.any(axis=1)
        involved[np.nonzero(hit)[1][np.nonzero(hit)[1] < n_active]] = True
        scale[involved] = 0.0
    return new_vel * scale[:, None]


# --------------------------------------------------------------------------------------------


def _rows(name: str, value: np.ndarray | float, n_total: int, n_active: int, width: int) -> np.ndarray:
    """Per-agent array with n_total or n_active rows (scalars broadcast when width == 0)."""
    arr = np.asarray(value, dtype=float)
    if width == 0 and arr.ndim == 0:
        return np.full(n_total, float(arr))
    shape_tail = (width,) if width else ()
    if arr.shape in ((n_total, *shape_tail), (n_active, *shape_tail)):
        return arr
    raise ValueError(
        f"{name} must have shape {(n_total, *shape_tail)} or {(n_active, *shape_tail)}"
        f"{' or be a scalar' if width == 0 else ''}, got {arr.shape}"
    )


def orca_velocities(
    pos: np.ndarray,
    vel: np.ndarray,
    pref_vel: np.ndarray,
    radius: np.ndarray | float,
    max_speed: np.ndarray | float,
    dt: float,
    params: OrcaParams,
    segments: np.ndarray | None = None,
    n_active: int | None = None,
) -> np.ndarray:
    """New ORCA velocities of the active agents.

    Args:
        pos: Positions of all N agents, (N, 2) m. Agents ``[0, n_active)`` are active.
        vel: Current velocities, (N, 2) m/s (used for passive agents as their prediction).
        pref_vel: Preferred velocities, (N, 2) or (n_active, 2) m/s.
        radius: Radii, (N,) m or a scalar.
        max_speed: Speed limits, (N,) or (n_active,) m/s or a scalar, >= 0.
        dt: Control period (s), > 0: existing overlaps are resolved within dt and, with
            ``one_step_safety``, no new overlap may appear within dt.
        params: ORCA parameters.
        segments: Wall segments, (M, 2, 2) m; None or M = 0 for none. Zero-length segments
            are ignored.
        n_active: Number of active agents (default N). Agents ``[n_active, N)`` are passive
            (e.g. robots): avoided with full responsibility, not updated.

    Returns:
        New velocities of the active agents, (n_active, 2) m/s, each with speed <= max_speed.

    Raises:
        ValueError: On inconsistent shapes or invalid dt / n_active / max_speed / radius.
    """
    pos = np.asarray(pos, dtype=float)
    if pos.ndim != 2 or pos.shape[1] != 2:
        raise ValueError(f"pos must have shape (N, 2), got {pos.shape}")
    n_total = pos.shape[0]
    if n_active is None:
        n_active = n_total
    if (
        isinstance(n_active, bool)
        or not isinstance(n_active, int | np.integer)
        or not 0 <= n_active <= n_total
    ):
        raise ValueError(f"n_active must be in [0, {n_total}], got {n_active!r}")
    if not dt > 0.0:
        raise ValueError(f"dt must be > 0, got {dt!r}")
    vel = np.asarray(vel, dtype=float)
    if vel.shape != (n_total, 2):
        raise ValueError(f"vel must have shape ({n_total}, 2), got {vel.shape}")
    pref_vel = _rows("pref_vel", pref_vel, n_total, n_active, 2)[:n_active]
    radius = _rows("radius", radius, n_total, n_total, 0)
    if np.any(radius < 0):
        raise ValueError(f"radius must be >= 0, got min {radius.min()!r}")
    max_speed = _rows("max_speed", max_speed, n_total, n_active, 0)[:n_active]
    if np.any(max_speed < 0):
        raise ValueError(f"max_speed must be >= 0, got min {max_speed.min()!r}")
    if segments is None or np.asarray(segments).size == 0:
        seg = np.zeros((0, 2, 2))
    else:
        seg = np.asarray(segments, dtype=float)
        if seg.ndim != 3 or seg.shape[1:] != (2, 2):
            raise ValueError(f"segments must have shape (M, 2, 2), got {seg.shape}")
        seg = seg[np.linalg.norm(seg[:, 1] - seg[:, 0], axis=1) > 1e-9]
    if n_active == 0:
        return np.zeros((0, 2))

    a_point, a_dir, a_valid, h_point, h_dir, h_valid = _agent_lines(pos, vel, radius, n_active, params, dt)
    if seg.shape[0]:
        o_point, o_dir, o_valid = _obstacle_lines(
            pos[:n_active], vel[:n_active], radius[:n_active], max_speed, seg, params
        )
    else:
        o_point = o_dir = np.zeros((n_active, 0, 2))
        o_valid = np.zeros((n_active, 0), dtype=bool)
    # Line layout per agent: [obstacle lines | one-step lines | agent lines]. The one-step
    # lines only take part when the regular program is infeasible (see _solve_agent).
    point = np.concatenate([o_point, h_point, a_point], axis=1)
    direction = np.concatenate([o_dir, h_dir, a_dir], axis=1)
    valid = np.concatenate([o_valid, h_valid, a_valid], axis=1)
    regular = valid.copy()
    regular[:, o_valid.shape[1] : o_valid.shape[1] + h_valid.shape[1]] = False
    n_obst = o_valid.sum(axis=1)
    n_step = h_valid.sum(axis=1)

    # Start from the preferred velocity clipped to the speed disc (what linearProgram2 does)
    # and skip the sequential LP for agents that violate none of their lines.
    speed = np.linalg.norm(pref_vel, axis=1)
    opt = pref_vel * np.minimum(1.0, max_speed / np.maximum(speed, _TINY))[:, None]
    violated = regular & (_det(direction, point - opt[:, None, :]) > 0.0)
    result = opt.copy()
    # Target of the LP: the preferred velocity turned right by right_bias.
    cos_b, sin_b = math.cos(params.right_bias), math.sin(params.right_bias)
    target = np.stack(
        [cos_b * pref_vel[:, 0] + sin_b * pref_vel[:, 1], -sin_b * pref_vel[:, 0] + cos_b * pref_vel[:, 1]],
        axis=1,
    ).tolist()
    for i in np.flatnonzero(violated.any(axis=1) & (max_speed > 0.0)):
        result[i] = _solve_agent(
            point[i],
            direction[i],
            regular[i],
            valid[i],
            int(n_obst[i]),
            int(n_step[i]),
            float(max_speed[i]),
            target[i],
            params.one_step_safety,
        )
    if params.one_step_safety:
        result = _safety_filter(pos, vel, result, radius, dt)
    # Rounding in the LP can exceed the disc by ~1e-16; keep the documented bound exact.
    speed = np.linalg.norm(result, axis=1)
    over = speed > max_speed
    result[over] *= (max_speed[over] / speed[over])[:, None]
    return result
