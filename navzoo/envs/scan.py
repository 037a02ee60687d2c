"""Running a robot policy that observes a range scan (``NavConfig.scan_rays``) in any env.

A policy trained with ``scan_rays = R`` needs the ``"scan"`` entry in its observations. The benchmark
and most envs do not produce it (the paper's observation has none), so :class:`ScanPolicy` casts the
scan itself from the env's state (:meth:`navzoo.envs.nav_env.NavEnv.range_scan`, the same geometry
as the env's own) and adds it to each robot's observation before the wrapped policy acts.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv

__all__ = ["ScanPolicy"]


class ScanPolicy:
    """Give a scan-observing policy its ``"scan"`` in any env.

    In an env whose own ``scan_rays`` and ``scan_range`` equal the policy's the observations pass
    through unchanged. Otherwise each controlled robot's observation is turned into the Dict form
    (flat ones split with the env's layout), and the scan is cast and added.

    Args:
        policy: the wrapped policy (``act(observations, env)``, ``reset(env)``, ``controlled(...)``).
        rays: the scan's rays the policy was trained with.
        scan_range: its range (m).
    """

    def __init__(self, policy: Any, rays: int, scan_range: float) -> None:
        if int(rays) < 1 or not scan_range > 0:
            raise ValueError(f"ScanPolicy needs rays >= 1 and scan_range > 0, got {rays!r} and {scan_range!r}")
        self.policy = policy
        self.rays = int(rays)
        self.scan_range = float(scan_range)
        self.name = getattr(policy, "name", "scan")

    @property
    def model(self) -> Any:
        """The wrapped policy's network."""
        return self.policy.model

    def controlled(self, observations: Mapping[str, Any], env: NavEnv | None = None) -> list[str]:
        return self.policy.controlled(observations, env)

    def reset(self, env: NavEnv) -> None:
        env = getattr(env, "unwrapped", env)  # a wrapper of navzoo.make: the NavEnv under it
        self.policy.reset(env)

    def _passthrough(self, env: NavEnv) -> bool:
        cfg = env.config
        return cfg.scan_rays == self.rays and abs(cfg.scan_range - self.scan_range) < 1e-9

    def act(self, observations: Mapping[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        env = getattr(env, "unwrapped", env)
        if self._passthrough(env):
            return self.policy.act(observations, env)
        from navzoo.agents.transformer import flat_layout

        names = self.policy.controlled(observations, env)
        if not names:
            return {}
        cfg = env.config
        layout = flat_layout(cfg.k_neighbors, cfg.history, cfg.map_cells, cfg.scan_rays)
        idx = np.array([env.agent_index(a) for a in names], dtype=int)
        scans = env.range_scan(idx, rays=self.rays, scan_range=self.scan_range)
        new = dict(observations)
        for n, a in enumerate(names):
            o = observations[a]
            if isinstance(o, Mapping):
                o = dict(o)
            else:
                flat = np.asarray(o, dtype=np.float32).reshape(-1)
                o = {key: flat[s:e].reshape(shape) for key, (s, e, shape) in layout.items()}
            o["scan"] = scans[n]
            new[a] = o
        return self.policy.act(new, env)
