"""Does one social-force person cross a scene alone, and how does that depend on the wall potential?

    python scripts/sfm_lone_wall.py --scene cluttered_room --seeds 0,1,2,3 --walls 1.0:0.1,0.3:0.1,1.0:0.05 [--json]

Runs ``NavEnv(scene, n_robots=0, n_humans=1, crowd_model="sfm")`` for ``--seconds`` (default 200) per seed with the
person frozen on :class:`navzoo.agents.crowd.CrowdPolicy` ("sfm") and the wall potential ``A_wall:B_wall`` of
:class:`navzoo.agents.sfm.SocialForceParams` (the default is 1.0:0.1), and prints the goals the person reached per
seed. No crowd, no robot: a person who reaches no goal is held by the walls and the path alone.
"""

from __future__ import annotations

import argparse
import json


def lone_goals(scene: str, seed: int, seconds: float, a_wall: float, b_wall: float) -> int:
    """Goals one social-force person reaches in ``scene`` in ``seconds`` with wall potential (a_wall, b_wall)."""
    from navzoo.agents.crowd import CrowdPolicy
    from navzoo.agents.sfm import SocialForceParams
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.wrappers import FrozenAgents

    env = NavEnv(scene=scene, n_robots=0, n_humans=1, crowd_model="sfm", time_limit=seconds)
    policy = CrowdPolicy("sfm", sfm_params=SocialForceParams(A_wall=a_wall, B_wall=b_wall))
    wrapped = FrozenAgents(env, lambda a: a.startswith("human_"), policy)
    try:
        wrapped.reset(seed=seed)
        while not env._needs_reset:
            wrapped.step({})
        return int(env.goals_reached.sum())
    finally:
        wrapped.close()


def parse_walls(text: str) -> list[tuple[float, float]]:
    out = []
    for item in (x.strip() for x in text.split(",") if x.strip()):
        a, sep, b = item.partition(":")
        try:
            pair = (float(a), float(b))
        except ValueError:
            raise ValueError(f"--walls: each item is A_WALL:B_WALL (numbers), got {item!r}") from None
        if not sep or min(pair) <= 0:
            raise ValueError(f"--walls: each item is A_WALL:B_WALL with both > 0, got {item!r}")
        out.append(pair)
    if not out:
        raise ValueError("--walls: give at least one A_WALL:B_WALL")
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="cluttered_room")
    parser.add_argument("--seeds", default="0,1,2,3")
    parser.add_argument("--seconds", type=float, default=200.0)
    parser.add_argument("--walls", default="1.0:0.1,0.3:0.1,1.0:0.05", help="A_WALL:B_WALL,... (default 1.0:0.1 first)")
    parser.add_argument("--json", action="store_true")
    args = parser.parse_args(argv)
    try:
        walls = parse_walls(args.walls)
        seeds = [int(s) for s in args.seeds.split(",") if s.strip()]
    except ValueError as exc:
        parser.error(str(exc))
    from navzoo.world.library import get_scene

    try:
        get_scene(args.scene)
    except ValueError as exc:
        parser.error(str(exc))
    rows = [{"A_wall": a, "B_wall": b, "goals": [lone_goals(args.scene, s, args.seconds, a, b) for s in seeds]}
            for a, b in walls]
    result = {"scene": args.scene, "seeds": seeds, "seconds": args.seconds, "rows": rows}
    if args.json:
        print(json.dumps(result))
    else:
        print(f"one social-force person in {args.scene}, {args.seconds:g} s, seeds {seeds}")
        for r in rows:
            print(f"  A_wall {r['A_wall']:g}, B_wall {r['B_wall']:g}: goals per seed {r['goals']}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
