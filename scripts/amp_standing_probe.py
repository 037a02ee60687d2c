"""Where and why physics pedestrians stand: one scene of the following protocol, step by step.

Runs one scene with AMP bodies (``navzoo.benchmark.pedestrians.follow_scene``'s set-up: the scene, its people,
200 s) and records, every env step, each standing person's planar speed, the bearing of its next target points
(the mean of the next five, 0.5 s apart, against the body's heading) and the distance to the nearest other
person. It prints the trip outcomes and:

- ``still``: the share of person-time the bodies stand (planar speed under 0.15 m/s), fallen and arrived people
  left out;
- ``still_behind`` / ``still_side`` / ``still_ahead``: standing with the target points more than 90 degrees off the
  heading, 45-90 degrees, under 45;
- ``still_by_nearest``: the standing share within each band of distance to the nearest person (0-1, 1-1.5,
  1.5-2.5, over 2.5 m), with each band's share of person-time;
- ``target_lead_still_m``: the mean distance of those target points from a standing body.

``--const NAME=VALUE`` sets an upper-case constant of ``navzoo.envs.amp_humans`` first (repeatable), e.g.
``--const STALL_WARP_S=1.0``:

    python scripts/amp_standing_probe.py --scene doorway --people 13 --crowd diffusion --seed 0 \\
        --json docs/results/stall_warp/standing_doorway_vm.json

One scene of 200 s takes 1-2.5 minutes on a 2-core VM.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

STILL_SPEED = 0.15  # m/s
BANDS = ((0.0, 1.0), (1.0, 1.5), (1.5, 2.5), (2.5, float("inf")))


def parse_const(items: list[str]) -> dict[str, float | bool | int]:
    """``NAME=VALUE`` items for upper-case constants of ``navzoo.envs.amp_humans``, typed as the constant is."""
    from navzoo.envs import amp_humans

    out: dict[str, float | bool | int] = {}
    for item in items:
        name, sep, value = item.partition("=")
        current = getattr(amp_humans, name, None)
        if not sep or not name.isupper() or not isinstance(current, bool | int | float):
            raise SystemExit(f"--const {item!r}: expected NAME=VALUE of a numeric or boolean upper-case constant "
                             "of navzoo.envs.amp_humans")
        try:
            number = float(value)
        except ValueError:
            raise SystemExit(f"--const {item!r}: {value!r} is not a number") from None
        out[name] = bool(number) if isinstance(current, bool) else int(number) if isinstance(current, int) else number
    return out


def standing_shares(speed: np.ndarray, bearing: np.ndarray, lead: np.ndarray, nearest: np.ndarray,
                    active: np.ndarray) -> dict:
    """The shares of the module docstring from per-step arrays (T, H): planar speed, bearing of the target
    points (rad), their mean distance from the body, distance to the nearest person, and who counts (standing
    up, not arrived)."""
    total = int(active.sum())
    if total == 0:
        raise ValueError("no person-time to count")
    still = (speed < STILL_SPEED) & active
    off = np.abs(bearing)
    out = {
        "person_steps": total,
        "still": float(still.sum() / total),
        "still_behind": float((still & (off > np.pi / 2)).sum() / total),
        "still_side": float((still & (off > np.pi / 4) & (off <= np.pi / 2)).sum() / total),
        "still_ahead": float((still & (off <= np.pi / 4)).sum() / total),
        "target_lead_still_m": float(lead[still].mean()) if still.any() else float("nan"),
        "still_by_nearest": [],
    }
    for lo, hi in BANDS:
        band = active & (nearest >= lo) & (nearest < hi)
        out["still_by_nearest"].append({"from_m": lo, "to_m": hi if np.isfinite(hi) else None,
                                        "time_share": float(band.sum() / total),
                                        "still": float((still & band).sum() / max(int(band.sum()), 1))})
    return out


def run(scene: str, people: int, crowd: str, seed: int, seconds: float) -> dict:
    from navzoo.benchmark import pedestrians as P

    wrapped, env = P._make(scene, people, "amp", seconds, seed, None, crowd)
    amp = env.amp
    trips = P.Trips(env, people)
    h = np.arange(env.n_robots, env.n_total)
    outcomes = {"success": 0, "off_path": 0, "fall": 0, "timeout": 0}
    rec: dict[str, list[np.ndarray]] = {k: [] for k in ("speed", "bearing", "lead", "nearest", "active")}
    while not env._needs_reset:
        wrapped.step({})
        pos, hd, vel, _ = amp.planar()
        rel = amp.waypoints()[:, :5] - pos[:, None]
        mean = rel.mean(axis=1)
        rec["bearing"].append((np.arctan2(mean[:, 1], mean[:, 0]) - hd + np.pi) % (2 * np.pi) - np.pi)
        rec["lead"].append(np.linalg.norm(mean, axis=1))
        rec["speed"].append(np.linalg.norm(vel, axis=1))
        d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
        np.fill_diagonal(d, np.inf)
        rec["nearest"].append(d.min(axis=1) if people > 1 else np.full(people, np.inf))
        rec["active"].append(~(env.arrived[h] | amp.fallen))
        err = np.linalg.norm(env.pos[h] - P.target_points(env), axis=1)
        for _, outcome, _, _ in trips.update(err, env.human_fallen):
            outcomes[outcome] += 1
    wrapped.close()
    arrays = {k: np.asarray(v) for k, v in rec.items()}
    return {"scene": scene, "people": people, "crowd": crowd, "seed": seed, "seconds": seconds, "trips": outcomes,
            **standing_shares(arrays["speed"], arrays["bearing"], arrays["lead"], arrays["nearest"], arrays["active"])}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--scene", default="doorway")
    parser.add_argument("--people", type=int, default=13)
    parser.add_argument("--crowd", default="diffusion", choices=("sfm", "diffusion", "orca"))
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--seconds", type=float, default=200.0)
    parser.add_argument("--const", action="append", default=[], metavar="NAME=VALUE")
    parser.add_argument("--json", default=None, help="append the result as one JSON line to this file")
    args = parser.parse_args(argv)
    if args.people < 1 or args.seconds <= 0:
        raise SystemExit("--people and --seconds must be positive")
    consts = parse_const(args.const)
    from navzoo.envs import amp_humans
    from navzoo.machine import cpu_model, package_versions
    from navzoo.torch_threads import one_torch_thread

    for name, value in consts.items():
        setattr(amp_humans, name, value)
    with one_torch_thread():
        row = run(args.scene, args.people, args.crowd, args.seed, args.seconds)
    row.update(const=consts, cpu=cpu_model(), packages=package_versions())
    bands = ", ".join(f"{b['from_m']:g}-{b['to_m'] if b['to_m'] is not None else 'inf'} m: {b['still']:.2f} of "
                      f"{b['time_share']:.2f}" for b in row["still_by_nearest"])
    print(f"{args.scene} ({args.people}, {args.crowd}, seed {args.seed}) trips {row['trips']}; still {row['still']:.3f} "
          f"(targets behind {row['still_behind']:.3f}, side {row['still_side']:.3f}, ahead {row['still_ahead']:.3f}; "
          f"target points {row['target_lead_still_m']:.2f} m away); still by nearest person: {bands}", flush=True)
    if args.json:
        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        with open(args.json, "a", encoding="utf-8") as f:
            f.write(json.dumps(row) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
