"""What tips the physics pedestrians over in the following runs, and do falls come in cascades?

    python scripts/fall_causes.py RUNS.jsonl [RUNS.jsonl ...] [--by-scene] [--scenes protocol|heldout|S,S] [--counts]
        [--within S] [--near M] [--json] [--paired-cpus]

Reads the rows of ``scripts/amp_target_ablation.py`` (or any rows of ``navzoo.benchmark.pedestrians.follow_scene``)
that carry ``fall_events`` (:class:`navzoo.benchmark.pedestrians.FallLog`, since 2026-12-06; older rows are
skipped and counted, or with ``--counts`` taken for their fall counts alone). Per configuration and kind of CPU (and scene with ``--by-scene``) it prints:

- ``runs``, ``falls`` and the share of the falls that happen in runs with at least ``CASCADE_RUN`` falls
  (``in_runs_with_3plus``): a few runs holding most falls means falls come in cascades;
- the falls by cause (:func:`navzoo.benchmark.pedestrians.fall_cause`: the last touch within ``--within`` s
  before the fall was detected: a body that had fallen, a standing person or a robot, a wall; or none);
- ``near_fallen``: falls whose key bodies came within ``--near`` m of a body that had fallen before;
- for the falls tipped by a lying body, the median time since the fall before them in the run
  (``fallen_body_after_s``) and how many came within ``KNOCKED_S`` of it (knocked over by a falling body rather
  than walking into a lying one);
- ``slid_m_median`` / ``slid_m_max`` (``--json``): how far the bodies slid after they were found fallen (rows since
  the FallLog records it);
- successes per run in runs without falls and in runs with ``CASCADE_RUN`` falls or more: a fallen person makes no
  more trips, so a cascade costs a run much of its successes;
- how the bodies moved before the falls that nothing touched (cause ``none``; rows since 2026-12-07 carry the
  motion keys of :class:`navzoo.benchmark.pedestrians.FallLog`): their median root speed, the share slower than
  ``navzoo.benchmark.pedestrians.SLOW_MPS`` (0.3 m/s: standing or shuffling), the share whose target was that slow too, and the median yaw rate and lag
  behind the target (``untouched_motion``; ``None`` without such falls), and those falls per person-minute spent
  under and over that speed (``untouched_per_minute``, from the rows' ``slow_s`` and ``moving_s``).

``--paired-cpus`` instead compares two kinds of CPU (a run repeats trip for trip only on one kind): per configuration,
the runs (scene, people, seed) that ran on both, their falls on each, and a paired sign-flip test of the difference
(two-sided, ``SIGN_FLIP_DRAWS`` random sign patterns from a fixed seed): do falls differ between the CPUs more than
runs that differ trip for trip do by chance?
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import defaultdict
from pathlib import Path

import numpy as np

CASCADE_RUN = 3
KNOCKED_S = 3.0  # a fall this soon after the one before, tipped by that body: knocked over as it fell
SIGN_FLIP_DRAWS = 200_000
CAUSES = ("fallen body", "person", "wall", "none")


def read(paths: list[str], counts: bool = False) -> tuple[list[dict], int]:
    """Rows with fall events (a run that appears in several files is counted once) and the number skipped; with
    ``counts``, rows without fall events too (their falls are their ``fall`` count; they have no causes)."""
    rows, seen, skipped = [], set(), 0
    for path in paths:
        for n, line in enumerate(Path(path).read_text().splitlines(), 1):
            if not line.strip():
                continue
            try:
                r = json.loads(line)
            except json.JSONDecodeError as e:
                raise ValueError(f"{path}:{n}: not a JSON line ({e})") from None
            if "scene" not in r or "fall" not in r:
                continue  # a settings line
            if "fall_events" not in r and not counts:
                skipped += 1
                continue
            key = (r.get("config"), r.get("crowd"), r["scene"], r.get("pedestrians"), r.get("seed"), _cpu(r))
            if key in seen:
                continue
            seen.add(key)
            rows.append(r)
    return rows, skipped


def _cpu(row: dict) -> str:
    """The kind of CPU a row ran on ("Intel", "AMD"; "?" when the row does not say)."""
    return (str(row.get("cpu") or "?").split("(")[0].split() or ["?"])[0]


def _falls(row: dict) -> int:
    """A run's falls: its fall events, or its ``fall`` count for an older row read with ``--counts``."""
    return len(row["fall_events"]) if "fall_events" in row else int(row["fall"])


def paired_cpus(rows: list[dict], draws: int = SIGN_FLIP_DRAWS, seed: int = 0) -> list[dict]:
    """Per configuration run on exactly two kinds of CPU: the falls of the runs that ran on both, and the two-sided
    sign-flip p-value of their summed paired difference (the share of random sign patterns whose sum is as far from 0)."""
    by_config: dict[tuple, dict[str, dict[tuple, int]]] = defaultdict(lambda: defaultdict(dict))
    for r in rows:
        by_config[(r.get("config", "?"), r.get("crowd", "sfm"))][_cpu(r)][(r["scene"], r.get("pedestrians"),
                                                                           r.get("seed"))] = _falls(r)
    out = []
    for (config, crowd), cpus in sorted(by_config.items()):
        if len(cpus) != 2:
            continue
        (ca, a), (cb, b) = sorted(cpus.items())
        keys = sorted(set(a) & set(b), key=str)
        if not keys:
            continue
        d = np.array([a[k] - b[k] for k in keys])
        signs = np.random.default_rng(seed).choice([-1, 1], size=(draws, len(d)))
        p = float(np.mean(np.abs(signs @ d) >= abs(d.sum()))) if d.any() else 1.0
        out.append({"config": config, "crowd": crowd, "cpus": [ca, cb], "runs": len(keys),
                    "falls": [int(sum(a[k] for k in keys)), int(sum(b[k] for k in keys))],
                    "runs_more_falls": [int((d > 0).sum()), int((d < 0).sum())], "p_sign_flip": round(p, 4)})
    return out


def summarize(rows: list[dict], within: float, near: float) -> dict:
    from navzoo.benchmark.pedestrians import fall_cause

    falls = [_falls(r) for r in rows]
    timed = [r for r in rows if "slow_s" in r]
    events = [e for r in rows for e in r.get("fall_events", [])]
    causes = dict.fromkeys(CAUSES, 0)
    for e in events:
        causes[fall_cause(e, within)] += 1
    gaps = []  # falls tipped by a lying body: seconds since the fall before them in the run
    for r in rows:
        ev = r.get("fall_events", [])
        gaps += [e["t"] - max(x["t"] for x in ev[:k]) for k, e in enumerate(ev)
                 if k and fall_cause(e, within) == "fallen body"]
    slid = [e["slid_m"] for e in events if e.get("slid_m") is not None]  # how far bodies slid once found fallen
    cascade = [r for r, f in zip(rows, falls, strict=True) if f >= CASCADE_RUN]
    calm = [r for r, f in zip(rows, falls, strict=True) if f == 0]
    total = sum(falls)
    return {
        "runs": len(rows), "falls": total,
        "falls_per_run": sorted(falls, reverse=True),
        f"in_runs_with_{CASCADE_RUN}plus": round(sum(f for f in falls if f >= CASCADE_RUN) / total, 3) if total else None,
        f"runs_with_{CASCADE_RUN}plus": len(cascade),
        "causes": causes,
        "near_fallen": sum(1 for e in events if e["fallen_m"] is not None and e["fallen_m"] <= near),
        "fallen_body_after_s": round(float(np.median(gaps)), 1) if gaps else None,
        "slid_m_median": round(float(np.median(slid)), 2) if slid else None,
        "slid_m_max": round(float(max(slid)), 2) if slid else None,
        f"fallen_body_within_{KNOCKED_S:g}s": sum(1 for g in gaps if g <= KNOCKED_S),
        "success_per_run_no_falls": round(sum(r["success"] for r in calm) / len(calm), 1) if calm else None,
        f"success_per_run_{CASCADE_RUN}plus_falls": (round(sum(r["success"] for r in cascade) / len(cascade), 1)
                                                    if cascade else None),
        "untouched_motion": untouched_motion([e for e in events if fall_cause(e, within) == "none"]),
        "untouched_per_minute": untouched_per_minute(timed, within),
    }


def untouched_per_minute(rows: list[dict], within: float) -> dict | None:
    """Falls that nothing touched per person-minute while slow (under ``SLOW_MPS``) and while moving, over rows that
    carry the time spent in each (``slow_s``, ``moving_s``; rows since 2026-12-07), with those times (``slow_min``,
    ``moving_min``); ``None`` without such rows. A fall counts as slow by its mean speed 2.0 to 0.5 s before it was
    detected (FallLog's ``speed_mps``), the time by the speed of each step."""
    from navzoo.benchmark.pedestrians import SLOW_MPS, fall_cause

    if not rows:
        return None
    ev = [e for r in rows for e in r["fall_events"] if fall_cause(e, within) == "none" and e.get("speed_mps") is not None]
    slow_min, moving_min = sum(r["slow_s"] for r in rows) / 60, sum(r["moving_s"] for r in rows) / 60
    n_slow = sum(e["speed_mps"] < SLOW_MPS for e in ev)
    rate = lambda n, m: round(n / m, 3) if m > 0 else None  # noqa: E731
    return {"slow": rate(n_slow, slow_min), "moving": rate(len(ev) - n_slow, moving_min),
            "slow_min": round(slow_min, 1), "moving_min": round(moving_min, 1)}


def untouched_motion(events: list[dict]) -> dict | None:
    """How the bodies moved before falls (FallLog's motion keys): ``falls`` with those keys, the median root speed
    (``speed_median``), the shares slower than ``SLOW_MPS`` (``slow_share``) and with a target slower than that
    too (``slow_target_share``, of the falls with a target), the median yaw rate (``turn_median``) and lag behind
    the target (``lag_median``). ``None`` when no event has the keys (rows before 2026-12-07)."""
    from navzoo.benchmark.pedestrians import SLOW_MPS

    ev = [e for e in events if e.get("speed_mps") is not None]
    if not ev:
        return None
    speed = np.array([e["speed_mps"] for e in ev])
    tgt = [e for e in ev if e.get("target_speed_mps") is not None]
    med = lambda k, xs: round(float(np.median([e[k] for e in xs])), 2) if xs else None  # noqa: E731
    return {"falls": len(ev), "speed_median": round(float(np.median(speed)), 2),
            "slow_share": round(float((speed < SLOW_MPS).mean()), 2),
            "slow_target_share": (round(sum(e["speed_mps"] < SLOW_MPS and e["target_speed_mps"] < SLOW_MPS
                                            for e in tgt) / len(tgt), 2) if tgt else None),
            "turn_median": med("turn_rad_s", ev), "lag_median": med("lag_m", tgt)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("files", nargs="+", help="JSON lines of scripts/amp_target_ablation.py")
    ap.add_argument("--by-scene", action="store_true", help="one line per configuration and scene")
    ap.add_argument("--within", type=float, default=None,
                    help="a touch this long (s) before the fall counts as its cause (default FALL_CAUSE_S, 1.5)")
    ap.add_argument("--near", type=float, default=0.5, help="m: a fall this close to a fallen body is 'near_fallen'")
    ap.add_argument("--json", action="store_true", help="one JSON line per group instead of the table")
    ap.add_argument("--scenes", default=None, metavar="S,S",
                    help="only these scenes ('protocol' for the 8 of the following protocol, 'heldout' for the 10)")
    ap.add_argument("--counts", action="store_true",
                    help="also rows without fall events (older runs): their fall counts, no causes")
    ap.add_argument("--paired-cpus", action="store_true",
                    help="compare the falls of the same runs on two kinds of CPU (paired sign-flip test)")
    a = ap.parse_args(argv)
    from navzoo.benchmark.pedestrians import FALL_CAUSE_S

    within = FALL_CAUSE_S if a.within is None else a.within
    if within <= 0 or a.near <= 0:
        ap.error("--within and --near must be positive")
    try:
        rows, skipped = read(a.files, a.counts)
    except (OSError, ValueError) as e:
        ap.error(str(e))
    if a.scenes is not None:
        from navzoo.benchmark.pedestrians import scene_names

        try:
            only = set(scene_names(a.scenes))
        except ValueError as e:
            ap.error(str(e))
        rows = [r for r in rows if r["scene"] in only]
    if skipped:
        print(f"fall_causes: {skipped} rows without fall_events (runs before 2026-12-06) left out", file=sys.stderr)
    if not rows:
        ap.error("no rows with fall_events in these files (--counts takes the fall counts of older rows)")
    if a.paired_cpus:
        pairs = paired_cpus(rows)
        if not pairs:
            ap.error("no configuration has the same runs on two kinds of CPU in these files")
        for x in pairs:
            print(json.dumps(x) if a.json else
                  f"{x['config']} ({x['crowd']}): {x['runs']} runs on both; falls {x['cpus'][0]} {x['falls'][0]}, "
                  f"{x['cpus'][1]} {x['falls'][1]}; more falls on {x['cpus'][0]} in {x['runs_more_falls'][0]} runs, "
                  f"on {x['cpus'][1]} in {x['runs_more_falls'][1]}; paired sign-flip p = {x['p_sign_flip']}")
        return 0
    groups: dict[tuple, list[dict]] = defaultdict(list)
    for r in rows:  # rows of another kind of CPU are other runs: kept apart
        groups[(r.get("config", "?"), r.get("crowd", "sfm"), _cpu(r), r["scene"] if a.by_scene else "all")].append(r)
    if not a.json:
        print(f"| configuration | scene | runs | falls | in runs with {CASCADE_RUN}+ falls | "
              + " | ".join(f"cause: {c}" for c in CAUSES)
              + f" | within {a.near} m of a fallen body | tipped by a lying body: median time after the fall before "
              f"(within {KNOCKED_S:g} s) | successes per run, no falls / {CASCADE_RUN}+ falls "
              "| untouched falls: median speed (m/s), share under 0.3 m/s (target too), median yaw rate (rad/s), lag (m) "
              "| untouched falls per person-minute under / over 0.3 m/s (person-minutes) |")
        print("|" + "---|" * (12 + len(CAUSES) - 1))
    for (config, crowd, cpu, scene), rs in sorted(groups.items()):
        s = summarize(rs, within, a.near)
        if a.json:
            print(json.dumps({"config": config, "crowd": crowd, "cpu": cpu, "scene": scene, **s}))
            continue
        share = s[f"in_runs_with_{CASCADE_RUN}plus"]
        print(f"| {config} ({crowd}, {cpu}) | {scene} | {s['runs']} | {s['falls']} | "
              f"{'-' if share is None else f'{100 * share:.0f} %'} ({s[f'runs_with_{CASCADE_RUN}plus']} runs) | "
              + " | ".join(str(s["causes"][c]) for c in CAUSES)
              + f" | {s['near_fallen']} | {s['fallen_body_after_s']} s ({s[f'fallen_body_within_{KNOCKED_S:g}s']}) "
              f"| {s['success_per_run_no_falls']} / "
              f"{s[f'success_per_run_{CASCADE_RUN}plus_falls']} | {_motion_cell(s['untouched_motion'])} | {_rate_cell(s['untouched_per_minute'])} |")
    return 0


def _motion_cell(m: dict | None) -> str:
    if m is None:
        return "-"
    slow_target = "-" if m["slow_target_share"] is None else f"{100 * m['slow_target_share']:.0f} %"
    return (f"{m['speed_median']}, {100 * m['slow_share']:.0f} % ({slow_target}), {m['turn_median']}, "
            f"{m['lag_median']} ({m['falls']} falls)")


def _rate_cell(m: dict | None) -> str:
    return "-" if m is None else f"{m['slow']} / {m['moving']} ({m['slow_min']} / {m['moving_min']})"


if __name__ == "__main__":
    raise SystemExit(main())
