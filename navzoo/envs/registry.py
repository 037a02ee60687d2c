"""Scenario presets, registered with PettingZoo's registry as versioned ids.

``pettingzoo.make("parallel", "navzoo/Station-v0")`` and ``navzoo.make("navzoo/Station-v0")``
return the env most users want: robots learnable, pedestrians frozen on their rule-based crowd
model. ``raw=True`` returns the bare :class:`NavEnv` where every pedestrian is an agent too.
"""

from __future__ import annotations

from typing import Any

from pettingzoo import ParallelEnv

from navzoo.agents.crowd import CrowdPolicy
from navzoo.agents.robot import RobotSpec
from navzoo.envs.config import AMP_CONTROL_HZ, NavConfig
from navzoo.envs.nav_env import NavEnv
from navzoo.envs.wrappers import FrozenAgents

# CrowdNav's protocol: holonomic robot, radius 0.3 m, v_pref 1 m/s, dt 0.25 s, 25 s, invisible robot,
# 5 ORCA (RVO2 semantics) people of radius 0.3 m and v_pref 1 m/s who stop at their goals, collisions
# judged on discs only.
_CROWDNAV = dict(
    human_body_contacts=False, human_at_goal="stop",
    robot=RobotSpec(kinematics="holonomic", max_accel=100.0, max_ang_accel=100.0, max_turn_rate=8.0),
    crowd_model="orca_rvo2", humans_see_robots=False, human_yielding=False, human_speed=(1.0, 1.0), dt=0.25, time_limit=25.0,
)

SCENARIOS: dict[str, dict[str, Any]] = {
    "navzoo/CircleCrossing-v0": dict(scene="circle_crossing", **_CROWDNAV),
    "navzoo/SquareCrossing-v0": dict(scene="square_crossing", **_CROWDNAV),
    "navzoo/Station-v0": dict(scene="station"),
    "navzoo/Home-v0": dict(scene="home"),
    "navzoo/Grocery-v0": dict(scene="grocery"),
    "navzoo/Corridor-v0": dict(scene="corridor"),
    "navzoo/Doorway-v0": dict(scene="doorway"),
    "navzoo/Lobby-v0": dict(scene="lobby"),
}


def make_raw(env_id: str | None = None, render_mode: str | None = None, **overrides: Any) -> NavEnv:
    """The bare env (every robot and pedestrian is an agent) for a scenario id or a plain config."""
    base: dict[str, Any] = {}
    if env_id is not None:
        if env_id not in SCENARIOS:
            raise ValueError(f"unknown navzoo env id {env_id!r}; registered ids: {sorted(SCENARIOS)}")
        base = dict(SCENARIOS[env_id])
    render_view = overrides.pop("render_view", "topdown")
    if isinstance(overrides.get("robot"), dict):
        overrides["robot"] = RobotSpec(**{**base.get("robot", RobotSpec()).__dict__, **overrides["robot"]})
    cfg = NavConfig.from_dict({**base, **overrides})
    return NavEnv(cfg, render_mode=render_mode, render_view=render_view)


def make(env_id: str | None = None, render_mode: str | None = None, raw: bool = False, **overrides: Any) -> ParallelEnv:
    """Make a navzoo env: robots learnable, pedestrians frozen on the config's crowd model.

    Args:
        env_id: a registered id (``navzoo.envs.registry.SCENARIOS``) or None for the default config.
        render_mode: None, ``"rgb_array"`` or ``"human"``.
        raw: return the bare NavEnv (pedestrians are agents too).
        **overrides: NavConfig fields (``n_robots=2``, ``n_humans=20``, ``crowd_model="orca"``, ...)
            and ``render_view``. ``human_model="amp"`` freezes the pedestrians on the shipped AMP
            controller and, unless ``dt`` is given, sets ``dt`` to its 1/30 s control period.
    """
    if overrides.get("human_model") == "amp" and "dt" not in overrides:
        overrides["dt"] = 1.0 / AMP_CONTROL_HZ  # the AMP controller acts at its training rate
    env = make_raw(env_id, render_mode=render_mode, **overrides)
    if raw:
        return env
    if env.config.human_model == "amp":
        from navzoo.agents.amp.pedestrian_policy import AmpPedestrianPolicy

        return FrozenAgents(env, lambda a: a.startswith("human_"), AmpPedestrianPolicy())
    crowd = CrowdPolicy(env.config.crowd_model, see_robots=env.config.humans_see_robots)
    return FrozenAgents(env, lambda a: a.startswith("human_"), crowd)


def _entry(env_id: str):
    def factory(**kwargs: Any) -> ParallelEnv:
        kwargs.pop("max_cycles", None)
        return make(env_id, **kwargs)

    return factory


def register_all() -> None:
    """Register every scenario id with PettingZoo (parallel) — done on ``import navzoo``."""
    import pettingzoo

    for env_id in SCENARIOS:
        if env_id not in pettingzoo.parallel_registry:
            pettingzoo.register("parallel", env_id, entry_point=_entry(env_id))
