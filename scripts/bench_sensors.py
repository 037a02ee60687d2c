"""Time the rendered cameras and the 2D lidar in Lobby-v0 with its default crowd.

Usage::

    .venv/bin/python scripts/bench_sensors.py [--calls 20] [--env navzoo/Lobby-v0] [--egl]

Prints the median (and 10th / 90th percentile) milliseconds per call over ``--calls`` calls, one call
per env step (the env is stepped with random robot actions between calls; stepping is not timed).

``--egl`` renders with PyBullet's EGL plugin instead of TinyRenderer (``NavConfig(egl=True)``: the
plugin is loaded as the env connects and polygon obstacles get OBJ visual meshes, which EGL draws);
it exits with a message where EGL is not available.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import navzoo
from navzoo.sensors import (
    Lidar2D,
    default_robot_cameras,
    render_camera,
    render_robot_cameras,
    render_robot_lidar,
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--calls", type=int, default=20)
    ap.add_argument("--env", default="navzoo/Lobby-v0")
    ap.add_argument("--egl", action="store_true", help="render with the EGL plugin (see above)")
    args = ap.parse_args()

    renderer = "EGL" if args.egl else "TinyRenderer"
    env = navzoo.make(args.env, egl=args.egl)  # robots learnable, people on the default crowd model
    if args.egl and not env.unwrapped.egl:
        raise SystemExit("EGL is not available here")
    base = env.unwrapped
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    from navzoo.machine import cpu_model

    cpu = cpu_model()
    print(
        f"{args.env}: {base.n_robots} robot(s), {base.n_humans} people; {cpu}, {os.cpu_count()} CPUs; {renderer}"
    )

    def step() -> None:
        if not env.agents:
            env.reset(seed=int(rng.integers(1 << 30)))
        env.step({a: env.action_space(a).sample() for a in env.agents})

    def pose() -> tuple[float, float, float]:
        return (float(base.pos[0, 0]), float(base.pos[0, 1]), float(base.yaw[0]))

    lidar = Lidar2D()  # 360 rays, 10 m
    cases = {}
    for w, h in ((640, 480), (320, 240)):
        cam = default_robot_cameras(w, h)[0]
        robot_id = base.robots.ids[0]
        cases[f"render_camera {w}x{h} (1 camera)"] = lambda cam=cam, robot_id=robot_id: render_camera(
            base.client, cam, pose(), hide_body_ids=[robot_id]
        )
        cams = default_robot_cameras(w, h)
        cases[f"render_robot_cameras {w}x{h} (2 cameras)"] = lambda cams=cams: render_robot_cameras(
            env, 0, cams
        )
    cases["render_robot_lidar 360 rays (people revealed)"] = lambda: render_robot_lidar(env, 0, lidar)
    cases["Lidar2D.scan 360 rays (no reveal)"] = lambda: lidar.scan(base.client, pose())

    for name, fn in cases.items():
        fn()  # warm-up
        times = []
        for _ in range(args.calls):
            step()
            t0 = time.perf_counter()
            fn()
            times.append(1e3 * (time.perf_counter() - t0))
        q10, med, q90 = np.percentile(times, [10, 50, 90])
        print(f"{name:48s} median {med:7.2f} ms  (p10 {q10:6.2f}, p90 {q90:6.2f}, n={len(times)})")
    env.close()


if __name__ == "__main__":
    main()
