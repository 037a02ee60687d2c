"""Choose among the policy snapshots of an AMP training run on the following protocol.

The training reward of the AMP controller stopped tracking the following protocol (docs/pedestrians.md:
every branch from checkpoint 5174 raised the reward and lost following success), so a run's policies
are compared on the protocol itself, in two stages:

1. **short**: every snapshot, and the baseline policy, for ``--short-seconds`` per scene at
   ``--short-seeds``. At 60 s and one seed this ranked five checkpoints like the full protocol (rank
   correlation 0.9) at a fifteenth of its cost, but could not separate close ones
   (docs/pedestrians_log.md, "Can a short protocol choose checkpoints?"), so it only shortlists;
2. **full**: the ``--top`` best of stage 1 and the baseline, for ``--full-seconds`` at ``--full-seeds``
   (the reported protocol: 200 s, seeds 0 and 1). The chosen policy is the one with the highest
   stage-2 success; the baseline wins ties.

Both stages run ``scripts/amp_target_ablation.py`` (8 scenes, 3-15 people, social-force targets,
parallel processes) and append to ``<out>/short.jsonl`` and ``<out>/full.jsonl``, so an interrupted
selection resumes where it stopped. ``<out>/selection.json`` lists every candidate's success per
stage (successes / ended trips, pooled over scenes and seeds) and the choice. Snapshots are the
``policy_<iteration>`` folders that ``navzoo train amp --snapshot-every N`` writes into
``<run>/snapshots``; ``--trim`` sets one steering trim for all of them (default: each policy's own).

    python scripts/amp_select_snapshots.py --snapshots RUN/snapshots --baseline policies/amp_pedestrian \\
        --trim 0.025 --workers 16 --out RUN/selection
    python scripts/amp_select_snapshots.py ... --full-seeds ''      # stage 1 only
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
import amp_target_ablation as ata  # noqa: E402  (the sibling script)

# The shipped target settings of physics pedestrians: 0.1 m planning margins, waypoint lookahead 4,
# turn-rate limit 2 rad/s, no extra env flags (the configuration of every following row since run 16).
TARGETS = "0.1:0.1:4:2.0:0"
TRIP_KEYS = ("success", "off_path", "fall", "timeout")


def candidates(snapshots: Path, baseline: str | None) -> dict[str, str]:
    """Candidate name -> policy folder: ``it<iteration>`` per snapshot (in order), then ``baseline``."""
    found = sorted(p for p in snapshots.glob("policy_*") if (p / "config.json").is_file())
    if not found and baseline is None:
        raise FileNotFoundError(f"no policy snapshots (policy_*/config.json) in {snapshots}")
    out = {f"it{int(p.name.split('_')[-1])}": str(p) for p in found}
    if baseline is not None:
        if not (Path(baseline) / "config.json").is_file():
            raise FileNotFoundError(f"no exported AMP policy (config.json) in the baseline {baseline}")
        out["baseline"] = baseline
    return out


def success_by_config(path: Path) -> dict[str, dict[str, float]]:
    """Pooled success share and ended trips of every configuration in an ablation result file."""
    rows = [json.loads(line) for line in path.read_text().splitlines() if line.strip()] if path.is_file() else []
    out: dict[str, dict[str, float]] = {}
    for name in dict.fromkeys(r["config"] for r in rows):
        rs = [r for r in rows if r["config"] == name]
        trips = sum(r[k] for r in rs for k in TRIP_KEYS)
        out[name] = {"success": sum(r["success"] for r in rs) / max(1, trips), "trips": trips, "runs": len(rs)}
    return out


def _stage(configs: list[str], seconds: float, seeds: str, workers: int, out: Path, scenes: str | None) -> None:
    argv = ["--configs", ",".join(configs), "--seconds", str(seconds), "--seeds", seeds,
            "--workers", str(workers), "--out", str(out)]
    if scenes:
        argv += ["--scenes", scenes]
    if ata.main(argv) != 0:
        raise RuntimeError(f"the following protocol failed for {out}")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--snapshots", required=True, help="folder of policy_<iteration> snapshots")
    ap.add_argument("--baseline", default=None, help="exported policy to compare with (e.g. the branch point)")
    ap.add_argument("--trim", type=float, default=None, help="steering trim (rad) for every candidate")
    ap.add_argument("--short-seconds", type=float, default=60.0)
    ap.add_argument("--short-seeds", default="2")
    ap.add_argument("--top", type=int, default=2, help="candidates passed to the full protocol")
    ap.add_argument("--full-seconds", type=float, default=200.0)
    ap.add_argument("--full-seeds", default="0,1", help="'' = stop after the short protocol")
    ap.add_argument("--scenes", default=None, help="comma-separated subset of the 8 scenes (tests)")
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--out", required=True, help="folder for short.jsonl, full.jsonl and selection.json")
    args = ap.parse_args(argv)
    if args.top < 1:
        ap.error(f"--top must be at least 1, got {args.top}")
    if args.trim is not None and not abs(args.trim) <= 0.5:
        ap.error(f"--trim must be within ±0.5 rad, got {args.trim}")
    try:
        cands = candidates(Path(args.snapshots), args.baseline)
    except FileNotFoundError as exc:
        ap.error(str(exc))
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    trim = "" if args.trim is None else repr(args.trim)
    config = {name: f"{name}:{TARGETS}:{trim}:{policy}" for name, policy in cands.items()}

    _stage(list(config.values()), args.short_seconds, args.short_seeds, args.workers, out / "short.jsonl", args.scenes)
    short = success_by_config(out / "short.jsonl")
    ranked = sorted((n for n in cands if n != "baseline"), key=lambda n: -short[n]["success"])
    finalists = list(dict.fromkeys(ranked[: args.top] + (["baseline"] if "baseline" in cands else [])))
    full: dict[str, dict[str, float]] = {}
    chosen = None
    if args.full_seeds.strip():
        _stage([config[n] for n in finalists], args.full_seconds, args.full_seeds, args.workers, out / "full.jsonl",
               args.scenes)
        full = success_by_config(out / "full.jsonl")
        # the highest full-protocol success; on a tie the baseline, then the earlier snapshot
        order = list(cands)
        chosen = max(finalists, key=lambda n: (full[n]["success"], n == "baseline", -order.index(n)))
    result = {
        "candidates": {n: {"policy": p, "short": short.get(n), "full": full.get(n)} for n, p in cands.items()},
        "short_ranking": ranked,
        "finalists": finalists if full else [],
        "chosen": chosen,
        "chosen_policy": cands.get(chosen) if chosen else None,
        "settings": {k: getattr(args, k) for k in ("short_seconds", "short_seeds", "top", "full_seconds", "full_seeds",
                                                   "trim", "scenes")},
    }
    (out / "selection.json").write_text(json.dumps(result, indent=1))
    for n, c in result["candidates"].items():
        s = c["short"]
        f = c["full"]
        print(f"{n:12s} short {s['success']:.3f} ({s['trips']} trips)"
              + (f"  full {f['success']:.3f} ({f['trips']} trips)" if f else ""))
    print(f"chosen: {chosen} ({result['chosen_policy']})" if chosen else "short protocol only: no choice made")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
