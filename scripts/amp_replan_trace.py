"""What each person's diffusion plan and target rollout do at every replan of one following-protocol run.

Runs one scene as ``navzoo eval pedestrians`` does (physics pedestrians, the shipped AMP policy) and, at every replan
from ``--from`` to ``--until`` seconds, records for each person: its body's position and heading, its goal, its
plan's pace over the next 2 s (``plan_speed``, m/s) and where that plan point lies from the body (``plan_dir``),
how far its new target rollout gets in 2 s (``rollout_reach_2s_m``) and how long the body has stood
(``still_s``, counted while ``STALL_WARP_S`` is on). A plan that walks while the rollout stays put points at the
rollout (social force, walls, people), not at the plan:

    python scripts/amp_replan_trace.py --scene bottleneck --people 7 --seed 2 --const STALL_WARP_S=1.0 \\
        --from 104 --until 111 --json docs/results/stall_warp/replan_bottleneck_s2_warp_vm.json

The run stops at ``--until``; a 110 s run of seven people takes about 1.5 min on a 2-core VM.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

REACH_S = 2.0  # s: how far into each plan and rollout the trace looks


def trace(scene: str, people: int, seed: int, t_from: float, t_until: float, crowd: str = "diffusion",
          policy_dir: str | None = None) -> list[dict]:
    """The rows of every replan between ``t_from`` and ``t_until`` (s), one per person."""
    from navzoo.benchmark import pedestrians as P
    from navzoo.envs.amp_humans import CONTROL_HZ
    from navzoo.torch_threads import one_torch_thread

    if not 0 <= t_from <= t_until:
        raise ValueError(f"need 0 <= --from <= --until, got {t_from} and {t_until}")
    rows: list[dict] = []
    with one_torch_thread():
        wrapped, env = P._make(scene, people, "amp", t_until, seed, policy_dir, crowd)
        amp, plans = env.amp, env.diffusion
        if plans is None:
            wrapped.close()
            raise ValueError(f"crowd {crowd!r} has no diffusion plans to trace")
        plan_all = amp.plan_all
        k_reach = int(round(REACH_S * CONTROL_HZ))

        def traced_plan_all() -> None:
            plan_all()
            t0 = env.sim_time
            if not t_from <= t0 <= t_until:
                return
            later = plans._plans_at(t0 + REACH_S)[:, 0]
            speed = np.linalg.norm(later - plans._plans_at(t0)[:, 0], axis=1) / REACH_S
            pos, heading, _, _ = amp.planar()
            R = env.n_robots
            for j in range(amp.n):
                rows.append({
                    "t": round(float(t0), 2), "id": j, "pos": np.round(pos[j], 3).tolist(),
                    "heading_deg": round(float(np.degrees(heading[j])), 1),
                    "goal": np.round(env.goal[R + j], 3).tolist(), "plan_speed": round(float(speed[j]), 3),
                    "plan_dir": np.round(later[j] - pos[j], 3).tolist(),
                    "rollout_reach_2s_m": round(float(np.linalg.norm(amp.paths[j, k_reach] - pos[j])), 3),
                    "still_s": round(float(amp.still_s[j]), 2),
                })

        amp.plan_all = traced_plan_all
        while not env._needs_reset:
            wrapped.step({})
        wrapped.close()
    return rows


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="bottleneck")
    ap.add_argument("--people", type=int, default=7)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--from", dest="t_from", type=float, default=0.0, help="first replan time traced (s)")
    ap.add_argument("--until", type=float, default=20.0, help="last replan time traced; the run ends here (s)")
    ap.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    ap.add_argument("--const", action="append", default=[], metavar="NAME=VALUE",
                    help="upper-case numeric or boolean constant of navzoo.envs.amp_humans, repeatable")
    ap.add_argument("--json", default=None, help="also write the rows here")
    args = ap.parse_args(argv)
    from amp_stand_trace import apply_const

    try:
        consts = apply_const(args.const)
    except ValueError as e:
        ap.error(str(e))
    try:
        rows = trace(args.scene, args.people, args.seed, args.t_from, args.until, policy_dir=args.policy)
    except ValueError as e:
        ap.error(str(e))
    for r in rows:
        print(f"t {r['t']:6.1f} person {r['id']} pos {r['pos']} heading {r['heading_deg']:6.1f} goal {r['goal']} "
              f"plan {r['plan_speed']:.2f} m/s toward {r['plan_dir']} rollout {r['rollout_reach_2s_m']:.2f} m in 2 s "
              f"stood {r['still_s']:.1f} s")
    if args.json:
        from navzoo.machine import cpu_model, package_versions

        Path(args.json).parent.mkdir(parents=True, exist_ok=True)
        Path(args.json).write_text(json.dumps({
            "scene": args.scene, "people": args.people, "seed": args.seed, "from_s": args.t_from, "until_s": args.until,
            "const": consts, "cpu": cpu_model(), "packages": package_versions(), "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
