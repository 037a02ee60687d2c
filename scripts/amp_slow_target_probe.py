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
          scene: str = "circle_crossing") -> dict:
    """One run: a straight target at ``speed`` m/s, ``bearing_deg`` off the body's first heading."""
    from navzoo.benchmark import pedestrians as P
    from navzoo.envs import amp_humans as AH

    if speed <= 0 or seconds <= 0:
        raise ValueError(f"speed and seconds must be positive, got {speed}, {seconds}")
    wrapped, env = P._make(scene, 1, "amp", seconds + 5.0, seed, policy_dir, "sfm")
    amp = env.amp
    pos0, hd0, _, _ = amp.planar()
    yaw = float(hd0[0]) + np.radians(bearing_deg)
    u = np.array([np.cos(yaw), np.sin(yaw)])
    tau = np.arange(amp.path_len) / AH.CONTROL_HZ

    def plan_all(who: np.ndarray | None = None) -> None:  # the body's own position, then straight on at `speed`
        del who  # one body: every replan (timed, or an event the env passes on) is its own
        pos = amp.planar()[0]
        amp.paths = pos[:, None, :] + (speed * tau)[None, :, None] * u[None, None, :]
        amp.plan_t[:] = amp.t
        amp.k_prog[:] = 0

    amp.plan_all = plan_all
    plan_all()
    t_1m = None
    along = 0.0
    while env.sim_time < seconds - 1e-9 and not env._needs_reset:
        wrapped.step({})
        along = float((amp.planar()[0][0] - pos0[0]) @ u)
        if t_1m is None and along >= 1.0:
            t_1m = round(float(env.sim_time), 3)
    hd = float(amp.planar()[1][0])
    heading_error = abs((hd - yaw + np.pi) % (2 * np.pi) - np.pi)
    fell = bool(amp.fallen[0])
    wrapped.close()
    return {"speed": speed, "bearing_deg": bearing_deg, "seconds": seconds, "along_m": round(along, 3),
            "target_m": round(speed * seconds, 3), "time_to_1m_s": t_1m,
            "heading_error_deg": round(float(np.degrees(heading_error)), 1), "fell": fell}


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
    from navzoo.torch_threads import one_torch_thread

    rows = []
    with one_torch_thread():
        for v in speeds:
            for b in bearings:
                row = probe(v, b, args.seconds, args.seed, args.policy)
                rows.append(row)
                print(f"target {v:.2f} m/s, {b:5.0f} deg off: {row['along_m']:5.2f} of {row['target_m']:.1f} m in "
                      f"{args.seconds:.0f} s, 1 m at {row['time_to_1m_s']} s, heading error "
                      f"{row['heading_error_deg']:.0f} deg, fell {row['fell']}", flush=True)
    if args.json:
        from navzoo.machine import cpu_model, package_versions

        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({"cpu": cpu_model(), "packages": package_versions(), "rows": rows},
                                              indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
