"""Where and why do physics pedestrians stand? One scene of the following protocol, traced.

    python scripts/amp_stand_trace.py --scene home --people 5 --crowd diffusion --seconds 200 --seed 0 \
        [--diffusion-set K=V,...] [--set KEY=VALUE ...] --out F.json [--plot F.png]
    python scripts/amp_stand_trace.py --plot-contacts A.json B.json --out F.png

Runs one scene as ``navzoo eval pedestrians`` does (``navzoo.benchmark.pedestrians._make``: the shipped AMP
policy, today's target settings, no robot) and samples every ``--every`` s each standing (not fallen) person:
its speed over the last sample interval, its goal and next A* waypoint, the distance from its body to its own
target point (``env.amp.target_now()``), the target point's speed, its wall and people contacts at that step, the distance
to the nearest other person and the clearance of its position (``Scene.clearance``). A person who moved less
than ``--still`` m/s is *standing*, and each standing sample gets one cause, first match wins:

- ``target stands``: its target point is within 0.4 m of the body and moved less than ``--still`` m/s too:
  the target generator holds the person (a jam or a stop in the crowd model itself);
- ``wall contact``: the target is ahead, and the body touches a wall or an obstacle;
- ``person near``: the target is ahead, and another person stands within 0.9 m (a jam between bodies);
- ``held, no contact``: the target is ahead and nothing touches or is near (the body does not follow).

Each class is split by where it happens: ``narrow`` where the clearance is below 0.6 m (doors, gaps between
furniture, beside a wall), ``open`` elsewhere. ``--plot`` draws the scene with every standing sample coloured by
cause. ``--set`` gives NavConfig fields to the run (e.g. ``amp_wall_strength=0.3``, as ``navzoo eval pedestrians
--set``). The summary's ``walls`` splits the wall contacts of all samples (walking or standing) by whether another
person is within ``PASSING_M`` (1.5 m): contacts while people pass or queue, against contacts of a person alone
(along a wall, round a corner). Each sample also records ``target_bearing_deg``, the bearing of the person's next
target points (the mean of the next five, 0.5 s apart) from the body's heading, and the summary's ``facing`` splits
the standing samples by it: ``behind`` (more than 90 degrees off), ``side`` (45-90) and ``ahead``, with the mean
distance of those points from a standing body (``target_points_m``; the controller walks off slowly, or not at all,
toward slow targets behind it: scripts/amp_slow_target_probe.py). ``--const NAME=VALUE`` sets an upper-case numeric
or boolean constant of ``navzoo.envs.amp_humans`` for the run (e.g. ``--const STALL_WARP_S=1.0``). A diagnostic: the
counts depend on the seed, and it says where person-time goes, not why a policy acts. With door turns on
(``NavConfig.human_door_turns``) each sample also records the person's door turn (:func:`door_state`), and the
summary's ``doors`` splits the standing samples within ``DOOR_NEAR_M`` of the person's next door by it. The
summary's ``waypoint_hidden`` is the share of samples whose next A* waypoint is out of the person's line of sight
(:func:`waypoint_hidden`: a body pushed past an obstacle, its waypoint behind it), ``standing_waypoint_hidden`` the
share standing so. ``--resummarize TRACE.json``
prints the summary of an earlier trace's samples again, from ``--after`` seconds on, of ``--person`` only and
within ``--box X0,Y0,X1,Y1`` (m) only.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

CAUSES = ("target stands", "wall contact", "person near", "held, no contact")
NEAR_TARGET_M = 0.4
NEAR_PERSON_M = 0.9
NARROW_M = 0.6
PASSING_M = 1.5
DOOR_NEAR_M = 3.0


def trace(scene: str, people: int, crowd: str, seconds: float, seed: int, every: float, still: float,
          policy_dir: str | None = None, diffusion_settings: dict | None = None,
          env_overrides: dict | None = None) -> dict:
    from navzoo.benchmark import pedestrians as P
    from navzoo.benchmark.matched_realism import diffusion_settings_for_new_crowds
    from navzoo.torch_threads import one_torch_thread

    with one_torch_thread(), diffusion_settings_for_new_crowds(diffusion_settings):
        wrapped, env = P._make(scene, people, "amp", seconds, seed, policy_dir, crowd, env_overrides)
        h = np.arange(env.n_robots, env.n_total)
        dt_s = sample_interval(env, every)
        samples: list[dict] = []
        t0 = time.time()
        for pos, tgt, speed, tgt_speed in sampled_run(wrapped, env, h, dt_s):
            root, heading, _, _ = env.amp.planar()
            ahead = env.amp.waypoints()[:, :5].mean(axis=1) - root
            bearing = np.degrees((np.arctan2(ahead[:, 1], ahead[:, 0]) - heading + np.pi) % (2 * np.pi) - np.pi)
            d = np.linalg.norm(pos[:, None] - pos[None], axis=2)
            np.fill_diagonal(d, np.inf)
            clear = env.scene.clearance(pos)
            goal, wp = env.goal[h], env.next_waypoints()[h]
            for j in range(len(h)):
                if env.human_fallen[j]:
                    continue
                samples.append({
                    "t": round(float(env.sim_time), 2), "id": j, "x": float(pos[j, 0]), "y": float(pos[j, 1]),
                    "speed": float(speed[j]), "target_m": float(np.linalg.norm(tgt[j] - pos[j])),
                    "target_speed": float(tgt_speed[j]), "wall": bool(env.human_map_contact[j]),
                    "agent": bool(env.human_agent_contact[j]),
                    "nearest_m": float(d[j].min()) if len(h) > 1 else float("inf"), "clearance": float(clear[j]),
                    "target_bearing_deg": float(bearing[j]), "target_points_m": float(np.linalg.norm(ahead[j])),
                    "goal": [round(float(v), 2) for v in goal[j]], "waypoint": [round(float(v), 2) for v in wp[j]],
                    **door_state(env.door_turns, j, pos[j]),
                })
        goals = int(env.goals_reached[h].sum())
        wrapped.close()
    for s in samples:
        s["cause"] = classify(s, still) if s["speed"] < still else None
        s["narrow"] = s["clearance"] < NARROW_M
    return {"scene": scene, "people": people, "crowd": crowd, "diffusion_settings": diffusion_settings or {},
            "env_overrides": env_overrides or {},
            "seconds": seconds, "seed": seed, "every_s": dt_s,
            "still_mps": still, "goals": goals, "wall_s": round(time.time() - t0, 1), "samples": samples,
            "summary": {**summarize(samples),
                        **sight_summary(samples, waypoint_hidden(scene, samples,
                                                                 (env_overrides or {}).get("human_radius", 0.3)))}}


def sample_interval(env, every: float) -> float:
    """The sampling interval (s): ``every`` rounded to a whole number (at least one) of the env's steps."""
    return max(int(round(every / env.config.dt)), 1) * env.config.dt


def sampled_run(wrapped, env, h: np.ndarray, dt_s: float):
    """Step ``wrapped`` (no robot actions) to the end of the run; every ``dt_s`` s (:func:`sample_interval`) yield the
    positions (H, 2) and target points (H, 2) of the pedestrians ``h``, and their speeds (H,) since the last sample."""
    k_every = max(int(round(dt_s / env.config.dt)), 1)
    prev_pos, prev_tgt = env.pos[h].copy(), env.amp.target_now().copy()
    steps = 0
    while not env._needs_reset:
        wrapped.step({})
        steps += 1
        if steps % k_every:
            continue
        pos, tgt = env.pos[h].copy(), env.amp.target_now().copy()
        speed = np.linalg.norm(pos - prev_pos, axis=1) / dt_s
        tgt_speed = np.linalg.norm(tgt - prev_tgt, axis=1) / dt_s
        prev_pos, prev_tgt = pos, tgt
        yield pos, tgt, speed, tgt_speed


def door_state(turns, j: int, pos: np.ndarray) -> dict:
    """Person ``j``'s door turns at the last update (``NavConfig.human_door_turns``; {} when off): ``door`` (its next
    door on its path, -1: none), ``door_m`` (distance to that door's centre), ``door_state`` (``held``: it holds the
    door; ``waits``: it asked and was not granted; ``against``: the door is held the other way and it does not hold
    it; ``free`` otherwise; ``none`` without a next door) and ``door_room`` (whether its side has a waiting spot)."""
    if turns is None:
        return {}
    d, g = int(turns._cur[j]), int(turns._sign[j])
    if d < 0:
        return {"door": -1, "door_m": float("inf"), "door_state": "none", "door_room": False}
    held = turns._held_ways(turns._sign)[d]
    state = ("held" if turns.granted[j] == d else "waits" if bool(turns.waiting()[j])
             else "against" if held not in (0, g) else "free")
    return {"door": d, "door_m": float(np.linalg.norm(pos - turns.centres[d])), "door_state": state,
            "door_room": bool(turns.can_queue(d, g))}


def waypoint_hidden(scene: str, samples: list[dict], human_radius: float = 0.3) -> list[bool | None]:
    """For each sample with a ``waypoint`` (traces since 2026-12-06): whether that next A* waypoint was out of the
    person's line of sight on the scene's bare planning grid for a pedestrian of ``human_radius`` (the A* planner's
    ``line_of_sight`` from the nearest free point, as ``NavConfig.human_replan_blocked`` tests it; fallen bodies are
    not on that grid). None for samples without a waypoint or off the grid."""
    from navzoo.envs.nav_env import NavEnv

    env = NavEnv(scene=scene, n_robots=0, n_humans=1, human_model="kinematic", human_radius=human_radius)
    planner = env._planner(float(human_radius))
    out: list[bool | None] = []
    for x in samples:
        sees = planner.sight_from((x["x"], x["y"]), np.asarray(x["waypoint"])) if "waypoint" in x else None
        out.append(None if sees is None else not sees)
    env.close()
    return out


def sight_summary(samples: list[dict], hidden: list[bool | None]) -> dict:
    """Shares of all samples whose next waypoint is hidden (:func:`waypoint_hidden`), and of those standing."""
    n = len(samples)
    return {"waypoint_hidden": sum(bool(h) for h in hidden) / n if n else 0.0,
            "standing_waypoint_hidden": sum(bool(h) and s["cause"] is not None for s, h in zip(samples, hidden,
                                                                                             strict=True)) / n
            if n else 0.0}


def parse_const(items: list[str]) -> dict[str, float | int | bool]:
    """``--const NAME=VALUE`` items: upper-case numeric or boolean constants of ``navzoo.envs.amp_humans``, parsed as
    the SET field of ``scripts/amp_target_ablation.py`` is (``parse_constants``); ValueError naming the item."""
    if not items:
        return {}
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from amp_target_ablation import parse_constants

    out: dict[str, float | int | bool] = {}
    for item in items:
        out.update(parse_constants(item, item, what="--const"))
    return out


def apply_const(items: list[str]) -> dict[str, float | int | bool]:
    """:func:`parse_const` the ``--const`` items and set them on ``navzoo.envs.amp_humans``; returns them (ValueError
    naming a bad item, before anything is set)."""
    consts = parse_const(items)
    from navzoo.envs import amp_humans

    for name, value in consts.items():
        setattr(amp_humans, name, value)
    return consts


def classify(s: dict, still: float) -> str:
    """The cause of one standing sample (see the module doc)."""
    if s["target_m"] < NEAR_TARGET_M and s["target_speed"] < still:
        return "target stands"
    if s["wall"]:
        return "wall contact"
    if s["nearest_m"] < NEAR_PERSON_M:
        return "person near"
    return "held, no contact"


def summarize(samples: list[dict]) -> dict:
    """Shares of all standing-person samples: standing, and each cause split into narrow / open places."""
    n = len(samples)
    stand = [s for s in samples if s["cause"] is not None]
    out: dict = {"samples": n, "standing_share": len(stand) / n if n else 0.0, "causes": {}}
    for c in CAUSES:
        these = [s for s in stand if s["cause"] == c]
        out["causes"][c] = {
            "share_of_person_time": len(these) / n if n else 0.0,
            "narrow": sum(s["narrow"] for s in these) / n if n else 0.0,
            "open": sum(not s["narrow"] for s in these) / n if n else 0.0,
        }
    wall = [s for s in samples if s["wall"]]
    passing = [s for s in wall if s["nearest_m"] < PASSING_M]
    facing = {"behind": lambda b: b > 90.0, "side": lambda b: 45.0 < b <= 90.0, "ahead": lambda b: b <= 45.0}
    out["facing"] = {k: sum(test(abs(x.get("target_bearing_deg", 0.0))) for x in stand) / n if n else 0.0
                     for k, test in facing.items()}
    out["facing"]["target_points_m"] = (float(np.mean([x.get("target_points_m", np.nan) for x in stand]))
                                        if stand else float("nan"))
    out["standing_medians"] = {k: float(np.median([x[k] for x in stand])) if stand else float("nan")
                               for k in ("target_speed", "nearest_m")}
    near = [x for x in stand if x.get("door_m", np.inf) < DOOR_NEAR_M]
    if any("door_state" in x for x in samples):  # door turns on: the states of standing samples near a door
        out["doors"] = {"standing_near_door": len(near) / n if n else 0.0,
                        **{f"{st}, {'room' if room else 'no room'}":
                           sum(x["door_state"] == st and x["door_room"] == room for x in near) / n if n else 0.0
                           for st in ("held", "waits", "against", "free") for room in (True, False)}}
    out["walls"] = {"contact_share": len(wall) / n if n else 0.0,
                    "passing": len(passing) / n if n else 0.0, "alone": (len(wall) - len(passing)) / n if n else 0.0,
                    "standing": sum(s["cause"] is not None for s in wall) / n if n else 0.0}
    return out


def load_trace(path: str) -> dict:
    """An earlier trace (an ``--out`` file), plain or gzipped (``.gz``, as the traces kept under docs/results)."""
    if path.endswith(".gz"):
        import gzip

        with gzip.open(path, "rt") as f:
            return json.load(f)
    return json.loads(Path(path).read_text())


def window(samples: list[dict], after: float | None = None, people: list[int] | None = None,
           box: tuple[float, float, float, float] | None = None) -> list[dict]:
    """The samples from ``after`` seconds on, of the persons ``people`` (None: all), inside ``box``
    (x0, y0, x1, y1; None: anywhere)."""
    return [s for s in samples if (after is None or s["t"] >= after) and (people is None or s["id"] in people)
            and (box is None or (box[0] <= s["x"] <= box[2] and box[1] <= s["y"] <= box[3]))]


def plot(result: dict, out: str) -> None:
    import matplotlib

    matplotlib.use("Agg")

    from navzoo.world.library import get_scene
    from navzoo.world.plot import plot_scene

    scene = get_scene(result["scene"])
    ax = plot_scene(scene, show_regions=False, show_waypoints=False,
                    title=f"{result['scene']}, {result['people']} people, {result['crowd']} targets, seed "
                          f"{result['seed']}: standing samples by cause")
    colors = dict(zip(CAUSES, ("#1f77b4", "#d62728", "#ff7f0e", "#7f7f7f"), strict=True))
    walk = [s for s in result["samples"] if s["cause"] is None]
    ax.scatter([s["x"] for s in walk], [s["y"] for s in walk], s=2, c="#2ca02c", alpha=0.25, label="walking")
    for c in CAUSES:
        pts = [s for s in result["samples"] if s["cause"] == c]
        share = result["summary"]["causes"][c]["share_of_person_time"]
        ax.scatter([s["x"] for s in pts], [s["y"] for s in pts], s=6, c=colors[c], alpha=0.6,
                   label=f"{c} ({share:.0%} of person-time)")
    ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    ax.figure.tight_layout()
    ax.figure.savefig(out, dpi=110)


def plot_contacts(results: list[dict], out: str) -> None:
    """Top views side by side, one per trace (e.g. two settings of one scene): every sample green, the samples in
    wall contact red (walking) or black (standing)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from navzoo.world.library import get_scene
    from navzoo.world.plot import plot_scene

    fig, axes = plt.subplots(1, len(results), figsize=(6 * len(results), 5), squeeze=False)
    for ax, r in zip(axes[0], results, strict=True):
        what = ", ".join(f"{k} {v}" for k, v in r.get("env_overrides", {}).items()) or "defaults"
        plot_scene(get_scene(r["scene"]), ax=ax, show_regions=False, show_waypoints=False,
                   title=f"{r['scene']}, {r['crowd']} targets, seed {r['seed']}: {what}")
        s = r["samples"]
        ax.scatter([x["x"] for x in s], [x["y"] for x in s], s=1, c="#2ca02c", alpha=0.15)
        w = [x for x in s if x["wall"]]
        ax.scatter([x["x"] for x in w], [x["y"] for x in w], s=12,
                   c=["#d62728" if x["cause"] is None else "k" for x in w],
                   label=f"wall contact, {r['summary']['walls']['contact_share']:.2%} of person-time")
        ax.legend(loc="upper left", fontsize=7, framealpha=0.9)
    fig.tight_layout()
    fig.savefig(out, dpi=80)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="home")
    ap.add_argument("--people", type=int, default=5)
    ap.add_argument("--crowd", default="diffusion", help="target generator: sfm, orca or diffusion")
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--every", type=float, default=0.5, help="sample interval (s)")
    ap.add_argument("--still", type=float, default=0.15, help="below this speed (m/s) a person stands")
    ap.add_argument("--policy", default=None, help="exported AMP policy directory (default: the shipped one)")
    ap.add_argument("--diffusion-set", default="", metavar="K=V,...",
                    help="diffusion crowd settings (names as in `navzoo eval crowd-matched --diffusion-set`)")
    ap.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE",
                    help="NavConfig field for the run, repeatable (e.g. --set amp_wall_strength=0.3)")
    ap.add_argument("--const", action="append", default=[], metavar="NAME=VALUE",
                    help="upper-case numeric or boolean constant of navzoo.envs.amp_humans, repeatable")
    ap.add_argument("--out", default=None, help="JSON result (samples and summary)")
    ap.add_argument("--resummarize", default=None, metavar="TRACE.json",
                    help="print the summary of an earlier trace's samples (with --after, --person) and stop")
    ap.add_argument("--after", type=float, default=None, help="with --resummarize: only samples from this time (s)")
    ap.add_argument("--person", default=None, help="with --resummarize: only these persons (comma-separated)")
    ap.add_argument("--box", default=None, metavar="X0,Y0,X1,Y1",
                    help="with --resummarize: only samples inside this rectangle (m)")
    ap.add_argument("--plot", default=None, help="PNG top view of the standing samples")
    ap.add_argument("--plot-contacts", nargs="+", default=None, metavar="TRACE.json",
                    help="only draw the wall contacts of earlier traces (--out files), side by side, into --out (PNG)")
    args = ap.parse_args()
    if args.resummarize:
        try:
            people = [int(x) for x in args.person.split(",")] if args.person else None
        except ValueError:
            ap.error(f"--person {args.person!r}: expected comma-separated person numbers")
        box = None
        if args.box:
            try:
                box = tuple(float(x) for x in args.box.split(","))
            except ValueError:
                box = ()
            if len(box) != 4 or not (box[0] < box[2] and box[1] < box[3]):
                ap.error(f"--box {args.box!r}: expected X0,Y0,X1,Y1 with X0 < X1 and Y0 < Y1")
        tr = load_trace(args.resummarize)
        samples = window(tr["samples"], args.after, people, box)
        summary = summarize(samples)
        if samples and "waypoint" in samples[0]:
            summary.update(sight_summary(samples, waypoint_hidden(
                tr["scene"], samples, tr.get("env_overrides", {}).get("human_radius", 0.3))))
        print(json.dumps(summary, indent=1))
        return
    if args.out is None:
        ap.error("--out is required")
    if args.plot_contacts:
        plot_contacts([load_trace(f) for f in args.plot_contacts], args.out)
        return
    if args.people < 1 or args.seconds <= 0 or args.every <= 0 or args.still <= 0:
        ap.error("--people, --seconds, --every and --still must be positive")
    from navzoo.benchmark.matched_realism import _settings, check_diffusion_settings
    from navzoo.benchmark.pedestrians import env_set_option

    try:
        settings = check_diffusion_settings(_settings(args.diffusion_set))
        overrides = env_set_option("amp_stand_trace.py", args.env_set)
        consts = apply_const(args.const)
    except ValueError as e:
        ap.error(str(e))
    result = trace(args.scene, args.people, args.crowd, args.seconds, args.seed, args.every, args.still, args.policy,
                   settings, overrides)
    result["const"] = consts
    Path(args.out).parent.mkdir(parents=True, exist_ok=True)
    Path(args.out).write_text(json.dumps(result) + "\n")
    print(json.dumps({k: v for k, v in result.items() if k != "samples"}, indent=1))
    if args.plot:
        plot(result, args.plot)


if __name__ == "__main__":
    main()
