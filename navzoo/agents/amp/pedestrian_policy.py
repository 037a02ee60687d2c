"""The shipped AMP pedestrian controller as a frozen-agents policy: batched over all pedestrians."""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from navzoo.agents.amp.checkpoint import TRIM_OFF_KEY, load_policy

if TYPE_CHECKING:
    from navzoo.envs.nav_env import NavEnv


def default_policy_dir() -> Path:
    """Directory of the shipped AMP pedestrian policy (``policies/amp_pedestrian``)."""
    import policies

    for root in policies.__path__:  # a package, or a namespace (editable installs) with one real dir
        if (Path(root) / "amp_pedestrian").is_dir():
            return Path(root) / "amp_pedestrian"
    raise FileNotFoundError(f"the shipped AMP policy is missing from {list(policies.__path__)}")


class AmpPedestrianPolicy:
    """Drives ``human_model="amp"`` pedestrians with an exported AMP policy, one forward pass per step
    for all of them (deterministic: the action mean).

    Args:
        policy_dir: exported policy (``config.json`` + weights); default: the shipped one.
        device: torch device of the forward pass.
        steering_trim: rad; overrides the policy's calibrated steering trim (``0.0`` turns it off;
            None keeps the config's, see :mod:`navzoo.agents.amp.steering`). The config's trim is not
            applied in envs whose ``crowd_model`` its ``off_for_crowd_models`` list names (the shipped
            policy: ``diffusion``, where it was measured to lower success and raise falls); an explicit
            ``steering_trim`` applies everywhere.
        symmetric: make the policy left/right symmetric (:mod:`navzoo.agents.amp.symmetry`; drops
            the trim); None keeps the config's setting.
    """

    def __init__(self, policy_dir: str | Path | None = None, device: str = "cpu",
                 steering_trim: float | None = None, symmetric: bool | None = None) -> None:
        self.policy_dir = Path(policy_dir) if policy_dir is not None else default_policy_dir()
        self.policy = load_policy(self.policy_dir, device=device)
        if steering_trim is not None or symmetric is not None:
            self.policy.override(steering_trim, symmetric)  # checked by AmpPolicy
        off = (self.policy.config.get("steering_trim") or {}).get(TRIM_OFF_KEY, [])
        if not (isinstance(off, list) and all(isinstance(m, str) for m in off)):
            raise ValueError(f"{self.policy_dir}/config.json: steering_trim.{TRIM_OFF_KEY} must be a list of "
                             f"crowd model names, got {off!r}")
        #: the config's trim, and the crowd models it is not applied to (None: the trim was overridden)
        self._config_trim = None if (steering_trim is not None or symmetric) else (self.policy.steering_trim, set(off))

    def reset(self, env: NavEnv) -> None:
        if env.config.human_model != "amp":
            raise ValueError("AmpPedestrianPolicy drives human_model='amp' pedestrians; "
                             f"this env has human_model={env.config.human_model!r}")
        want = getattr(self.policy, "obs_dim", None)
        have = env.observation_space(env.possible_agents[-1]).shape[0] if env.n_humans else want
        if want is not None and want != have:
            raise ValueError(f"policy {self.policy_dir} takes {want} inputs, the env's pedestrians observe {have}")
        if self._config_trim is not None:
            trim, off = self._config_trim
            self.policy.steering_trim = 0.0 if env.config.crowd_model in off else trim

    def act(self, observations: dict[str, Any], env: NavEnv) -> dict[str, np.ndarray]:
        names = list(observations)
        if not names:
            return {}
        actions = self.policy(np.stack([np.asarray(observations[a], dtype=np.float32) for a in names]))
        return {a: actions[k].astype(np.float32) for k, a in enumerate(names)}
