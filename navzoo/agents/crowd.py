"""Rule-based crowd: drives the pedestrian agents with social force or ORCA along A* waypoints.

This is the policy that the frozen-agents wrapper owns for pedestrians by default. It reads the
world's state arrays from the env (positions, velocities, A* waypoints, walls), computes every
pedestrian's new velocity in one vectorised call, and returns it as the pedestrians' actions
(planar velocity in each person's own frame, normalised by ``human_max_speed``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Literal

import numpy as np

from navzoo.agents.orca import OrcaParams, orca_velocities
from navzoo.agents.sfm import SocialForceParams, social_force_velocities

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv


class CrowdPolicy:
    """Social-force or ORCA pedestrians following their A* waypoints.

    Args:
        model: ``"sfm"``, ``"orca"`` (navzoo's ORCA: keep-right bias and one-step safety, see
            docs/crowd_models.md) or ``"orca_rvo2"`` (the same solver with RVO2's exact
            semantics and CrowdNav's settings: maximum speed = preferred speed, discs 0.01 m larger
            inside ORCA, slowing down within 1 m of the goal, as CrowdNav's pedestrians) or
            ``"diffusion"`` (the env's :class:`navzoo.agents.diffusion.crowd.DiffusionCrowd` plans as
            preferred velocities, and social force, or ORCA with ``NavConfig.diffusion_walker="orca"`` (``"hybrid"``:
            ORCA, and social force for the people ORCA holds still), for the bodies in between) or ``"replay"`` (recorded
            ETH/UCY tracks, :mod:`navzoo.agents.replay`: the env moves the people itself and ignores
            their actions; this policy returns their recorded velocities as actions, for completeness).
        see_robots: whether people react to robots (False = CrowdNav's invisible robot).
        sfm_params / orca_params: model parameters. Without ``sfm_params`` (None) the social force takes the env's
            (``NavEnv.crowd_sfm_params``: the defaults, with the config's ``crowd_wall_*`` walls). Without
            ``orca_params`` ORCA takes its defaults, and the diffusion crowd's ORCA walker
            :data:`navzoo.agents.diffusion.crowd.ORCA_WALKER`.
    """

    def __init__(
        self,
        model: Literal["sfm", "orca", "orca_rvo2", "diffusion", "replay"] = "sfm",
        see_robots: bool = True,
        sfm_params: SocialForceParams | None = None,
        orca_params: OrcaParams | None = None,
    ) -> None:
        if model not in ("sfm", "orca", "orca_rvo2", "diffusion", "replay"):
            raise ValueError(f"crowd model must be 'sfm', 'orca', 'orca_rvo2', 'diffusion' or 'replay', got {model!r}")
        self.model = model
        self.see_robots = see_robots
        self.sfm_params = sfm_params
        self._orca_given = orca_params is not None
        if orca_params is None:
            orca_params = OrcaParams(right_bias=0.0, one_step_safety=False) if model == "orca_rvo2" else OrcaParams()
        self.orca_params = orca_params
        self._switch = None  # the "hybrid" diffusion walker's StallSwitch, made at the first step

    def reset(self, env: NavEnv) -> None:
        """Start an episode: only the diffusion crowd's ``"hybrid"`` walker keeps state (who walks with social
        force, :class:`~navzoo.agents.diffusion.crowd.StallSwitch`); everything else is in the env."""
        self._switch = None

    def velocities(self, env: NavEnv) -> np.ndarray:
        """New world-frame velocities (H, 2) of all pedestrians."""
        R, N = env.n_robots, env.n_total
        h = np.arange(R, N)
        if h.size == 0:
            return np.zeros((0, 2))
        pos, vel, rad = env.pos[h], env.vel[h], env.radius[h]
        if self.model == "replay":  # the env plays the recording; actions are ignored
            if getattr(env, "replay", None) is None:
                raise ValueError("CrowdPolicy('replay') needs an env made with crowd_model='replay'")
            return vel.copy()
        if self.model == "diffusion":  # the sampled plans set where and how fast; social force avoids
            if env.diffusion is None:
                raise ValueError("CrowdPolicy('diffusion') needs an env made with crowd_model='diffusion'")
            pref = env.crowd_conventions(env.diffusion.preferred_velocities(env), env.sim_time)
        else:
            # Toward the next A* waypoint, with turn-taking; CrowdNav's people slow down within 1 m of the goal.
            pref = env.human_preferred_velocity(slow_radius=1.0 if self.model == "orca_rvo2" else 0.5)
        vmax = np.full(h.size, env.config.human_max_speed)
        robots = np.flatnonzero(env.alive[:R]) if self.see_robots else np.zeros(0, dtype=int)
        walker = env.config.diffusion_walker if self.model == "diffusion" else None
        orca_walker = walker in ("orca", "hybrid")

        def social_force() -> np.ndarray:
            return social_force_velocities(
                pos, vel, pref, env.radius[h], vmax, env.config.dt, self.sfm_params or env.crowd_sfm_params, env.segments,
                others_pos=env.pos[robots], others_vel=env.vel[robots], others_radius=env.radius[robots],
                segment_groups=env.segment_groups,
            )

        if self.model == "sfm" or walker == "sfm":
            return social_force()
        if self.model == "orca_rvo2":  # CrowdNav's people: RVO2 agents of max speed v_pref, discs + 0.01 m
            vmax = env.v_pref[h].copy()
            rad = rad + 0.01
        params = self.orca_params
        if orca_walker:
            from navzoo.agents.diffusion import crowd as diffusion_crowd

            if not self._orca_given:
                params = diffusion_crowd.ORCA_WALKER
            rad = rad + diffusion_crowd.ORCA_WALKER_MARGIN  # ORCA keeps discs just touching: room to spare
        all_pos = np.concatenate([pos, env.pos[robots]])
        all_vel = np.concatenate([vel, env.vel[robots]])
        all_pref = np.concatenate([pref, env.vel[robots]])
        all_rad = np.concatenate([rad, env.radius[robots]])
        all_max = np.concatenate([vmax, np.full(robots.size, env.config.robot.max_speed)])
        v = orca_velocities(all_pos, all_vel, all_pref, all_rad, all_max, env.config.dt, params,
                            env.segments, n_active=h.size)
        if walker != "hybrid":
            return v
        from navzoo.agents.diffusion.crowd import StallSwitch

        if self._switch is None or self._switch.n != h.size:
            self._switch = StallSwitch(h.size)
        use = self._switch.update(env.sim_time, env.config.dt, v, pref)
        if use.any():
            v[use] = social_force()[use]
        return v

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        v = self.velocities(env)
        R = env.n_robots
        yaw = env.yaw[R:]
        c, s = np.cos(yaw), np.sin(yaw)
        local = np.stack([c * v[:, 0] + s * v[:, 1], -s * v[:, 0] + c * v[:, 1]], axis=1) / env.config.human_max_speed
        live = set(env.agents)
        return {
            f"human_{j}": np.clip(local[j], -1, 1).astype(np.float32)
            for j in range(env.n_humans)
            if f"human_{j}" in live
        }
