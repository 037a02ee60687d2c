"""The main job: one episode of a baseline robot among a crowd, with video, plot and metrics."""

from __future__ import annotations

import json
import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from navzoo.agents.baselines import make_policy
from navzoo.benchmark.metrics import episode_summary
from navzoo.envs.registry import SCENARIOS, make

DEFAULT_SCENE = "lobby"


def scene_to_env_id(scene: str) -> str | None:
    for env_id, cfg in SCENARIOS.items():
        if cfg["scene"] == scene:
            return env_id
    return None


def run_demo(
    scene: str = DEFAULT_SCENE,
    out: str | Path = "runs/demo",
    seed: int = 0,
    policy: str = "orca",
    n_humans: int | None = None,
    video: bool = True,
    camera: bool = True,
    progress: bool = True,
) -> dict[str, Any]:
    """Run one episode and write ``video.mp4``, ``trajectories.png``, ``metrics.json``, ``episode.npz``.

    Returns the metrics dict (also written to ``metrics.json``) with the output paths under ``files``.
    """
    robot = make_policy(policy)  # raises naming the valid baselines
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    env_id = scene_to_env_id(scene)
    overrides: dict[str, Any] = {} if env_id else {"scene": scene}
    if n_humans is not None:
        overrides["n_humans"] = n_humans
    env = make(env_id, render_mode="rgb_array", render_view="both" if camera else "topdown", **overrides)
    nav = env.unwrapped
    obs, _ = env.reset(seed=seed)
    robot.reset(nav)
    R = nav.n_robots
    robot_pos, human_pos = [nav.pos[:R].copy()], [nav.pos[R:].copy()]
    frames_written = 0
    writer = None
    video_path = out / "video.mp4"
    t_start = time.perf_counter()
    events: dict[str, str] = {}
    bar = None
    if progress:
        from tqdm import tqdm

        bar = tqdm(total=nav.max_steps, desc=f"demo {nav.scene.name}", unit="step", leave=False)
    while env.agents:
        if video:
            frame = env.render()
            if writer is None:
                h, w = frame.shape[:2]
                writer = cv2.VideoWriter(str(video_path), cv2.VideoWriter_fourcc(*"mp4v"), int(round(1 / nav.config.dt)), (w, h))
            writer.write(cv2.cvtColor(frame, cv2.COLOR_RGB2BGR))
            frames_written += 1
        actions = robot.act(obs, nav)
        obs, rewards, terms, truncs, infos = env.step(actions)
        for a, info in infos.items():
            if terms[a] or truncs[a]:
                events[a] = info["event"]
        robot_pos.append(nav.pos[:R].copy())
        human_pos.append(nav.pos[R:].copy())
        if bar is not None:
            bar.update(1)
    if bar is not None:
        bar.close()
    if writer is not None:
        writer.write(cv2.cvtColor(env.render(), cv2.COLOR_RGB2BGR))
        writer.release()
    wall = time.perf_counter() - t_start
    rp, hp = np.array(robot_pos), np.array(human_pos)
    per_robot = []
    for i in range(R):
        agent = nav.possible_agents[i]
        per_robot.append({
            "agent": agent,
            **episode_summary(rp[:, i], hp, nav.config.robot.radius, nav.radius[R:], nav.config.dt,
                              events.get(agent, "timeout"), float(nav.shortest_path_length[i]), nav.time_limit),
        })
    np.savez_compressed(out / "episode.npz", robot_pos=rp, human_pos=hp, dt=nav.config.dt,
                        robot_radius=nav.config.robot.radius, human_radius=nav.radius[R:],
                        goals=nav.goal[:R], scene=nav.scene.name)
    _plot(nav, rp, hp, out / "trajectories.png", per_robot)
    metrics = {
        "scene": nav.scene.name,
        "env_id": env_id,
        "robot_policy": policy,
        "crowd_model": nav.config.crowd_model,
        "n_humans": nav.n_humans,
        "seed": seed,
        "dt": nav.config.dt,
        "wall_time_s": wall,
        "sim_time_s": nav.sim_time,
        "robots": per_robot,
        "files": {
            "video": str(video_path) if video else None,
            "trajectory_plot": str(out / "trajectories.png"),
            "metrics": str(out / "metrics.json"),
            "episode": str(out / "episode.npz"),
        },
    }
    (out / "metrics.json").write_text(json.dumps(metrics, indent=2))
    env.close()
    return metrics


def _plot(nav, rp: np.ndarray, hp: np.ndarray, path: Path, per_robot: list[dict]) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from navzoo.world.plot import plot_scene

    xmin, ymin, xmax, ymax = nav.scene.bounds
    w, h = xmax - xmin, ymax - ymin
    fig, ax = plt.subplots(figsize=(8, max(3.0, 8 * h / w)))
    plot_scene(nav.scene, ax=ax, show_regions=True)
    cmap = plt.get_cmap("Oranges")
    for j in range(hp.shape[1]):
        ax.plot(hp[:, j, 0], hp[:, j, 1], color=cmap(0.4 + 0.5 * j / max(1, hp.shape[1])), lw=0.8, alpha=0.7)
        ax.plot(hp[-1, j, 0], hp[-1, j, 1], "o", color="tab:orange", ms=3)
    for i, r in enumerate(per_robot):
        ax.plot(rp[:, i, 0], rp[:, i, 1], color="tab:blue", lw=2.0, label=f"{r['agent']} ({r['event']})")
        ax.plot(*rp[0, i], "s", color="tab:blue")
        ax.plot(*nav.goal[i], "*", color="tab:green", ms=14)
        ax.add_patch(plt.Circle(rp[-1, i], nav.config.robot.radius, color="tab:blue", alpha=0.5))
    ax.set_title(f"{nav.scene.name}: {per_robot[0]['event']} in {nav.sim_time:.1f} s, "
                 f"min gap {per_robot[0]['min_person_distance_m']:.2f} m")
    ax.legend(loc="upper right", fontsize=8)
    ax.set_aspect("equal")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
