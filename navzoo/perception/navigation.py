"""Navigation with perceived instead of ground-truth people: the same robots, the same episodes.

For each method, scene and episode seed the episode is run twice: once with the env's ground truth,
once behind a :class:`~navzoo.perception.wrapper.PerceptionWrapper` (the robot avoids the people it
tracks; collisions, success and distances are always judged on the true people). Reported per method
and mode: success, collision and timeout rates, mean of each episode's minimum distance (edge to edge)
to a person, and mean time to goal of the successful episodes.
"""

from __future__ import annotations

from typing import Any

import numpy as np

__all__ = ["compare", "run_episode"]


def run_episode(method: str, scene: str, seed: int, perceived: bool, crowd_model: str = "orca",
                model_dir: str | None = None) -> dict[str, Any]:
    """One episode; returns ``event``, ``min_distance_m``, ``time_s``.

    ``scene`` is a library scene (with ``crowd_model`` people) or a registered env id such as
    ``navzoo/CircleCrossing-v0`` (its preset, crowd included). A method's ``-diffdrive`` /
    ``-holonomic`` suffix sets the robot's kinematics, as in the benchmark.
    """
    import navzoo
    from navzoo.agents.baselines import make_policy
    from navzoo.benchmark.runner import method_kinematics

    kin = method_kinematics(method)
    robot = {"robot": {"kinematics": kin}} if kin else {}
    if scene.startswith("navzoo/"):
        env = navzoo.make(scene, n_robots=1, **robot)
    else:
        env = navzoo.make(None, scene=scene, n_robots=1, crowd_model=crowd_model, **robot)
    if perceived:
        from navzoo.perception.monoloco import load_estimator
        from navzoo.perception.pipeline import RobotPerception
        from navzoo.perception.wrapper import PerceptionWrapper

        env = PerceptionWrapper(env, RobotPerception(estimator=load_estimator(model_dir), seed=seed))
    nav = env.unwrapped
    policy = make_policy(method)
    try:
        obs, _ = env.reset(seed=seed)
        policy.reset(nav)
        R = nav.n_robots
        min_d = np.inf
        event = "timeout"
        while env.agents:
            obs, _, terms, truncs, infos = env.step(policy.act(obs, nav))
            if nav.n_humans:
                here = nav.present[R:] & nav.alive[R:]
                if here.any():
                    d = np.linalg.norm(nav.pos[R:][here] - nav.pos[0], axis=1) - nav.radius[R:][here] - nav.radius[0]
                    min_d = min(min_d, float(d.min()))
            if terms.get("robot_0") or truncs.get("robot_0"):
                event = infos["robot_0"].get("event", "timeout")
        return {"method": method, "scene": scene, "seed": seed, "perceived": perceived, "event": event,
                "min_distance_m": float(min_d), "time_s": float(nav.sim_time)}
    finally:
        env.close()


def compare(methods: tuple[str, ...], scenes: tuple[str, ...], episodes: int, seed: int = 0, workers: int = 1,
            **kw: Any) -> dict[str, Any]:
    """Run every (method, scene, episode) with ground truth and with perception; summarise per method."""
    from navzoo.benchmark.pedestrians import _pool_map

    jobs = [(m, s, seed + 1000 * k + e, perceived)
            for m in methods for k, s in enumerate(scenes) for e in range(episodes) for perceived in (False, True)]
    if kw:
        rows = [run_episode(*j, **kw) for j in jobs]
    else:
        rows = _pool_map(run_episode, jobs, workers)
    out: dict[str, Any] = {}
    for m in methods:
        for perceived in (False, True):
            r = [x for x in rows if x["method"] == m and x["perceived"] == perceived]
            ev = [x["event"] for x in r]
            ok = [x["time_s"] for x in r if x["event"] == "goal"]
            out.setdefault(m, {})["perceived" if perceived else "ground_truth"] = {
                "episodes": len(r),
                "success": float(np.mean([e == "goal" for e in ev])),
                "collision": float(np.mean([e.startswith("collision") for e in ev])),
                "timeout": float(np.mean([e == "timeout" for e in ev])),
                "min_distance_m": float(np.mean([x["min_distance_m"] for x in r if np.isfinite(x["min_distance_m"])])),
                "time_to_goal_s": float(np.mean(ok)) if ok else None,
            }
    return {"methods": out, "scenes": list(scenes), "episodes_per_scene": episodes, "episodes": rows}
