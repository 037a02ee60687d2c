"""Ablation of how physics (AMP) pedestrians' target trajectories are made, on the following protocol.

Runs :func:`navzoo.benchmark.pedestrians.follow_scene` (8 scenes, 3-15 people, social-force targets)
once per configuration and scene, in parallel processes, and appends one JSON row per run to
``--out`` (runs already there, same configuration, crowd model, settings, scene and seed, are skipped, so an
interrupted run resumes; a name already there with other parameters is refused). A configuration is
``NAME:PLAN_MARGIN:WALL_MARGIN:LOOKAHEAD[:TURN_RATE[:FALLEN]]`` and sets, in every worker,
``navzoo.envs.amp_humans.PLAN_MARGIN`` (people and A* inflation), ``WALL_PLAN_MARGIN`` (walls in the
social-force rollouts), ``WAYPOINT_LOOKAHEAD`` (0 = waypoints in strict order) and
``TARGET_TURN_RATE`` (rad/s, the rollouts' heading-rate limit; 0 or left out = off) and, with
FALLEN = 1, ``NavConfig.human_fallen_obstacles`` (people plan around fallen bodies; 0 or left out = NavConfig's
default, which is on since 2026-12-06: ``human_fallen_obstacles=false`` turns it off; rows record the value used);
FALLEN may instead name boolean NavConfig flags to turn on, joined by ``+`` (e.g.
``human_door_entries+human_fallen_obstacles``), or set word-valued ones as ``name=value`` (e.g.
``human_replan_blocked=off``) and numeric ones the same way (e.g. ``amp_wall_strength=0.3``; values are read as
``--set`` values are: JSON, else a word). A seventh field TRIM sets the AMP policy's steering
trim in rad (``AmpPolicy.steering_trim``; left out = the policy's own, see ``navzoo train amp-trim``).
An eighth field POLICY names an exported AMP policy directory (left out = the shipped one); an empty
TRIM field keeps that policy's own trim. A ninth field ACCEL sets ``TARGET_ACCEL`` and ``DIFFUSION_TARGET_ACCEL`` (m/s², the
rollouts' speed-up limit; 0 = off; left out = the module's defaults); empty TRIM and POLICY fields keep
the policy's own. A tenth field GRADED turns the graded wall margin of the rollouts on (1) or off (0)
(``GRADED_WALL_MARGIN``: less wall margin in doors too narrow for it; left out or empty = the module's default, on).
An eleventh field SKIP does the same for ``SKIP_PASSED_WAYPOINTS`` (moving past waypoints a body has passed
while it sees the next one; default off), and a twelfth field KEEP for ``KEEP_APART`` (the people margin of the
rollouts held by a short-range push instead of a wider radius). A thirteenth field DCAP sets
``DIFFUSION_SPEED_CAP`` (the rollouts toward diffusion plans go at most DCAP x the preferred speed; left out
or empty = the module's default), and a fourteenth field SCAP sets ``TARGET_SPEED_CAP`` (the social-force or
ORCA rollouts go at most SCAP x the preferred speed; 0 = off; left out or empty = the module's default), and a
fifteenth field LAG turns ``LAG_LIMIT_RULES`` on (1) or off (0) (social-force and ORCA targets run at most
``LAG_LIMIT_S`` ahead of the body, as diffusion targets do; default on since 2026-12-01). A sixteenth field SET sets other
upper-case constants of ``navzoo.envs.amp_humans``, ``NAME=VALUE`` joined by ``+`` (e.g.
``START_LAG=1+START_REPLAN_S=0.7``; the value takes the constant's type, booleans as 1 or 0).
``--crowd`` picks the crowd model that makes the targets (default ``sfm``), and
``--diffusion-set K=V,...`` changes the diffusion crowd's settings in every run (names as in
``navzoo eval crowd-matched --diffusion-set``).
``--scenes`` picks some of the 8 scenes (each keeps its people count), or names any library scene with its people
count as ``SCENE:N``, or ``heldout`` for :data:`navzoo.benchmark.pedestrians.HELDOUT_SCENES` (10 scenes no setting
was chosen on, 3-15 people). ``--bodies kinematic`` walks the crowd
model with kinematic bodies instead (the AMP-only fields then change nothing; for NavConfig fields that
apply to both, such as ``human_replan_blocked=all``).

    python scripts/amp_target_ablation.py --configs before:0.1:0.1:0,now:0.1:0:4 --seconds 200 \
        --workers 16 --out docs/results/amp_target_ablation.jsonl
    python scripts/amp_target_ablation.py --summary docs/results/amp_target_ablation.jsonl [--by-scene | --pooled] [--summary-seeds 0,1]
"""

from __future__ import annotations

import argparse
import json
import multiprocessing as mp
import sys
import typing
from contextlib import nullcontext
from pathlib import Path


def parse_config(text: str) -> dict:
    parts = text.split(":")
    if len(parts) not in range(4, 17):
        raise ValueError("a configuration is NAME:PLAN_MARGIN:WALL_MARGIN:LOOKAHEAD[:TURN_RATE[:FALLEN[:TRIM[:POLICY[:ACCEL"
                         "[:GRADED[:SKIP[:KEEP[:DCAP[:SCAP[:LAG[:SET]]]]]]]]]]]]], "
                         f"got {text!r}")
    name, plan, wall, ahead = parts[:4]
    cfg = {"name": name, "plan_margin": float(plan), "wall_margin": float(wall), "lookahead": int(ahead),
           "turn_rate": float(parts[4]) if len(parts) >= 5 else 0.0,
           "trim": float(parts[6]) if len(parts) >= 7 and parts[6] else None,
           "policy": parts[7] if len(parts) >= 8 and parts[7] else None,
           "accel": float(parts[8]) if len(parts) >= 9 and parts[8] else None,
           "graded": {"1": True, "0": False}.get(parts[9]) if len(parts) >= 10 and parts[9] else None,
           "skip": {"1": True, "0": False}.get(parts[10]) if len(parts) >= 11 and parts[10] else None,
           "keep": {"1": True, "0": False}.get(parts[11]) if len(parts) >= 12 and parts[11] else None,
           "dcap": float(parts[12]) if len(parts) >= 13 and parts[12] else None,
           "scap": float(parts[13]) if len(parts) >= 14 and parts[13] else None,
           "lag": {"1": True, "0": False}.get(parts[14]) if len(parts) >= 15 and parts[14] else None,
           "set": parse_constants(parts[15], text) if len(parts) == 16 and parts[15] else None}
    for field, i in (("GRADED", 9), ("SKIP", 10), ("KEEP", 11), ("LAG", 14)):
        if len(parts) > i and parts[i] and cfg[field.lower()] is None:
            raise ValueError(f"{field} must be 1 or 0, got {parts[i]!r} in {text!r}")
    if cfg["policy"] is not None and not (Path(cfg["policy"]) / "config.json").is_file():
        raise ValueError(f"no exported AMP policy (config.json) in {cfg['policy']!r}, in {text!r}")
    flags = parts[5].strip() if len(parts) >= 6 else "0"
    cfg["env_flags"] = [] if flags == "0" else ["human_fallen_obstacles"] if flags == "1" else flags.split("+")
    from navzoo.benchmark.pedestrians import check_env_overrides
    from navzoo.envs.config import NavConfig

    hints = typing.get_type_hints(NavConfig)
    for flag in cfg["env_flags"]:
        name, eq, _ = flag.partition("=")
        # a boolean field, or one that is a bool or None (human_door_turns: None = on for AMP pedestrians)
        if not eq and hints.get(name) not in (bool, bool | None):
            raise ValueError(f"{flag!r} is not a boolean NavConfig field (give other fields as name=value), in {text!r}")
    try:  # a field NavConfig lacks, one the protocol sets, or a value it refuses is named here, before any run
        check_env_overrides(env_overrides(cfg["env_flags"]))
    except ValueError as e:
        raise ValueError(f"{e}, in {text!r}") from None
    cfg["fallen_obstacles"] = bool(env_overrides(cfg["env_flags"]).get(
        "human_fallen_obstacles", NavConfig.__dataclass_fields__["human_fallen_obstacles"].default))
    if min(cfg["plan_margin"], cfg["wall_margin"], cfg["lookahead"], cfg["turn_rate"], cfg["accel"] or 0.0) < 0:
        raise ValueError(f"margins, lookahead, turn rate and acceleration must be >= 0, got {text!r}")
    if cfg["dcap"] is not None and not cfg["dcap"] > 0:
        raise ValueError(f"the diffusion speed cap DCAP must be > 0, got {text!r}")
    if cfg["scap"] is not None and not cfg["scap"] >= 0:
        raise ValueError(f"the target speed cap SCAP must be >= 0 (0 = off), got {text!r}")
    if cfg["trim"] is not None and not abs(cfg["trim"]) <= 0.5:
        raise ValueError(f"the steering trim must be within ±0.5 rad, got {text!r}")
    return cfg


def parse_constants(field: str, text: str, what: str = "SET") -> dict:
    """The SET field: ``NAME=VALUE`` pairs joined by ``+``, each an upper-case constant of
    ``navzoo.envs.amp_humans``; values take the constant's type (booleans as 1 or 0). ``what`` names the option in
    the error messages (other scripts' ``--const`` takes the same pairs)."""
    import navzoo.envs.amp_humans as ah

    out: dict = {}
    for pair in field.split("+"):
        name, eq, value = pair.partition("=")
        current = getattr(ah, name, None) if name.isupper() else None
        if not eq or not isinstance(current, (bool, int, float)):
            raise ValueError(f"{what} takes NAME=VALUE of a numeric or boolean upper-case constant of "
                             f"navzoo.envs.amp_humans, got {pair!r} in {text!r}")
        try:
            if isinstance(current, bool):
                out[name] = {"1": True, "0": False}[value]
            else:
                out[name] = type(current)(value)
        except (KeyError, ValueError):
            kind, why = ("1 or 0", "") if isinstance(current, bool) else (type(current).__name__, " (not a number)")
            raise ValueError(f"{name} takes {kind}, got {value!r}{why} in {text!r}") from None
    return out


def env_overrides(flags: list[str]) -> dict:
    """NavConfig fields of a configuration's FALLEN field: ``name`` (a boolean, turned on) or ``name=value``
    (the value read as ``--set`` values are, :func:`navzoo.envs.config.parse_override`: JSON, else a word)."""
    from navzoo.envs.config import parse_override

    out: dict = {}
    for flag in flags:
        name, value = parse_override(flag) if "=" in flag else (flag, True)
        out[name] = value
    return out


def _run(job: tuple[dict, str, int, float, int, str, dict]) -> dict:
    import os

    os.environ.setdefault("OMP_NUM_THREADS", "1")
    cfg, scene, n, seconds, seed, crowd, diffusion_settings, bodies = job
    import navzoo.envs.amp_humans as ah
    import navzoo.envs.nav_env as ne

    ah.PLAN_MARGIN = ne.AMP_PLAN_MARGIN = cfg["plan_margin"]
    ah.WALL_PLAN_MARGIN = cfg["wall_margin"]
    ah.WAYPOINT_LOOKAHEAD = ne.WAYPOINT_LOOKAHEAD = cfg["lookahead"]
    ah.TARGET_TURN_RATE = cfg["turn_rate"]
    if cfg.get("accel") is not None:
        ah.TARGET_ACCEL = ah.DIFFUSION_TARGET_ACCEL = cfg["accel"]
    if cfg.get("graded") is not None:
        ah.GRADED_WALL_MARGIN = cfg["graded"]
    if cfg.get("skip") is not None:
        ah.SKIP_PASSED_WAYPOINTS = cfg["skip"]
    if cfg.get("keep") is not None:
        ah.KEEP_APART = cfg["keep"]
    if cfg.get("dcap") is not None:
        ah.DIFFUSION_SPEED_CAP = cfg["dcap"]
    if cfg.get("scap") is not None:
        ah.TARGET_SPEED_CAP = cfg["scap"]
    if cfg.get("lag") is not None:
        ah.LAG_LIMIT_RULES = cfg["lag"]
    for name, value in (cfg.get("set") or {}).items():
        setattr(ah, name, value)
    from navzoo.benchmark.matched_realism import diffusion_settings_for_new_crowds
    from navzoo.benchmark.pedestrians import follow_scene

    with diffusion_settings_for_new_crowds(diffusion_settings):  # every DiffusionCrowd of the run gets them
        row = follow_scene(scene, n, seconds, seed, env_overrides=env_overrides(cfg["env_flags"]),
                           steering_trim=cfg.get("trim"), policy_dir=cfg.get("policy"), crowd_model=crowd,
                           human_model=bodies)
    row.pop("poses")
    row.pop("walk_kin")  # speed / acceleration / jerk samples: navzoo eval crowd reports them
    from navzoo.machine import cpu_model, package_versions

    return {"config": cfg["name"],
            **{k: cfg[k] for k in (*_PARAMS, "fallen_obstacles")},
            "crowd": crowd, "bodies": bodies, "diffusion_settings": diffusion_settings, "seed": seed, **row,
            "cpu": cpu_model(), "packages": package_versions()}


_PARAMS = ("plan_margin", "wall_margin", "lookahead", "turn_rate", "env_flags", "trim", "policy", "accel", "graded",
           "skip", "keep", "dcap", "scap", "lag", "set")


def parse_scenes(text: str | None) -> dict[str, int]:
    """Scene -> people of ``--scenes``: the protocol's 8 scenes (``None``), names among them (each keeps its people
    count), ``SCENE:N`` for any library scene with N people, and ``heldout`` for
    :data:`~navzoo.benchmark.pedestrians.HELDOUT_SCENES`. Unknown scenes and bad counts are refused."""
    from navzoo.benchmark.pedestrians import HELDOUT_SCENES, SCENES, people_per_scene
    from navzoo.world.library import get_scene

    protocol = dict(zip(SCENES, people_per_scene(len(SCENES)), strict=True))
    if text is None:
        return protocol
    out: dict[str, int] = {}
    for item in (x.strip() for x in text.split(",")):
        if item == "heldout":
            pairs = list(HELDOUT_SCENES)
        elif ":" in item:
            name, _, count = item.partition(":")
            try:
                n = int(count)
            except ValueError:
                raise ValueError(f"--scenes: people count of {name!r} must be an integer, got {count!r}") from None
            if n < 1:
                raise ValueError(f"--scenes: people count of {name!r} must be at least 1, got {n}")
            get_scene(name)  # ValueError naming the valid scenes
            pairs = [(name, n)]
        elif item in protocol:
            pairs = [(item, protocol[item])]
        else:
            raise ValueError(f"--scenes: {item!r} is not one of the protocol's scenes {list(SCENES)}; give another "
                             f"library scene with its people count as {item}:N, or 'heldout'")
        for name, n in pairs:
            if out.get(name, n) != n:
                raise ValueError(f"--scenes: {name!r} given with {out[name]} and {n} people")
            out[name] = n
    if not out:
        raise ValueError("--scenes: no scenes given")
    return out


def check_people(rows: list[dict], configs: list[dict], people: dict[str, int]) -> None:
    """Refuse a run whose scene is in the result file, for one of these configurations, with another people count:
    the resume key does not hold the count, so the new runs would be skipped or mixed with the old ones."""
    names = {c["name"] for c in configs}
    for r in rows:
        n = people.get(r["scene"])
        if r["config"] in names and n is not None and r.get("pedestrians", n) != n:
            raise ValueError(f"{r['scene']!r} is in the result file with {r['pedestrians']} people for configuration "
                             f"{r['config']!r}, asked for {n}; give another --out")


def _group(row: dict) -> tuple:
    """What a result row is a sample of: configuration, crowd model and its settings, seed, bodies. Rows
    written before the crowd (the bodies) was recorded were social-force runs (AMP bodies)."""
    settings = json.dumps(row.get("diffusion_settings") or {}, sort_keys=True)
    return row["config"], row.get("crowd", "sfm"), settings, row["seed"], row.get("bodies", "amp")


def done_runs(rows: list[dict], configs: list[dict]) -> set[tuple]:
    """Keys (group + scene) of the runs already in a result file, so a rerun skips exactly those. A
    configuration whose name is in the file with other parameters is refused: its rows would be mixed
    with the new ones under one name."""
    by_name = {c["name"]: c for c in configs}
    for r in rows:
        c = by_name.get(r["config"])
        if c is None:
            continue
        diff = [k for k in _PARAMS if k in r and r[k] != c[k]]
        if diff:
            raise ValueError(f"configuration {c['name']!r} is already in the result file with other "
                             f"{', '.join(diff)} ({', '.join(f'{r[k]!r}' for k in diff)}); give it another name "
                             "or another --out")
    return {(*_group(r), r["scene"]) for r in rows}


_RUN_FIELDS = ("success", "off_path", "fall", "timeout", "map_trips", "agent_trips", "err_n", "by_goal")


def _same_run(a: dict, b: dict) -> bool:
    """Whether two rows of one run key hold the same run: equal counts, path error sums equal to rounding."""
    return (all(a.get(k) == b.get(k) for k in _RUN_FIELDS)
            and abs(a["err_sum"] - b["err_sum"]) <= 1e-6 * max(1.0, abs(a["err_sum"])))


def _why_different(a: dict, b: dict) -> str:
    """What two rows of one run key record of where they ran, where it differs: CPUs, then package versions (rows
    since 2026-12-05 record them); empty when neither says."""
    cpus = {a.get("cpu"), b.get("cpu")}
    if len(cpus) == 2 and None not in cpus:
        return f" (run on different CPUs: {' and '.join(map(str, cpus))})"
    pa, pb = a.get("packages"), b.get("packages")
    if pa and pb and pa != pb:
        diff = [f"{k} {pa.get(k, 'absent')} and {pb.get(k, 'absent')}" for k in sorted({*pa, *pb})
                if pa.get(k) != pb.get(k)]
        return f" (run with different packages: {', '.join(diff)})"
    return ""


def read_rows(paths: str | list[str]) -> list[dict]:
    """The rows of one or more result files. A run (configuration, crowd model and settings, seed, bodies,
    scene) found in several files is kept once if its counts agree (the same floats repeat a run trip for trip),
    and refused if they differ (another installation or kind of CPU, or another setting under one name; the error
    names the CPUs or package versions where the rows record them): pooling both would count that seed and scene
    twice."""
    rows: list[dict] = []
    seen: dict[tuple, tuple[str, dict]] = {}
    for path in [paths] if isinstance(paths, str) else paths:
        for line in Path(path).read_text().splitlines():
            if not line.strip():
                continue
            r = json.loads(line)
            key = (*_group(r), r["scene"])
            if key in seen:
                first, other = seen[key]
                if not _same_run(r, other):
                    why = _why_different(other, r)  # in the order of the files named
                    raise ValueError(f"run {key[0]!r} seed {key[3]} {key[5]} is in {first} and {path} with different "
                                     f"counts: not the same run{why}")
                continue
            seen[key] = (path, r)
            rows.append(r)
    return rows


def summary(path: str | list[str], by_scene: bool = False, pooled: bool = False,
            seeds: list[int] | None = None, scenes: tuple[str, ...] | None = None) -> str:
    """Markdown table of one or more result files (:func:`read_rows`, a run found twice counted once): one
    line per configuration, crowd model and seed, or with
    ``by_scene`` one line per configuration, crowd model and scene, pooling the seeds, or with ``pooled``
    one line per configuration and crowd model, pooling seeds and scenes (trips counted together, not
    rates averaged); ``seeds`` keeps only those seeds' rows. Where the rows hold them, a second line counts
    the same runs one trip per goal (``pedestrians.Trips``). The last column is the share of the standing people's
    time in wall / people contact (rows that count it, ``contact_steps``; else n/a). ``scenes`` keeps only those scenes' rows (the
    labels count the scenes found; a ValueError when none is)."""
    import numpy as np

    from navzoo.benchmark.pedestrians import goal_trip_rates

    if by_scene and pooled:
        raise ValueError("choose one of by_scene and pooled")
    rows = read_rows(path)
    if seeds is not None:
        missing = sorted(set(seeds) - {r["seed"] for r in rows})
        if missing:
            where = path if isinstance(path, str) else ", ".join(path)
            raise ValueError(f"{where} holds no rows of seed(s) {', '.join(map(str, missing))}")
        rows = [r for r in rows if r["seed"] in seeds]
    if scenes is not None:
        rows = [r for r in rows if r["scene"] in scenes]
        if not rows:
            raise ValueError(f"no rows of scene(s) {', '.join(scenes)} in the result files")
    keys = ("success", "off_path", "fall", "timeout")
    lines = ["| configuration | trips | success | off path | fall | timeout | map contact | agent contact | path error (m) "
             "| wall / people contact time |",
             "|---|---|---|---|---|---|---|---|---|---|"]

    def group(r: dict) -> tuple:
        g = _group(r)
        if by_scene:
            return (*g[:3], r["scene"], r["pedestrians"], g[4])
        return (*g[:3], g[4]) if pooled else g

    for g in dict.fromkeys(group(r) for r in rows):
        rs = [r for r in rows if group(r) == g]
        name, crowd, settings = g[:3]
        if crowd != "sfm" or settings != "{}":
            name = f"{name} ({crowd}{'' if settings == '{}' else ' ' + settings})"
        if g[-1] != "amp":
            name = f"{name} [{g[-1]} bodies]"
        row_seeds = ",".join(map(str, sorted({r["seed"] for r in rs})))
        if by_scene:
            label = f"{name}, {g[3]} ({g[4]} people, seeds {row_seeds})"
        elif pooled:
            label = f"{name}, seeds {row_seeds} pooled ({len({r['scene'] for r in rs})} scenes)"
        else:
            label = f"{name}, seed {g[3]} ({len(rs)} scenes)"
        n = sum(r[k] for r in rs for k in keys)
        err_n = sum(r["err_n"] for r in rs)  # 0: no target trajectory (kinematic bodies of a rule-based crowd)
        err = f"{sum(r['err_sum'] for r in rs) / err_n:.3f}" if err_n else "n/a"
        share = {k: sum(r[k] for r in rs) / max(1, n) for k in (*keys, "map_trips", "agent_trips")}
        # share of the standing people's time in contact (rows since 2026-12-04 count it: contact_steps)
        if all("contact_steps" in r for r in rs):
            c = np.sum([r["contact_steps"] for r in rs], axis=0)
            times = f"{c[0] / max(c[2], 1):.4f} / {c[1] / max(c[2], 1):.4f}"
        else:
            times = "n/a"
        lines.append(f"| {label} | {n} | {share['success']:.3f} | {share['off_path']:.3f} | "
                     f"{share['fall']:.3f} | {share['timeout']:.3f} | {share['map_trips']:.3f} | "
                     f"{share['agent_trips']:.3f} | {err} | {times} |")
        if all("by_goal" in r for r in rs):  # the same runs, one trip per goal (pedestrians.Trips)
            g = goal_trip_rates([r["by_goal"] for r in rs])
            lines.append(f"| {label}, one trip per goal | {g['trips']} | {g['success_rate']:.3f} | "
                         f"{g['goal_rate'] - g['success_rate']:.3f} | {g['fall_rate']:.3f} | {g['timeout_rate']:.3f} | "
                         f"{g['map_collision_rate']:.3f} | {g['agent_collision_rate']:.3f} | | |")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--configs", default="before:0.1:0.1:0,now:0.1:0:4")
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--seeds", default="0")
    ap.add_argument("--scenes", default=None,
                    help="comma-separated: some of the 8 scenes, SCENE:N for any library scene with N people, or "
                         "'heldout' (default: the 8)")
    ap.add_argument("--workers", type=int, default=2,
                    help="runs at once, each in a fresh process (default 2); 0 runs them one after another in this "
                         "process, where a patched env is seen (scripts/trace_fallen_blocking.py)")
    ap.add_argument("--crowd", default="sfm", choices=("sfm", "orca", "diffusion"),
                    help="crowd model that makes the target trajectories (default sfm)")
    ap.add_argument("--bodies", default="amp", choices=("amp", "kinematic"),
                    help="pedestrian bodies (default amp: physics pedestrians tracking the crowd model's targets)")
    ap.add_argument("--diffusion-set", default="", metavar="K=V,...", help="diffusion crowd settings for every run")
    ap.add_argument("--out", default="amp_target_ablation.jsonl")
    ap.add_argument("--summary", metavar="JSONL", nargs="+",
                    help="print the table of one or more result files and exit (a run in several files counted once)")
    ap.add_argument("--by-scene", action="store_true", help="with --summary: one line per scene, seeds pooled")
    ap.add_argument("--pooled", action="store_true",
                    help="with --summary: one line per configuration, seeds and scenes pooled")
    ap.add_argument("--summary-seeds", default=None, metavar="S,S",
                    help="with --summary: only these seeds' rows (default: all in the file)")
    ap.add_argument("--summary-scenes", default=None, metavar="S,S",
                    help="with --summary: only these scenes' rows ('protocol' for the 8, 'heldout' for the 10)")
    args = ap.parse_args(argv)
    if args.summary:
        try:
            only = None if args.summary_seeds is None else [int(x) for x in args.summary_seeds.split(",")]
            from navzoo.benchmark.pedestrians import scene_names

            keep = None if args.summary_scenes is None else scene_names(args.summary_scenes)
            print(summary(args.summary, by_scene=args.by_scene, pooled=args.pooled, seeds=only, scenes=keep))
        except (ValueError, OSError) as e:
            ap.error(str(e))
        return 0
    if args.workers < 0:
        ap.error(f"--workers must be 0 (in this process) or more, got {args.workers}")
    configs = [parse_config(c) for c in args.configs.split(",")]
    seeds = [int(s) for s in args.seeds.split(",")]
    out = Path(args.out)
    rows = [json.loads(line) for line in out.read_text().splitlines() if line.strip()] if out.is_file() else []
    try:
        people = parse_scenes(args.scenes)
    except ValueError as exc:
        ap.error(str(exc))
    scenes = tuple(people)
    from navzoo.benchmark.matched_realism import _settings, check_diffusion_settings

    try:
        diffusion_settings = check_diffusion_settings(_settings(args.diffusion_set))
    except ValueError as exc:
        ap.error(str(exc))
    try:
        done = done_runs(rows, configs)
        check_people(rows, configs, people)
    except ValueError as exc:
        ap.error(str(exc))
    settings_key = json.dumps(diffusion_settings or {}, sort_keys=True)
    jobs = [(c, s, people[s], args.seconds, seed, args.crowd, diffusion_settings, args.bodies)
            for seed in seeds for s in scenes for c in configs
            if (c["name"], args.crowd, settings_key, seed, args.bodies, s) not in done]
    jobs.sort(key=lambda j: -j[2])  # crowded scenes first: they take longest
    print(f"{len(jobs)} runs ({len(rows)} rows already in {out})", file=sys.stderr, flush=True)
    pool = mp.get_context("spawn").Pool(args.workers, maxtasksperchild=1) if args.workers else nullcontext()
    with pool, out.open("a") as f:
        for row in (pool.imap_unordered(_run, jobs) if args.workers else map(_run, jobs)):
            f.write(json.dumps(row) + "\n")
            f.flush()
    print(summary(str(out)))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
