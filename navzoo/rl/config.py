"""Joint training configuration: which side learns, what drives the sides that do not.

A :class:`JointConfig` is a plain dataclass that reads from and writes to YAML/JSON. It says

- which scenario (``env_id``) and which NavConfig overrides (``env``: ``n_humans``, ``crowd_model``, ...),
- for each side, robots and humans, whether it **learns** (an RLlib policy, ``"robot"`` or
  ``"human"``, shared by every agent of that side) or is **frozen** on a fixed controller,
- what the frozen side runs: for robots a baseline controller by name (``"orca"``, ``"dwa"``, ...,
  :func:`navzoo.agents.baselines.policy_names`) or a policy trained before
  (``"rllib:PATH"``: the ``--out`` folder of a :mod:`navzoo.rl.train` run or one of its checkpoints);
  for humans the rule-based crowd model (``humans: crowd``, the env's ``crowd_model``), a kinematic
  pedestrian policy trained before (``humans: frozen`` with ``human_policy: "rllib:PATH"``) or, for
  physics pedestrians (``env: {human_model: amp}``), the shipped AMP controller (``humans: frozen``,
  ``human_policy: "amp"`` or ``"amp:DIR"``).

Frozen sides run *inside* the env (:class:`navzoo.envs.wrappers.FrozenAgents`), so RLlib only ever
sees the agents of the learning sides and their policies. Switching a side between learning and
frozen is a configuration change, never a code change.

This module does not import Ray: configurations can be written and validated without it.
"""

from __future__ import annotations

import dataclasses
import json
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

LEARN, FROZEN, CROWD = "learn", "frozen", "crowd"
ROBOT_MODES = (LEARN, FROZEN)
HUMAN_MODES = (LEARN, FROZEN, CROWD)
ROBOT_POLICY_ID, HUMAN_POLICY_ID = "robot", "human"
RLLIB_PREFIX = "rllib:"
AMP_PREFIX = "amp"


def policy_mapping_fn(agent_id: str, episode: Any = None, **kwargs: Any) -> str:
    """RLlib policy mapping: ``robot_*`` agents to the ``"robot"`` policy, ``human_*`` to ``"human"``."""
    if agent_id.startswith("robot_"):
        return ROBOT_POLICY_ID
    if agent_id.startswith("human_"):
        return HUMAN_POLICY_ID
    raise ValueError(f"cannot map agent {agent_id!r} to a policy: navzoo agents are named robot_<i> or human_<i>")


@dataclass
class JointConfig:
    """Robots and pedestrians in one env, each side learning or frozen.

    Attributes:
        env_id: a registered scenario (``navzoo.SCENARIOS``), e.g. ``"navzoo/CircleCrossing-v0"``.
        robots: ``"learn"`` (policy ``"robot"``) or ``"frozen"`` (driven by ``robot_policy``).
        humans: ``"learn"`` (policy ``"human"``), ``"frozen"`` (driven by ``human_policy``) or
            ``"crowd"`` (the env's rule-based ``crowd_model``; kinematic pedestrians only).
        n_robots: robots (None = the scenario's, 1).
        n_humans: pedestrians (None = the scenario's default).
        robot_policy: frozen robots: a baseline name or ``"rllib:PATH"``.
        human_policy: frozen humans: ``"rllib:PATH"`` (kinematic pedestrians) or ``"amp"`` /
            ``"amp:DIR"`` (``human_model="amp"``; None = the shipped AMP controller).
        env: NavConfig overrides (``crowd_model``, ``human_model``, ``time_limit``, ...);
            observations are always flat (``flat_obs=True``).
        robot_init: learning robots among learning AMP pedestrians (:mod:`navzoo.rl.amp_joint`, SB3 PPO with
            the transformer) start from this exported robot policy folder; None: a fresh network.
    """

    env_id: str = "navzoo/CircleCrossing-v0"
    robots: str = LEARN
    humans: str = LEARN
    n_robots: int | None = None
    n_humans: int | None = None
    robot_policy: str = "orca"
    human_policy: str | None = None
    env: dict[str, Any] = field(default_factory=dict)
    robot_init: str | None = None

    # ------------------------------------------------------------------ construction / IO
    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> JointConfig:
        """Build from a dict (YAML/JSON); unknown keys are rejected by name."""
        if not isinstance(data, dict):
            raise TypeError(f"joint config must be a mapping, got {type(data).__name__}")
        names = [f.name for f in dataclasses.fields(cls)]
        unknown = sorted(set(data) - set(names))
        if unknown:
            raise ValueError(f"unknown joint config key(s) {unknown}; valid keys: {names}")
        cfg = cls(**{k: (dict(v) if k == "env" and v is not None else v) for k, v in data.items()})
        if cfg.env is None:
            cfg.env = {}
        return cfg

    @classmethod
    def load(cls, path: str | Path) -> JointConfig:
        """Read a YAML or JSON file (a top-level ``joint:`` section is accepted too)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"joint config file {path} does not exist")
        text = path.read_text()
        if path.suffix == ".json":
            data = json.loads(text)
        else:
            import yaml

            data = yaml.safe_load(text) or {}
        if isinstance(data, dict) and set(data) == {"joint"}:
            data = data["joint"]
        return cls.from_dict(data)

    def to_dict(self) -> dict[str, Any]:
        d = dataclasses.asdict(self)
        d["env"] = dict(self.env)
        return d

    def save(self, path: str | Path) -> None:
        path = Path(path)
        if path.suffix == ".json":
            path.write_text(json.dumps(self.to_dict(), indent=2) + "\n")
        else:
            import yaml

            path.write_text(yaml.safe_dump(self.to_dict(), sort_keys=False))

    # ------------------------------------------------------------------ derived
    @property
    def learning_policies(self) -> list[str]:
        """RLlib policy ids that are trained, in a fixed order."""
        out = []
        if self.robots == LEARN:
            out.append(ROBOT_POLICY_ID)
        if self.humans == LEARN:
            out.append(HUMAN_POLICY_ID)
        return out

    def nav_overrides(self) -> dict[str, Any]:
        """The NavConfig overrides of the env (counts and ``flat_obs=True`` included)."""
        ov = dict(self.env)
        if self.n_robots is not None:
            ov["n_robots"] = self.n_robots
        if self.n_humans is not None:
            ov["n_humans"] = self.n_humans
        ov["flat_obs"] = True
        return ov

    def nav_config(self):
        """The validated :class:`navzoo.envs.config.NavConfig` of the env (without building it)."""
        from navzoo.envs.config import NavConfig
        from navzoo.envs.registry import SCENARIOS

        base = dict(SCENARIOS[self.env_id])
        ov = self.nav_overrides()
        if ov.get("human_model") == "amp" and "dt" not in ov:
            from navzoo.envs.config import AMP_CONTROL_HZ

            ov["dt"] = 1.0 / AMP_CONTROL_HZ  # as navzoo.make
        if isinstance(ov.get("robot"), dict):
            from navzoo.agents.robot import RobotSpec

            ov["robot"] = RobotSpec(**{**base.get("robot", RobotSpec()).__dict__, **ov["robot"]})
        return NavConfig.from_dict({**base, **ov})

    # ------------------------------------------------------------------ validation
    def validate(self, check_paths: bool = True, training: bool = True) -> JointConfig:
        """Raise ``ValueError``/``TypeError`` naming the problem; return self when the config is usable.

        Args:
            check_paths: also check that ``rllib:PATH`` policies exist (off inside env workers on
                other nodes, where the driver already checked them).
            training: the config is for training (some side must learn); ``False`` for evaluation,
                where every side must be frozen (or the crowd).
        """
        from navzoo.envs.registry import SCENARIOS

        if not isinstance(self.env_id, str) or self.env_id not in SCENARIOS:
            raise ValueError(f"unknown env_id {self.env_id!r}; registered ids: {sorted(SCENARIOS)}")
        if self.robots not in ROBOT_MODES:
            raise ValueError(f"robots must be one of {list(ROBOT_MODES)}, got {self.robots!r}")
        if self.humans not in HUMAN_MODES:
            raise ValueError(f"humans must be one of {list(HUMAN_MODES)}, got {self.humans!r}")
        if not isinstance(self.env, dict):
            raise TypeError(f"env must be a mapping of NavConfig overrides, got {type(self.env).__name__}")
        for key in ("n_robots", "n_humans"):
            if key in self.env:
                raise ValueError(f"set {key} at the top level of the joint config, not under env")
        if self.env.get("flat_obs", True) is not True:
            raise ValueError("RLlib training needs flat observations; remove flat_obs: false from env")
        for key in ("n_robots", "n_humans"):
            v = getattr(self, key)
            if v is not None and (isinstance(v, bool) or not isinstance(v, int) or v < 0):
                raise ValueError(f"{key} must be None or an integer >= 0, got {v!r}")
        nav = self.nav_config()  # NavConfig's own checks (unknown keys, ranges)
        n_humans = nav.n_humans
        if n_humans is None and nav.crowd_model != "replay":
            try:
                from navzoo.world.library import get_scene

                n_humans = int(get_scene(nav.scene).default_humans)
            except (ValueError, FileNotFoundError, OSError):
                n_humans = None  # a scene file: the env itself will check
        if training and not self.learning_policies:
            raise ValueError("nothing to train: robots and humans are both frozen; set robots: learn or humans: learn")
        if not training and self.learning_policies:
            raise ValueError(f"evaluation runs fixed policies: freeze the learning side(s) {self.learning_policies} "
                             "(robots: frozen with robot_policy, humans: frozen with human_policy, or humans: crowd)")
        if self.robots == LEARN and nav.n_robots == 0:
            raise ValueError("robots: learn needs n_robots >= 1")
        if self.humans == LEARN and n_humans == 0:
            raise ValueError("humans: learn needs n_humans >= 1")
        amp = nav.human_model == "amp"
        if self.robot_init is not None:
            if not (self.robots == LEARN and self.humans == LEARN and amp):
                raise ValueError("robot_init starts learning robots among learning AMP pedestrians (robots: learn, "
                                 "humans: learn, env: {human_model: amp}); RLlib robots start fresh")
            if not isinstance(self.robot_init, str) or (check_paths and not (Path(self.robot_init) / "config.json").is_file()):
                raise ValueError(f"robot_init must be an exported robot policy folder (with config.json), "
                                 f"got {self.robot_init!r}")
        if self.humans == LEARN and amp:
            # AMP pedestrians learn with the AMP learner (PPO + its discriminator's style reward), not RLlib:
            # navzoo.rl.amp_joint. Learning robots there are SB3 PPO stepped in the same loop.
            if self.robots == FROZEN and isinstance(self.robot_policy, str) and self.robot_policy.startswith(RLLIB_PREFIX):
                raise ValueError("humans: learn with human_model: amp drives its robots with a navzoo policy "
                                 f"(a baseline or a shipped learned method), not {self.robot_policy!r}")
        if self.humans == CROWD and amp:
            raise ValueError("humans: crowd drives kinematic pedestrians only; with human_model: amp use humans: frozen "
                             "(the AMP controller follows the crowd model's trajectories)")
        if self.robots == FROZEN:
            self._check_robot_policy(check_paths)
        if self.humans == FROZEN:
            self._check_human_policy(amp, check_paths)
        return self

    def _check_robot_policy(self, check_paths: bool) -> None:
        spec = self.robot_policy
        if not isinstance(spec, str) or not spec:
            raise ValueError(f"robots: frozen needs robot_policy (a baseline name or 'rllib:PATH'), got {spec!r}")
        if spec.startswith(RLLIB_PREFIX):
            if check_paths:
                resolve_module_dir(spec[len(RLLIB_PREFIX):], ROBOT_POLICY_ID)
            return
        from navzoo.agents.baselines import make_policy

        make_policy(spec)  # ValueError naming the valid baselines

    def _check_human_policy(self, amp: bool, check_paths: bool) -> None:
        spec = self.human_policy
        if amp:
            if spec is None or spec == AMP_PREFIX or (isinstance(spec, str) and spec.startswith(AMP_PREFIX + ":")):
                if check_paths and spec and spec.startswith(AMP_PREFIX + ":"):
                    d = Path(spec[len(AMP_PREFIX) + 1:])
                    if not (d / "config.json").is_file():
                        raise FileNotFoundError(f"AMP policy folder {d} has no config.json")
                return
            raise ValueError(f"humans: frozen with human_model: amp takes human_policy 'amp' or 'amp:DIR', got {spec!r}")
        if not isinstance(spec, str) or not spec.startswith(RLLIB_PREFIX):
            raise ValueError(
                "humans: frozen with kinematic pedestrians needs human_policy: 'rllib:PATH' (a pedestrian policy trained "
                f"by navzoo.rl.train), got {spec!r}; for rule-based pedestrians use humans: crowd")
        if check_paths:
            resolve_module_dir(spec[len(RLLIB_PREFIX):], HUMAN_POLICY_ID)


def resolve_module_dir(path: str | Path, module_id: str) -> Path:
    """The RLModule folder of ``module_id`` inside a training output or an RLlib checkpoint.

    Accepts the ``--out`` folder of :mod:`navzoo.rl.train` (its latest checkpoint), a checkpoint
    folder (``algo.save``) or the module folder itself.
    """
    p = Path(path).expanduser().resolve()  # RLlib loads modules from absolute paths (URIs) only
    if not p.exists():
        raise FileNotFoundError(f"policy path {p} does not exist")
    latest = p / "latest_checkpoint.txt"
    if latest.is_file():
        p = p / latest.read_text().strip()
    for cand in (p / "learner_group" / "learner" / "rl_module" / module_id, p / "rl_module" / module_id, p / module_id, p):
        if (cand / "class_and_ctor_args.pkl").is_file() and (cand / "module_state.pkl").is_file() and (
                cand.name == module_id or cand != p):
            return cand
    raise FileNotFoundError(f"no RLlib module {module_id!r} in {path} (expected a navzoo.rl.train --out folder, a checkpoint "
                            f"or .../learner_group/learner/rl_module/{module_id}); was the {module_id} side learning in that run?")
