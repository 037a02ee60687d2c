"""``PerceptionWrapper``: robots observe people through cameras, Monoloco and tracking, not ground truth.

The wrapper runs :class:`~navzoo.perception.pipeline.RobotPerception` after every ``reset`` and ``step``
and rewrites the people part of each robot's observation -- ``agents`` (K, T, 7) and ``agents_mask``
(K, T) -- from the robot's confirmed tracks, in exactly the ground-truth format (same keys, shapes,
frames and bounds; flat observations stay flat), so a policy switches without any change:

* a track's history over the last T steps is its filtered position and velocity at each step it
  existed (earlier steps masked), its orientation the filtered body orientation (the velocity
  heading before any orientation was observed), its radius the env's pedestrian radius;
* other robots stay ground truth (robots share their state over the network);
* the K nearest within ``sensor_range`` are kept, nearest first, as in the env.

Classical baselines do not read observations but the env's state; the wrapper therefore also
publishes each robot's perceived people as ``env.unwrapped.perceived_people[robot_index] =
(positions (M, 2), velocities (M, 2), radii (M,))``, which the baselines of
:mod:`navzoo.agents.baselines` use instead of the true people when it is set. ``info[robot]`` gains
``perception/detections`` and ``perception/tracks``; with ``images=True`` also
``perception/images``: each camera's :class:`~navzoo.sensors.render.CameraImages` at full resolution;
with ``lidar=Lidar2D(...)`` also ``perception/lidar``, a :class:`~navzoo.sensors.LidarScan`.
"""

from __future__ import annotations

from collections import deque
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from navzoo.envs import observations as obs_terms
from navzoo.envs.wrappers import _NavWrapper
from navzoo.perception.pipeline import PerceptionFrame, RobotPerception

__all__ = ["PerceptionWrapper"]


class PerceptionWrapper(_NavWrapper):
    """Replace the robots' ground-truth observations of people by perceived ones.

    Args:
        env: A navzoo parallel env (``navzoo.make(...)``, raw or with frozen pedestrians).
        perception: The perception pipeline (default :class:`RobotPerception` with the shipped network).
        images: Also render each robot's camera images into ``info[robot]["perception/images"]``.
        publish_to_env: Set ``env.unwrapped.perceived_people`` for the privileged baselines.
        lidar: Also scan a 2D lidar (:class:`navzoo.sensors.Lidar2D`, e.g. ``Lidar2D()``) into
            ``info[robot]["perception/lidar"]`` (a :class:`navzoo.sensors.LidarScan`).
    """

    def __init__(self, env: ParallelEnv, perception: RobotPerception | None = None, images: bool = False,
                 publish_to_env: bool = True, lidar: Any = None) -> None:
        super().__init__(env)
        if lidar is not None:
            from navzoo.sensors.lidar import Lidar2D

            if not isinstance(lidar, Lidar2D):
                raise TypeError(f"lidar must be a navzoo.sensors.Lidar2D or None, got {type(lidar).__name__}")
        self.lidar = lidar
        self.perception = perception if perception is not None else RobotPerception()
        self.images = bool(images)
        self.publish_to_env = bool(publish_to_env)
        self.possible_agents = list(env.possible_agents)
        nav = self.unwrapped
        self._T = int(nav.config.history)
        self._history: dict[int, deque] = {}
        self.last_frames: dict[int, PerceptionFrame] = {}

    @property
    def agents(self) -> list[str]:
        return self.env.agents

    def state(self):
        return self.env.state()

    # ------------------------------------------------------------------ API
    def reset(self, seed: int | None = None, options: dict | None = None):
        obs, infos = self.env.reset(seed=seed, options=options)
        nav = self.unwrapped
        self.perception.reset(nav, seed=seed)
        self._history = {i: deque(maxlen=self._T) for i in range(nav.n_robots)}
        nav.perceived_people = {}
        return self._perceive(obs, infos)

    def step(self, actions: dict[str, Any]):
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        obs, infos = self._perceive(obs, infos)
        return obs, rewards, terms, truncs, infos

    # ------------------------------------------------------------------ internals
    def _perceive(self, obs: dict[str, Any], infos: dict[str, Any]):
        nav = self.unwrapped
        robots = [a for a in obs if nav._index.get(a, nav.n_robots) < nav.n_robots]
        idx = [nav._index[a] for a in robots if nav.alive[nav._index[a]]]
        frames = self.perception.step(nav, idx) if idx else {}
        self.last_frames = frames
        human_r = float(np.median(nav.radius[nav.n_robots:])) if nav.n_humans else 0.3
        for i, f in frames.items():
            snap = {t.id: (np.asarray(t.position, float), np.asarray(t.velocity, float), _heading(t)) for t in f.tracks}
            self._history[i].append(snap)
            if self.publish_to_env:
                tr = f.tracks
                nav.perceived_people[i] = (np.array([t.position for t in tr], float).reshape(-1, 2),
                                           np.array([t.velocity for t in tr], float).reshape(-1, 2),
                                           np.full(len(tr), human_r))
        for a in robots:
            i = nav._index[a]
            if i not in frames:
                continue
            o = obs[a]
            flat = not isinstance(o, dict)
            d = spaces.unflatten(nav._dict_space, o) if flat else dict(o)
            feats, mask = self._features(i, human_r)
            d["agents"], d["agents_mask"] = feats, mask
            obs[a] = spaces.flatten(nav._dict_space, d).astype(np.float32) if flat else d
            info = infos.setdefault(a, {})
            info["perception/detections"] = int(len(frames[i].position))
            info["perception/tracks"] = [(t.id, *map(float, t.position)) for t in frames[i].tracks]
            if self.images:
                from navzoo.sensors.render import render_robot_cameras

                info["perception/images"] = render_robot_cameras(nav, i, self.perception.cameras)
            if self.lidar is not None:
                from navzoo.sensors.lidar import render_robot_lidar

                info["perception/lidar"] = render_robot_lidar(nav, i, self.lidar)
        return obs, infos

    def _features(self, i: int, human_r: float) -> tuple[np.ndarray, np.ndarray]:
        """(K, T, 7) features and (K, T) mask of robot i from its track history and the other robots."""
        nav = self.unwrapped
        cfg = nav.config
        T = self._T
        hist = list(self._history[i])
        steps = len(hist)
        ids = sorted({k for snap in hist for k in snap})
        R = nav.n_robots
        others = [j for j in range(R) if j != i]
        M = 1 + len(others) + len(ids)
        pos = np.zeros((T, M, 2))
        vel = np.zeros((T, M, 2))
        yaw = np.zeros((T, M))
        present = np.zeros((T, M), dtype=bool)
        valid = np.zeros(T, dtype=bool)
        valid[T - steps:] = True
        # Observer and other robots: the env's own history (ground truth).
        rob = [i] + others
        pos[:, :len(rob)] = nav.hist_pos[:, rob]
        vel[:, :len(rob)] = nav.hist_vel[:, rob]
        yaw[:, :len(rob)] = nav.hist_yaw[:, rob]
        present[:, :len(rob)] = True
        for s, snap in enumerate(hist):
            t = T - steps + s
            for k, tid in enumerate(ids):
                if tid in snap:
                    p_, v_, h_ = snap[tid]
                    col = len(rob) + k
                    pos[t, col], vel[t, col], yaw[t, col] = p_, v_, h_
                    present[t, col] = True
        radius = np.concatenate([nav.radius[rob], np.full(len(ids), human_r)])
        visible = present[-1].copy()
        visible[1:len(rob)] = nav.alive[others] if others else visible[1:len(rob)]
        feats, mask = obs_terms.neighbor_features(pos, vel, yaw, valid & nav.hist_valid, radius, visible,
                                                  np.array([0]), cfg.k_neighbors, cfg.sensor_range,
                                                  hist_present=present)
        return feats[0], mask[0]


def _heading(track) -> float:
    if track.orientation is not None and np.isfinite(track.orientation):
        return float(track.orientation)
    v = np.asarray(track.velocity, float)
    return float(np.arctan2(v[1], v[0])) if np.linalg.norm(v) > 1e-3 else 0.0
