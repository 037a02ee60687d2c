"""How the social-force wall potential holds people back: one person alone, or a crowd, per wall setting.

    python scripts/sfm_lone_wall.py --scene cluttered_room --seeds 0,1,2,3 --walls 1.0:0.1,0.3:0.1,1.0:0.05 [--json]
    python scripts/sfm_lone_wall.py --crowd --scenes protocol,heldout --seeds 0 --walls 1.0:0.1,0.3:0.1 [--workers 2]
    python scripts/sfm_lone_wall.py --crowd --walls 1.0:0.1,1.0:0.1:1.5:0.3     # softer walls only where people meet
    python scripts/sfm_lone_wall.py --markdown RESULT.json          # the table of a --crowd --json result

Lone (default): ``NavEnv(scene, n_robots=0, n_humans=1, crowd_model="sfm")`` for ``--seconds`` (default 200) per
seed, the person frozen on :class:`navzoo.agents.crowd.CrowdPolicy` ("sfm") with the wall potential
``A_wall:B_wall`` of :class:`navzoo.agents.sfm.SocialForceParams` (the default is 1.0:0.1); prints the goals the
person reached per seed. No crowd, no robot: a person who reaches no goal is held by the walls and the path alone.
A wall setting ``A_wall:B_wall:NEAR:A_NEAR`` also sets ``wall_near_range`` = NEAR (m) and ``A_wall_near`` = A_NEAR:
a person with another person within NEAR feels the walls with A_NEAR instead (softer walls only where people meet).

``--crowd``: the same with the following protocol's people (3-15 per scene, ``protocol`` = its 8 scenes,
``heldout`` = the 10 held-out scenes, or ``SCENE:N``), kinematic bodies; per scene and wall setting the goals
reached, the people's mean speed and the share of person-steps whose body edge is within 5 cm of an obstacle
(``Scene.clearance`` of the centre minus the radius; the scene's outer bounds are not counted).
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

NEAR_WALL_M = 0.05


def run_sfm(scene: str, n: int, seed: int, seconds: float, a_wall: float, b_wall: float,
            near_range: float = 0.0, a_wall_near: float = 1.0) -> dict:
    """``n`` social-force people in ``scene`` for ``seconds`` with wall potential (a_wall, b_wall) (and a_wall_near
    for people within near_range of another, if near_range > 0): goals reached, mean speed (m/s) and the share of
    person-steps with the body edge within :data:`NEAR_WALL_M` of an obstacle."""
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.agents.sfm import SocialForceParams
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    env = NavEnv(scene=scene, n_robots=0, n_humans=n, crowd_model="sfm", time_limit=seconds)
    near = {"wall_near_range": near_range, "A_wall_near": a_wall_near} if near_range > 0 else {}
    policy = CrowdPolicy("sfm", sfm_params=SocialForceParams(A_wall=a_wall, B_wall=b_wall, **near))
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
    speeds, positions = [], []
    try:
        wrapped.reset(seed=seed)
        radius = env.radius[env.n_robots:]
        while not env._needs_reset:
            wrapped.step({})
            positions.append(env.pos[env.n_robots:].copy())
            speeds.append(np.linalg.norm(env.vel[env.n_robots:], axis=1))
        pos = np.asarray(positions)  # (T, n, 2): the clearance of every person-step in one call
        edge = env.scene.clearance(pos.reshape(-1, 2)).reshape(pos.shape[:2]) - radius
        return {"scene": scene, "people": n, "seed": seed, "A_wall": a_wall, "B_wall": b_wall, **near,
                "goals": int(env.goals_reached.sum()), "mean_speed": round(float(np.mean(speeds)), 3),
                "near_wall_share": round(float(np.mean(edge < NEAR_WALL_M)), 4)}
    finally:
        wrapped.close()


def lone_goals(scene: str, seed: int, seconds: float, a_wall: float, b_wall: float) -> int:
    """Goals one social-force person reaches in ``scene`` in ``seconds`` with wall potential (a_wall, b_wall)."""
    return run_sfm(scene, 1, seed, seconds, a_wall, b_wall)["goals"]


def parse_walls(text: str) -> list[tuple[float, ...]]:
    """``A_WALL:B_WALL[:NEAR:A_NEAR],...`` as tuples of 2 or 4 numbers, all > 0."""
    out = []
    for item in (x.strip() for x in text.split(",") if x.strip()):
        parts = item.split(":")
        try:
            values = tuple(float(v) for v in parts)
        except ValueError:
            raise ValueError(f"--walls: each item is A_WALL:B_WALL[:NEAR:A_NEAR] (numbers), got {item!r}") from None
        if len(values) not in (2, 4) or not all(v > 0 and np.isfinite(v) for v in values):
            raise ValueError(f"--walls: each item is A_WALL:B_WALL[:NEAR:A_NEAR], all > 0, got {item!r}")
        out.append(values)
    if not out:
        raise ValueError("--walls: give at least one A_WALL:B_WALL")
    return out


def wall_key(row_or_walls) -> tuple[float, ...]:
    """The wall setting of a run row (its A_wall, B_wall and, if set, wall_near_range and A_wall_near) or of a
    ``walls`` item, as a tuple comparable with :func:`parse_walls`' items."""
    if isinstance(row_or_walls, dict):
        r = row_or_walls
        near = (r["wall_near_range"], r["A_wall_near"]) if r.get("wall_near_range") else ()
        return (r["A_wall"], r["B_wall"], *near)
    return tuple(row_or_walls)


def wall_label(walls: tuple[float, ...]) -> str:
    label = f"A_wall {walls[0]:g}, B_wall {walls[1]:g}"
    return label + (f", {walls[3]:g} within {walls[2]:g} m of another" if len(walls) == 4 else "")


def crowd_scenes(text: str) -> dict[str, int]:
    """Scene -> people of ``--scenes`` for ``--crowd``: ``protocol``, ``heldout``, ``SCENE:N`` or a protocol scene."""
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    from amp_target_ablation import parse_scenes

    out: dict[str, int] = {}
    for item in (x.strip() for x in text.split(",") if x.strip()):
        out.update(parse_scenes(None) if item == "protocol" else parse_scenes(item))
    return out


def _job(args: tuple) -> dict:
    return run_sfm(*args)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="cluttered_room", help="the lone person's scene")
    parser.add_argument("--crowd", action="store_true", help="crowds of the following protocol's size in --scenes")
    parser.add_argument("--scenes", default="protocol,heldout", help="with --crowd: protocol, heldout, SCENE:N, ...")
    parser.add_argument("--seeds", default="0,1,2,3")
    parser.add_argument("--seconds", type=float, default=200.0)
    parser.add_argument("--walls", default="1.0:0.1,0.3:0.1,1.0:0.05", help="A_WALL:B_WALL[:NEAR:A_NEAR],... (default 1.0:0.1 first; NEAR settings only with --crowd)")
    parser.add_argument("--workers", type=int, default=1, help="processes for --crowd runs")
    parser.add_argument("--json", action="store_true")
    parser.add_argument("--markdown", default=None, metavar="RESULT_JSON", help="print the table of a --crowd --json "
                        "result and exit")
    args = parser.parse_args(argv)
    if args.markdown:
        print(markdown(json.loads(Path(args.markdown).read_text())))
        return 0
    from navzoo.world.library import get_scene

    try:
        walls = parse_walls(args.walls)
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
        scenes = crowd_scenes(args.scenes) if args.crowd else {args.scene: 1}
        if not args.crowd and any(len(w) == 4 for w in walls):
            raise ValueError("--walls: A_WALL:B_WALL:NEAR:A_NEAR softens walls near other people: use it with --crowd")
        for name in scenes:
            get_scene(name)
    except ValueError as exc:
        parser.error(str(exc))
    if not args.crowd:
        rows = [{"A_wall": w[0], "B_wall": w[1], "goals": [lone_goals(args.scene, s, args.seconds, w[0], w[1])
                                                            for s in seeds]} for w in walls]
        result = {"scene": args.scene, "seeds": seeds, "seconds": args.seconds, "rows": rows}
        if args.json:
            print(json.dumps(result))
        else:
            print(f"one social-force person in {args.scene}, {args.seconds:g} s, seeds {seeds}")
            for r in rows:
                print(f"  A_wall {r['A_wall']:g}, B_wall {r['B_wall']:g}: goals per seed {r['goals']}")
        return 0
    jobs = [(sc, n, s, args.seconds, *w) for sc, n in scenes.items() for s in seeds for w in walls]
    if args.workers > 1:
        from multiprocessing import get_context

        with get_context("spawn").Pool(args.workers) as pool:
            runs = pool.map(_job, jobs)
    else:
        runs = [_job(j) for j in jobs]
    result = {"scenes": scenes, "seeds": seeds, "seconds": args.seconds, "walls": walls, "runs": runs}
    print(json.dumps(result) if args.json else markdown(result))
    return 0


def markdown(result: dict) -> str:
    """The table of a ``--crowd`` result: per scene and wall setting, goals summed over the seeds / mean speed /
    share of person-steps near a wall (means over the seeds)."""
    walls = [wall_key(w) for w in result["walls"]]
    lines = [f"social-force crowds, {result['seconds']:g} s, seeds {result['seeds']}: goals / mean speed (m/s) / "
             "share near a wall",
             "| scene (people) | " + " | ".join(wall_label(w) for w in walls) + " |",
             "|---|" + "---|" * len(walls)]
    totals = {w: 0 for w in walls}
    for sc, n in result["scenes"].items():
        cells = []
        for w in walls:
            rs = [r for r in result["runs"] if r["scene"] == sc and wall_key(r) == w]
            totals[w] += sum(r["goals"] for r in rs)
            cells.append(f"{sum(r['goals'] for r in rs)} / {np.mean([r['mean_speed'] for r in rs]):.2f} / "
                         f"{np.mean([r['near_wall_share'] for r in rs]):.3f}")
        lines.append(f"| {sc} ({n}) | " + " | ".join(cells) + " |")
    lines.append("| all goals | " + " | ".join(str(totals[w]) for w in walls) + " |")
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
