"""Named benchmark protocols: the fields of a benchmark spec that a published setting fixes.

``navzoo benchmark --protocol crowdnav-circle --methods orca-crowdnav --episodes 500`` runs CrowdNav's
circle-crossing test: the scene, the crowd (5 ORCA people with RVO2's semantics, robot invisible to them),
the robot (holonomic, radius 0.3 m, v_pref 1 m/s), dt 0.25 s and the 25 s time limit all come from the
protocol; fields given on the command line or in a spec file override the protocol's defaults.
``--protocol replay-ethucy`` runs the robot among recorded ETH/UCY people (the replay crowd, SocNavBench's
setting), one time window of a recording per episode.

The env settings are the registry's CrowdNav presets (:data:`navzoo.envs.registry.SCENARIOS`), so a
protocol and ``navzoo.make("navzoo/CircleCrossing-v0")`` are the same world.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

from navzoo.envs.registry import SCENARIOS

#: The recordings that ship with the package (navzoo/assets/tracks), for the replay protocol.
REPLAY_RECORDINGS = ("eth", "univ", "zara1", "zara3", "uni_examples")

__all__ = ["PROTOCOLS", "Protocol", "get_protocol", "protocol_names"]


@dataclass(frozen=True)
class Protocol:
    """Defaults a named protocol gives a benchmark spec.

    Attributes:
        name: the protocol's name (``--protocol``).
        description: one line for ``--help`` and the reports.
        scenes: scene names.
        crowds: crowd models (``NavConfig.crowd_model``).
        humans: people per scene (counts); ``None`` with ``densities`` None = the scene's default.
        densities: people per m² of free space (instead of ``humans``).
        episodes: episodes per cell.
        time_limit: episode time limit (s).
        env: NavConfig overrides (``robot`` as a dict of RobotSpec fields), applied to every episode.
        methods: the methods the protocol is usually run with (used when none are given).
        reference: published numbers to compare with, ``{method: {metric: value}}``.
    """

    name: str
    description: str
    scenes: tuple[str, ...]
    crowds: tuple[str, ...]
    humans: tuple[int, ...] | None = None
    densities: tuple[float, ...] | None = None
    episodes: int = 20
    time_limit: float | None = None
    env: dict[str, Any] = field(default_factory=dict)
    methods: tuple[str, ...] = ()
    reference: dict[str, dict[str, float]] = field(default_factory=dict)

    def spec_fields(self) -> dict[str, Any]:
        """The protocol as benchmark-spec fields (lists and plain dicts, as a YAML spec would give)."""
        out: dict[str, Any] = {
            "scenes": list(self.scenes),
            "crowd": list(self.crowds),
            "episodes": self.episodes,
            "env": dict(self.env),
        }
        if self.humans is not None:
            out["humans"] = list(self.humans)
        if self.densities is not None:
            out["density"] = list(self.densities)
        if self.time_limit is not None:
            out["time_limit"] = self.time_limit
        if self.methods:
            out["methods"] = list(self.methods)
        return out


def _crowdnav(env_id: str) -> tuple[dict[str, Any], str, float]:
    """A registry CrowdNav preset split into (env overrides, crowd model, time limit)."""
    preset = dict(SCENARIOS[env_id])
    preset.pop("scene")
    crowd = preset.pop("crowd_model")
    time_limit = float(preset.pop("time_limit"))
    robot = preset.pop("robot")
    env = {**preset, "robot": dataclasses.asdict(robot)}
    if "human_speed" in env:
        env["human_speed"] = list(env["human_speed"])
    return env, crowd, time_limit


# CrowdNav (Chen et al. 2019), circle crossing, 500 test episodes (METRICS.md): its ORCA robot is
# ``orca-crowdnav``; navzoo's own ``orca-holonomic`` (keep-right bias, one-step safety, no 0.01 m disc
# margin) is compared with the same row (docs/benchmarks.md explains the gap).
_CROWDNAV_ORCA = {"success_rate": 0.43, "collision_rate": 0.57, "nav_time_s": 10.86}
_CROWDNAV_REFERENCE = {"orca-crowdnav": dict(_CROWDNAV_ORCA), "orca-holonomic": dict(_CROWDNAV_ORCA)}


def _make_protocols() -> dict[str, Protocol]:
    circle_env, circle_crowd, circle_limit = _crowdnav("navzoo/CircleCrossing-v0")
    square_env, square_crowd, square_limit = _crowdnav("navzoo/SquareCrossing-v0")
    return {
        "crowdnav-circle": Protocol(
            name="crowdnav-circle",
            description="CrowdNav circle crossing: radius 4 m, 5 ORCA (RVO2) people, robot invisible to them, "
            "holonomic robot r 0.3 m, v_pref 1 m/s, dt 0.25 s, 25 s, 500 episodes",
            scenes=("circle_crossing",),
            crowds=(circle_crowd,),
            humans=(5,),
            episodes=500,
            time_limit=circle_limit,
            env=circle_env,
            methods=("orca-crowdnav",),
            reference=_CROWDNAV_REFERENCE,
        ),
        "replay-ethucy": Protocol(
            name="replay-ethucy",
            description="recorded ETH/UCY people who do not react to the robot (SocNavBench's setting), the five "
            "packaged recordings, each episode another window of the recording (robot default, 60 s)",
            scenes=tuple(f"replay_{name}" for name in REPLAY_RECORDINGS),
            crowds=("replay",),
            episodes=20,
        ),
        "crowdnav-square": Protocol(
            name="crowdnav-square",
            description="CrowdNav square crossing: 5 ORCA (RVO2) people crossing a square, robot invisible to "
            "them, holonomic robot r 0.3 m, v_pref 1 m/s, dt 0.25 s, 25 s, 500 episodes",
            scenes=("square_crossing",),
            crowds=(square_crowd,),
            humans=(5,),
            episodes=500,
            time_limit=square_limit,
            env=square_env,
            methods=("orca-crowdnav",),
        ),
    }


PROTOCOLS: dict[str, Protocol] = _make_protocols()


def protocol_names() -> list[str]:
    """The names of the named protocols, sorted."""
    return sorted(PROTOCOLS)


def get_protocol(name: str) -> Protocol:
    """The protocol ``name``; an unknown name raises ``ValueError`` listing the valid ones."""
    if not isinstance(name, str) or name.strip().lower() not in PROTOCOLS:
        raise ValueError(f"unknown benchmark protocol {name!r}; valid protocols: {', '.join(protocol_names())}")
    return PROTOCOLS[name.strip().lower()]
