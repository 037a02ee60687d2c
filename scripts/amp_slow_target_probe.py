"""How the AMP controller follows slow targets, and targets that start behind it.

One physics pedestrian stands in the open (the circle-crossing scene, nobody else). At every replan (2 s) its
target path starts at the body and runs straight at ``v`` m/s in one fixed world direction: the body's heading at
the start turned by ``bearing`` degrees (180 = straight behind it). The lag limit holds the target as in the
following protocol. After ``--seconds`` the script reports how far the body got along that direction, when it had
gone 1 m, its heading error, and whether it fell:

    python scripts/amp_slow_target_probe.py --speeds 0.2,0.3,0.45,0.6,0.8,1.0 --bearings 0,45,90,135,180 \\
        --json docs/results/stall_warp/slow_target_probe_vm.json

About 1.5 s per (speed, bearing) pair on a 2-core VM. ``--summary A.json B.json ...`` pools earlier files (one per
``--seed``, say) per speed and bearing.

``--lead-in W --pause P`` makes it a stop-turn-go probe, the motion of a crowd's stop-and-go: the target first walks
straight ahead along the body's first heading at ``--lead-speed`` (default 1.0 m/s) for W s, then stands for P s,
then sets off at ``v`` in the direction ``bearing`` off that first heading; distance, the time to 1 m and the heading
error are then counted from the set-off, over ``--seconds`` after it, and ``fell_at_s`` says when a body fell
(seconds from the set-off, negative before it):

    python scripts/amp_slow_target_probe.py --lead-in 3 --pause 2 --speeds 0.45,1.0 --bearings 0,45,90,135,180
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def _floats(text: str, name: str) -> list[float]:
    try:
        out = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise SystemExit(f"{name} {text!r}: expected comma-separated numbers") from None
    if not out:
        raise SystemExit(f"{name} {text!r}: expected at least one number")
    return out


def probe(speed: float, bearing_deg: float, seconds: float = 12.0, seed: int = 0, policy_dir: str | None = None,
          scene: str = "circle_crossing", lead_in: float = 0.0, pause: float = 0.0, lead_speed: float = 1.0) -> dict:
    """One run: a straight target at ``speed`` m/s, ``bearing_deg`` off the body's first heading; with ``lead_in``
    or ``pause`` (s), first ``lead_in`` s straight ahead at ``lead_speed`` and ``pause`` s standing (the
    stop-turn-go probe of the module docstring)."""
    from navzoo.benchmark import pedestrians as P
    from navzoo.envs import amp_humans as AH

    if speed <= 0 or seconds <= 0:
        raise ValueError(f"speed and seconds must be positive, got {speed}, {seconds}")
    if lead_in < 0 or pause < 0 or (lead_in > 0 and lead_speed <= 0):
        raise ValueError(f"lead-in and pause must be >= 0 and the lead speed positive, got {lead_in}, {pause}, "
                         f"{lead_speed}")
    go = lead_in + pause  # seconds from the start to the set-off
    wrapped, env = P._make(scene, 1, "amp", go + seconds + 5.0, seed, policy_dir, "sfm")
    amp = env.amp
    pos0, hd0, _, _ = amp.planar()
    u0 = np.array([np.cos(hd0[0]), np.sin(hd0[0])])
    yaw = float(hd0[0]) + np.radians(bearing_deg)
    u = np.array([np.cos(yaw), np.sin(yaw)])
    dt = 1.0 / AH.CONTROL_HZ
    t0 = amp.t

    def velocity(t: np.ndarray) -> np.ndarray:  # (k, 2) the target's velocity at t s after the start
        lead = (t < lead_in)[:, None] * (lead_speed * u0)[None]
        return lead + (t >= go)[:, None] * (speed * u)[None]

    def plan_all(who: np.ndarray | None = None) -> None:  # the body's own position, then the schedule on from now
        del who  # one body: every replan (timed, or an event the env passes on) is its own
        pos = amp.planar()[0]
        t = (amp.t - t0) * dt + np.arange(amp.path_len) * dt
        steps = np.concatenate([np.zeros((1, 2)), np.cumsum(velocity(t[:-1]) * dt, axis=0)])
        amp.paths = pos[:, None, :] + steps[None]
        amp.plan_t[:] = amp.t
        amp.k_prog[:] = 0

    amp.plan_all = plan_all
    plan_all()
    t_1m = fell_at = None
    along = 0.0
    start = pos0[0].copy()  # where the body is at the set-off
    while env.sim_time < go + seconds - 1e-9 and not env._needs_reset:
        wrapped.step({})
        t_rel = float(env.sim_time) - go
        pos = env.pos[env.n_robots]  # the body's planar root after the step (the env reads it once per step)
        if fell_at is None and amp.fallen[0]:
            fell_at = round(t_rel, 2)
        if t_rel < 0.0:
            start = pos.copy()
            continue
        along = float((pos - start) @ u)
        if t_1m is None and along >= 1.0:
            t_1m = round(t_rel, 3)
    hd = float(env.yaw[env.n_robots])
    heading_error = abs((hd - yaw + np.pi) % (2 * np.pi) - np.pi)
    fell = bool(amp.fallen[0])
    wrapped.close()
    row = {"speed": speed, "bearing_deg": bearing_deg, "seconds": seconds, "along_m": round(along, 3),
           "target_m": round(speed * seconds, 3), "time_to_1m_s": t_1m,
           "heading_error_deg": round(float(np.degrees(heading_error)), 1), "fell": fell}
    if go > 0:
        row.update({"lead_in_s": lead_in, "pause_s": pause, "lead_speed": lead_speed, "fell_at_s": fell_at})
    return row


def summary(files: list[str]) -> list[dict]:
    """Rows of several ``--json`` files (e.g. one per probe seed) pooled per target speed and bearing: the mean
    distance gone, how many runs went 1 m, and how many fell; then per speed over every bearing (``bearing_deg``
    None)."""
    cells: dict[tuple, list[dict]] = {}
    for f in files:
        for row in json.loads(Path(f).read_text())["rows"]:
            cells.setdefault((row["speed"], row["bearing_deg"]), []).append(row)
    if not cells:
        raise ValueError(f"no probe rows in {files}")

    def pooled(speed: float, bearing: float | None, rows: list[dict]) -> dict:
        return {"speed": speed, "bearing_deg": bearing, "runs": len(rows),
                "mean_along_m": round(float(np.mean([r["along_m"] for r in rows])), 3),
                "reached_1m": sum(r["time_to_1m_s"] is not None for r in rows), "fell": sum(r["fell"] for r in rows)}

    out = [pooled(v, b, rows) for (v, b), rows in sorted(cells.items())]
    for v in sorted({v for v, _ in cells}):
        out.append(pooled(v, None, [r for (s, _), rows in cells.items() if s == v for r in rows]))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--speeds", default="0.3,0.6,1.0", help="target speeds (m/s), comma-separated")
    parser.add_argument("--bearings", default="0,90,180", help="degrees between the body's heading and the target's direction")
    parser.add_argument("--seconds", type=float, default=12.0)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    parser.add_argument("--lead-in", type=float, default=0.0,
                        help="s: first walk straight ahead at --lead-speed for this long (stop-turn-go probe)")
    parser.add_argument("--pause", type=float, default=0.0, help="s: then stand this long before setting off")
    parser.add_argument("--lead-speed", type=float, default=1.0, help="m/s of the lead-in (default 1.0)")
    parser.add_argument("--json", default=None, help="also write the rows here")
    parser.add_argument("--summary", nargs="+", default=None, metavar="JSON",
                        help="pool the rows of earlier --json files per speed and bearing, print them and stop")
    args = parser.parse_args(argv)
    if args.summary:
        try:
            rows = summary(args.summary)
        except (OSError, ValueError, KeyError) as e:
            raise SystemExit(f"--summary: {e}") from None
        for r in rows:
            where = "every bearing" if r["bearing_deg"] is None else f"{r['bearing_deg']:5.0f} deg off"
            print(f"target {r['speed']:.2f} m/s, {where}: {r['mean_along_m']:.2f} m on average over {r['runs']} runs, "
                  f"{r['reached_1m']} went 1 m, {r['fell']} fell")
        return 0
    speeds, bearings = _floats(args.speeds, "--speeds"), _floats(args.bearings, "--bearings")
    if any(v <= 0 for v in speeds) or args.seconds <= 0:
        raise SystemExit("--speeds and --seconds must be positive")
    if args.lead_in < 0 or args.pause < 0 or args.lead_speed <= 0:
        raise SystemExit("--lead-in and --pause must be >= 0, --lead-speed positive")
    from navzoo.torch_threads import one_torch_thread

    rows = []
    with one_torch_thread():
        for v in speeds:
            for b in bearings:
                row = probe(v, b, args.seconds, args.seed, args.policy, lead_in=args.lead_in, pause=args.pause,
                            lead_speed=args.lead_speed)
                rows.append(row)
                print(f"target {v:.2f} m/s, {b:5.0f} deg off: {row['along_m']:5.2f} of {row['target_m']:.1f} m in "
                      f"{args.seconds:.0f} s, 1 m at {row['time_to_1m_s']} s, heading error "
                      f"{row['heading_error_deg']:.0f} deg, fell {row['fell']}"
                      + (f" (at {row['fell_at_s']} s from the set-off)" if row.get("fell_at_s") is not None else ""),
                      flush=True)
    if args.json:
        from navzoo.machine import cpu_model, package_versions

        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"cpu": cpu_model(), "packages": package_versions(), "rows": rows},
                                              indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
