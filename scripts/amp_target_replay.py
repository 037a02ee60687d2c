"""Do a crowd's target trajectories alone fell a physics pedestrian? Record them in a crowd, replay them to a lone body.

    python scripts/amp_target_replay.py --scene lobby:15 --seed 0 [--policy DIR] [--replay-policy DIR] [--seconds 200] [--json F]
        [--save-targets F.npz] [--no-replay]

**Record.** One run of the following protocol's scene (social-force targets, today's defaults, as
``scripts/amp_target_ablation.py`` runs it) with the AMP policy ``--policy``. Every time a person's target path or its
timing changes (a replan, or an edit between replans), the path is kept *relative to where the body stands* (the path
minus the body's planar position), with the control step, the path's start step and its progress index; falls are
logged with their causes (:class:`navzoo.benchmark.pedestrians.FallLog`).

**Replay.** For each recorded person, one body alone in the open (``circle_crossing``, nobody else, as
``scripts/amp_slow_target_probe.py``) walks the same target paths: at each recorded step its path becomes the recorded
relative path, turned by the difference of the two bodies' first headings, added to its own position. It runs for as
long as the recorded person was up (to its fall, or the run's end), and the env's own planner is switched off. The
lone bodies run ``--replay-policy`` (default: the recording's policy), so one crowd's targets can be walked by
another controller. The lone body meets no people and no walls, so the replay keeps what the crowd's targets ask of a body (their speeds,
stops, turns, jitter between replans) and leaves out the people and the room.

``--save-targets F.npz`` also writes the recorded target updates of every person, in the format that
``navzoo train amp --recorded-targets F.npz`` trains on (:func:`navzoo.agents.amp.path_env.load_recorded_targets`);
``--no-replay`` records only.

The printout sets the falls per person-minute in the crowd (all causes, and those nothing touched within
``FALL_CAUSE_S``) against the replays', and the distance the bodies walked in each (a replay that walks about as far
asked about as much of its body). ``--json`` keeps one row per person. About 1-3 minutes per scene on a 2-core VM.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np


def record(scene: str, n: int, seed: int, seconds: float, policy_dir: str | None) -> dict:
    """The crowd run: per person its first heading, up-time (s), whether it fell and how, and its target updates
    ``(step, plan_t, k_prog, relative path, the body's heading)``, in the order they came."""
    from navzoo.benchmark import pedestrians as P

    wrapped, env = P._make(scene, n, "amp", seconds, seed, policy_dir, "sfm")
    amp = env.amp
    updates: list[list[tuple]] = [[] for _ in range(n)]
    last = [None] * n

    def keep(pos: np.ndarray, hd: np.ndarray) -> None:
        for j in range(n):
            key = (int(amp.plan_t[j]), amp.paths[j].tobytes())
            if key != last[j]:
                last[j] = key
                updates[j].append((int(amp.t), int(amp.plan_t[j]), int(amp.k_prog[j]),
                                   (amp.paths[j] - pos[j]).astype(np.float32), float(hd[j])))

    prev, heading0 = amp.planar()[:2]
    keep(prev, heading0)
    falls = P.FallLog(env)
    up_steps = np.zeros(n, dtype=np.int64)
    walked = np.zeros(n)
    h = slice(env.n_robots, env.n_total)
    while not env._needs_reset:
        wrapped.step({})
        fallen = env.human_fallen.copy()
        falls.update(env.human_map_contact, fallen, P.target_points(env))
        up_steps += ~fallen
        now = env.pos[h].copy()  # the bodies' planar roots after the step (the env reads them once per step)
        walked += np.where(fallen, 0.0, np.linalg.norm(now - prev, axis=1))
        prev = now
        keep(now, env.yaw[h])
    wrapped.close()
    dt = float(env.config.dt)
    causes: dict[int, str] = {e["id"]: P.fall_cause(e) for e in falls.events}
    return {"heading0": heading0, "updates": updates, "up_s": up_steps * dt, "dt": dt, "walked_m": walked,
            "fell": [j in causes for j in range(n)], "cause": [causes.get(j) for j in range(n)]}


def replay(updates: list[tuple], heading0: float, up_s: float, seed: int, policy_dir: str | None) -> dict:
    """One lone body walks a recorded person's target updates for ``up_s`` seconds: whether and when it fell."""
    from navzoo.benchmark import pedestrians as P

    wrapped, env = P._make("circle_crossing", 1, "amp", up_s + 5.0, seed, policy_dir, "sfm")
    amp = env.amp
    start, hd = amp.planar()[:2]
    turn = float(hd[0]) - heading0
    rot = np.array([[np.cos(turn), -np.sin(turn)], [np.sin(turn), np.cos(turn)]])
    amp.plan_all = lambda who=None: None  # the recorded updates are the only targets
    t0 = int(amp.t)
    k = 0
    fell_at = None
    walked = 0.0
    pos = start[0]
    while env.sim_time < up_s - 1e-9 and not env._needs_reset:
        while k < len(updates) and updates[k][0] <= int(amp.t) - t0:  # the updates come in step order
            step, plan_t, k_prog, rel = updates[k][:4]
            amp.paths[0] = pos + rel @ rot.T
            amp.plan_t[0] = t0 + plan_t
            amp.k_prog[0] = k_prog
            k += 1
        wrapped.step({})
        if amp.fallen[0]:
            fell_at = round(float(env.sim_time), 2)
            break
        now = env.pos[env.n_robots].copy()
        walked += float(np.linalg.norm(now - pos))
        pos = now
    wrapped.close()
    return {"replay_fell": fell_at is not None, "replay_fell_at_s": fell_at, "replay_walked_m": round(walked, 2)}


def save_targets(path: str, recordings: list[dict]) -> int:
    """Write the target updates of every person of ``recordings`` (:func:`record`'s) to ``path`` (an .npz of plain
    arrays, :func:`navzoo.agents.amp.path_env.load_recorded_targets`); returns the number of people."""
    from navzoo.agents.amp.path_env import pack_recorded_paths

    people = [(rec["updates"][j], int(round(rec["up_s"][j] / rec["dt"]))) for rec in recordings
              for j in range(len(rec["updates"])) if rec["updates"][j]]
    ups = [u for upd, _ in people for u in upd]
    np.savez_compressed(
        path, person_start=np.cumsum([0] + [len(upd) for upd, _ in people]).astype(np.int64),
        up_steps=np.array([n for _, n in people], dtype=np.int64),
        step=np.array([u[0] for u in ups], dtype=np.int64), plan_t=np.array([u[1] for u in ups], dtype=np.int64),
        heading=np.array([u[4] for u in ups], dtype=np.float32), dt=np.float64(recordings[0]["dt"]),
        **pack_recorded_paths(np.stack([u[3] for u in ups])))
    return len(people)


def run_scene(scene: str, n: int, seed: int, seconds: float, policy_dir: str | None,
              replay_dir: str | None = None, recordings: list | None = None, do_replay: bool = True) -> list[dict]:
    """Record ``scene`` with ``policy_dir`` and replay each person to a lone body of ``replay_dir`` (default the same);
    the recording is appended to ``recordings`` when given; ``do_replay=False`` records only (rows without replays)."""
    rec = record(scene, n, seed, seconds, policy_dir)
    if recordings is not None:
        recordings.append(rec)
    if not do_replay:
        return []
    lone = policy_dir if replay_dir is None else replay_dir
    rows = []
    for j in range(n):
        r = replay(rec["updates"][j], float(rec["heading0"][j]), float(rec["up_s"][j]), seed, lone)
        rows.append({"scene": scene, "pedestrians": n, "seed": seed, "policy": policy_dir, "replay_policy": lone,
                     "person": j,
                     "up_s": round(float(rec["up_s"][j]), 2), "updates": len(rec["updates"][j]),
                     "crowd_fell": rec["fell"][j], "crowd_cause": rec["cause"][j],
                     "crowd_walked_m": round(float(rec["walked_m"][j]), 2), **r})
    return rows


def summary(rows: list[dict]) -> dict:
    """Falls per person-minute: in the crowd (all, and with cause ``none``) and in the lone replays."""
    minutes = sum(r["up_s"] for r in rows) / 60.0
    replay_min = sum((r["replay_fell_at_s"] if r["replay_fell"] else r["up_s"]) for r in rows) / 60.0
    crowd = sum(r["crowd_fell"] for r in rows)
    untouched = sum(r["crowd_cause"] == "none" for r in rows)
    lone = sum(r["replay_fell"] for r in rows)
    rate = lambda k, m: round(k / m, 3) if m > 0 else None  # noqa: E731
    return {"people": len(rows), "person_minutes": round(minutes, 1), "crowd_falls": crowd,
            "crowd_untouched_falls": untouched, "replay_falls": lone,
            "crowd_per_minute": rate(crowd, minutes), "crowd_untouched_per_minute": rate(untouched, minutes),
            "replay_per_minute": rate(lone, replay_min),
            "walked_m_crowd": round(sum(r["crowd_walked_m"] for r in rows), 1),
            "walked_m_replay": round(sum(r["replay_walked_m"] for r in rows), 1)}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", action="append", required=True, metavar="SCENE:N",
                    help="a library scene and its people count (repeat for several)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--seconds", type=float, default=200.0)
    ap.add_argument("--policy", default=None, help="exported AMP policy folder (default: the shipped one)")
    ap.add_argument("--replay-policy", default=None, help="policy of the lone bodies (default: --policy)")
    ap.add_argument("--json", default=None, help="also write one row per person here")
    ap.add_argument("--save-targets", default=None, metavar="F.npz",
                    help="also write every person's recorded target updates here (navzoo train amp --recorded-targets)")
    ap.add_argument("--no-replay", action="store_true", help="record only (with --save-targets)")
    a = ap.parse_args(argv)
    scenes = []
    for text in a.scene:
        name, _, count = text.partition(":")
        try:
            n = int(count)
        except ValueError:
            ap.error(f"--scene {text!r}: expected SCENE:N with N a whole number of people")
        if n < 1:
            ap.error(f"--scene {text!r}: N must be at least 1")
        scenes.append((name, n))
    if a.seconds <= 0:
        ap.error("--seconds must be positive")
    for flag, value in (("--policy", a.policy), ("--replay-policy", a.replay_policy)):
        if value is not None and not Path(value).is_dir():
            ap.error(f"{flag} {value}: not a folder")
    from navzoo.torch_threads import one_torch_thread

    if a.no_replay and not a.save_targets:
        ap.error("--no-replay records only: give --save-targets F.npz")
    rows: list[dict] = []
    recordings: list[dict] = []
    with one_torch_thread():
        for name, n in scenes:
            try:
                got = run_scene(name, n, a.seed, a.seconds, a.policy, a.replay_policy, recordings, not a.no_replay)
            except (KeyError, ValueError) as e:
                ap.error(f"--scene {name}: {e}")
            if got:
                print(f"{name} ({n} people, seed {a.seed}): {json.dumps(summary(got))}", flush=True)
            else:
                rec = recordings[-1]
                print(f"{name} ({n} people, seed {a.seed}): recorded {sum(map(len, rec['updates']))} target updates, "
                      f"{sum(rec['fell'])} of {n} people fell", flush=True)
            rows += got
    if a.save_targets:
        Path(a.save_targets).parent.mkdir(parents=True, exist_ok=True)
        people = save_targets(a.save_targets, recordings)
        print(f"saved the target updates of {people} people to {a.save_targets}")
    if not rows:
        return 0
    total = summary(rows)
    print(f"all: {json.dumps(total)}")
    if a.json:
        from navzoo.machine import cpu_model, package_versions

        Path(a.json).parent.mkdir(parents=True, exist_ok=True)
        Path(a.json).write_text(json.dumps({"cpu": cpu_model(), "packages": package_versions(), "summary": total,
                                            "rows": rows}, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
