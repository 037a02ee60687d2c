"""Micro-benchmark of the crowd models: wall-clock time per call of SFM and ORCA.

Usage::

    python -m navzoo.agents.crowd_bench [--agents 5 20 64] [--segments 40] [--calls 100]
    python -m navzoo.agents.crowd_bench --behaviour     # the behaviour figures of docs/crowd_models.md

Scene: a 14 m x 14 m room (4 wall segments) plus square pillars (4 segments each) up to
``--segments`` walls, N agents at random non-overlapping positions walking to random goals
(pedestrians re-target when they arrive). The states come from a short warm-up so that the
timed calls see realistic encounters. Time is measured per call with ``perf_counter`` and
reported as median and mean in milliseconds.
"""

from __future__ import annotations

import argparse
import platform
import time
from collections.abc import Callable

import numpy as np

from navzoo.agents.orca import OrcaParams, orca_velocities
from navzoo.agents.sfm import SocialForceParams, social_force_velocities
from navzoo.machine import cpu_model

HALF = 7.0
RADIUS = 0.3
SPEED = 1.2
DT = 0.1


def make_segments(n_segments: int) -> np.ndarray:
    """Room walls plus 0.6 m square pillars on a grid, ``n_segments`` segments in total."""
    corners = [(-HALF, -HALF), (HALF, -HALF), (HALF, HALF), (-HALF, HALF)]
    segments = [[corners[i], corners[(i + 1) % 4]] for i in range(4)]
    grid = [(x, y) for y in (-4.0, 0.0, 4.0) for x in (-4.0, 0.0, 4.0)]
    grid += [(x, y) for y in (-2.0, 2.0) for x in (-2.0, 2.0)]
    for cx, cy in grid:
        if len(segments) + 4 > n_segments:
            break
        h = 0.3
        sq = [(cx - h, cy - h), (cx + h, cy - h), (cx + h, cy + h), (cx - h, cy + h)]
        segments += [[sq[i], sq[(i + 1) % 4]] for i in range(4)]
    return np.array(segments[:n_segments], dtype=float)


def segment_groups(segments: np.ndarray) -> np.ndarray:
    """Wall id of each segment of :func:`make_segments`: the 4 room walls, then 4 edges per pillar."""
    m = len(segments)
    return np.concatenate([np.arange(min(m, 4)), 4 + np.arange(max(0, m - 4)) // 4])


def _free_points(rng: np.random.Generator, n: int, segments: np.ndarray) -> np.ndarray:
    """n points in the room, clear of each other and of the walls."""
    a, ab = segments[:, 0], segments[:, 1] - segments[:, 0]
    points: list[np.ndarray] = []
    while len(points) < n:
        p = rng.uniform(-HALF + 0.5, HALF - 0.5, 2)
        t = np.clip(np.einsum("md,md->m", p - a, ab) / np.einsum("md,md->m", ab, ab), 0.0, 1.0)
        if np.min(np.linalg.norm(p - (a + t[:, None] * ab), axis=1)) < 2 * RADIUS:
            continue
        if points and np.min(np.linalg.norm(np.array(points) - p, axis=1)) < 3 * RADIUS:
            continue
        points.append(p)
    return np.array(points)


def _time_model(
    step: Callable[..., np.ndarray], n: int, segments: np.ndarray, calls: int, seed: int
) -> np.ndarray:
    rng = np.random.default_rng(seed)
    pos = _free_points(rng, n, segments)
    goal = _free_points(rng, n, segments)
    vel = np.zeros_like(pos)
    times = []
    for k in range(20 + calls):
        delta = goal - pos
        dist = np.linalg.norm(delta, axis=1, keepdims=True)
        done = dist[:, 0] < 0.3
        if done.any():
            goal[done] = _free_points(rng, int(done.sum()), segments)
            delta = goal - pos
            dist = np.linalg.norm(delta, axis=1, keepdims=True)
        pref = delta / np.maximum(dist, 1e-9) * SPEED
        t0 = time.perf_counter()
        vel = step(pos, vel, pref, np.full(n, RADIUS), np.full(n, SPEED), DT, segments)
        if k >= 20:
            times.append(time.perf_counter() - t0)
        pos = pos + DT * vel
    return np.array(times)


def run(agents: list[int], n_segments: int = 40, calls: int = 100, seed: int = 0) -> list[dict[str, float]]:
    """Benchmark both models; returns one row per (model, N) with median/mean ms per call."""
    segments = make_segments(n_segments)
    sfm_params, orca_params = SocialForceParams(), OrcaParams()

    groups = segment_groups(segments)

    def sfm(pos, vel, pref, rad, vmax, dt, seg):  # noqa: ANN001, ANN202
        return social_force_velocities(pos, vel, pref, rad, vmax, dt, sfm_params, seg, segment_groups=groups)

    def orca(pos, vel, pref, rad, vmax, dt, seg):  # noqa: ANN001, ANN202
        return orca_velocities(pos, vel, pref, rad, vmax, dt, orca_params, seg)

    rows = []
    for name, step in (("sfm", sfm), ("orca", orca)):
        for n in agents:
            t = _time_model(step, n, segments, calls, seed) * 1e3
            rows.append(
                {
                    "model": name,
                    "agents": n,
                    "segments": len(segments),
                    "median_ms": float(np.median(t)),
                    "mean_ms": float(t.mean()),
                }
            )
    return rows


def _model(name: str, segments: np.ndarray) -> Callable[..., np.ndarray]:
    groups = np.arange(len(segments))
    if name == "sfm":
        return lambda pos, vel, pref, rad, vmax, dt: social_force_velocities(
            pos, vel, pref, rad, vmax, dt, SocialForceParams(), segments, segment_groups=groups)
    return lambda pos, vel, pref, rad, vmax, dt: orca_velocities(pos, vel, pref, rad, vmax, dt, OrcaParams(), segments)


def _walk(name: str, pos: np.ndarray, goal: np.ndarray, segments: np.ndarray, dt: float, t_max: float,
          speed: float = SPEED) -> dict[str, float]:
    """Agents walk straight-line preferred velocities to their goals; returns arrival and gap figures."""
    step = _model(name, segments)
    n = len(pos)
    pos, vel = pos.astype(float).copy(), np.zeros((n, 2))
    rad, vmax = np.full(n, RADIUS), np.full(n, 1.3 * speed)
    arrived_at = np.full(n, np.nan)
    min_gap, min_wall = np.inf, np.inf
    for k in range(int(round(t_max / dt))):
        d = goal - pos
        dist = np.linalg.norm(d, axis=1, keepdims=True)
        pref = np.where(dist > 1e-9, d / np.maximum(dist, 1e-9) * np.minimum(speed, dist / dt), 0.0)
        vel = step(pos, vel, pref, rad, vmax, dt)
        pos = pos + dt * vel
        if n > 1:
            cd = np.linalg.norm(pos[:, None] - pos[None], axis=2) + np.eye(n) * 1e9
            min_gap = min(min_gap, float(cd.min()) - 2 * RADIUS)
        if len(segments):
            from navzoo.world.geometry import min_distance_to_segments

            min_wall = min(min_wall, float(min_distance_to_segments(pos, segments).min()) - RADIUS)
        newly = np.isnan(arrived_at) & (np.linalg.norm(goal - pos, axis=1) < 0.1)
        arrived_at[newly] = (k + 1) * dt
    return {"arrived": float(np.mean(~np.isnan(arrived_at))), "last_arrival_s": float(np.nanmax(arrived_at))
            if (~np.isnan(arrived_at)).any() else float("nan"), "min_gap_m": min_gap, "min_wall_gap_m": min_wall,
            "final_pos": pos}


def behaviour() -> list[str]:
    """The behaviour figures quoted in docs/crowd_models.md (head-on swap, circle of 20, wall)."""
    lines = []
    room = np.array([[[-HALF, -HALF], [HALF, -HALF]], [[HALF, -HALF], [HALF, HALF]],
                     [[HALF, HALF], [-HALF, HALF]], [[-HALF, HALF], [-HALF, -HALF]]], float)
    none = np.zeros((0, 2, 2))
    for name in ("sfm", "orca"):
        for dt in (0.1, 0.25):
            r = _walk(name, np.array([[-4.0, 0.0], [4.0, 0.0]]), np.array([[4.0, 0.0], [-4.0, 0.0]]), none, dt, 20.0)
            lines.append(f"{name} head-on swap dt={dt}: arrived {r['arrived']:.0%} by {r['last_arrival_s']:.2f} s, "
                         f"smallest surface gap {r['min_gap_m']:.3f} m")
        for dt in (0.1, 0.25):
            arrived, gaps, walls = [], [], []
            for seed in range(8):
                rng = np.random.default_rng(seed)
                ang = np.linspace(0, 2 * np.pi, 20, endpoint=False)
                start = 5.0 * np.stack([np.cos(ang), np.sin(ang)], 1) + rng.uniform(-0.01, 0.01, (20, 2))
                r = _walk(name, start, -start, room, dt, 40.0)
                arrived.append(r["arrived"])
                gaps.append(r["min_gap_m"])
                walls.append(r["min_wall_gap_m"])
            lines.append(f"{name} circle of 20 (r 5 m, 14 m room, 8 seeds) dt={dt}: arrived {np.mean(arrived):.1%} "
                         f"within 40 s, smallest surface gap {min(gaps):+.3f} m, smallest wall gap {min(walls):+.3f} m")
        wall = np.array([[[-2.0, 2.0], [2.0, 2.0]]])
        for speed in (1.2, 2.0):
            r = _walk(name, np.array([[0.0, 0.0]]), np.array([[0.0, 5.0]]), wall, 0.1, 10.0, speed=speed)
            lines.append(f"{name} walking at a 4 m wall (goal behind it) at {speed} m/s: ends {2.0 - r['final_pos'][0, 1]:.2f} m "
                         f"from the wall (centre), smallest surface gap to it {r['min_wall_gap_m']:+.3f} m")
    return lines


def main(argv: list[str] | None = None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--agents", type=int, nargs="+", default=[5, 20, 64])
    parser.add_argument("--segments", type=int, default=40)
    parser.add_argument("--calls", type=int, default=100)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--behaviour", action="store_true", help="print the behaviour figures instead of timings")
    args = parser.parse_args(argv)
    if args.behaviour:
        print("\n".join(behaviour()))
        return
    print(
        f"python {platform.python_version()}, numpy {np.__version__}, {cpu_model()}"
    )
    print(f"{'model':<6} {'N':>4} {'walls':>5} {'median ms':>10} {'mean ms':>9}")
    for row in run(args.agents, args.segments, args.calls, args.seed):
        print(
            f"{row['model']:<6} {row['agents']:>4} {row['segments']:>5} {row['median_ms']:>10.3f} {row['mean_ms']:>9.3f}"
        )


if __name__ == "__main__":
    main()
