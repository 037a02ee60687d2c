"""Trace the planning round fallen bodies in one following run (docs/crowd_log.md, "People walk into the pile").

Runs ``scripts/amp_target_ablation.py`` with ``--workers 0`` (its runs in this process, so the patched env is the one
that runs) and writes one JSON line per event to ``--trace``:

- ``stamp``: the fallen bodies were stamped into the pedestrians' planning grid (a new fall, or a body that moved):
  who lies (``lying``), who got a path round them (``replanned``), and who is left with a path through them and no way
  round (``no_way_round``, with their positions ``pos``);
- ``straight_line``: a pedestrian got a new goal to which no path leads on that grid, and walks a straight line;
- ``scene_path``: with ``NavConfig.human_fallen_redraw``, none of the goals drawn for a pedestrian is reached on that
  grid, and it walks the last one's path on the bare scene grid (``points``: its length).

The run's row goes to ``--out`` as usual; it repeats the row of the same run without the trace trip for trip.

    python scripts/trace_fallen_blocking.py --trace corridor_s3.events --crowd diffusion --scenes corridor --seeds 3 \\
        --seconds 200 --configs "kdtfr:0.1:0.1:4:2.0:human_door_turns+human_fallen_obstacles::::::::::$S" \\
        --out corridor_s3.jsonl
"""

from __future__ import annotations

import json
import runpy
import sys
from pathlib import Path

import numpy as np

import navzoo.envs.nav_env as ne


def _trace(out: Path) -> None:
    def log(event: dict) -> None:
        with out.open("a") as f:
            f.write(json.dumps(event) + "\n")

    avoid, plan = ne.NavEnv._avoid_fallen, ne.NavEnv._plan

    def traced_avoid(self):
        changed = avoid(self)
        R = self.n_robots
        stuck = [int(j) for j in np.flatnonzero(~self.human_fallen & ~self.arrived[R:] & ~changed)
                 if self._path_passes_fallen(R + j)]
        log({"t": round(self.sim_time, 2), "kind": "stamp", "lying": sorted(int(k) for k in self._fallen_stamped),
             "replanned": [int(j) for j in np.flatnonzero(changed)], "no_way_round": stuck,
             "pos": {j: [round(float(v), 2) for v in self.pos[R + j]] for j in stuck}})
        return changed

    def traced_plan(self, i, start, goal, fallback=True, scene_grid=False):
        path = plan(self, i, start, goal, fallback, scene_grid)
        if fallback and self._fallen_grid is not None and i >= self.n_robots:
            who = {"t": round(self.sim_time, 2), "who": int(i - self.n_robots)}
            if scene_grid:  # human_fallen_redraw: no goal drawn is reached round the bodies
                log({**who, "kind": "scene_path", "points": len(path)})
            elif len(path) == 1 and np.array_equal(path[0], np.asarray(goal, dtype=np.float64)):
                log({**who, "kind": "straight_line"})
        return path

    ne.NavEnv._avoid_fallen, ne.NavEnv._plan = traced_avoid, traced_plan


def main() -> int:
    argv = sys.argv[1:]
    if "--trace" not in argv or argv.index("--trace") + 1 >= len(argv):
        print("usage: trace_fallen_blocking.py --trace EVENTS.jsonl ARGS OF amp_target_ablation.py", file=sys.stderr)
        return 2
    k = argv.index("--trace")
    out = Path(argv[k + 1])
    del argv[k:k + 2]
    _trace(out)
    sys.argv = [str(Path(__file__).with_name("amp_target_ablation.py")), *argv, "--workers", "0"]
    runpy.run_path(sys.argv[0], run_name="__main__")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
