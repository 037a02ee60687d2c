"""Action blending of exported AMP policies: one controller whose PD targets are the weighted mean of
several policies' PD targets for the same observation.

Weight averaging (:func:`navzoo.agents.amp.checkpoint.average_policies`) only works for policies
fine-tuned from one starting checkpoint. Policies trained independently (e.g. the shipped lineage,
which balances in crowds, and the stance run, which walks with the clips' gait) can still be combined
in action space: every component sees the same observation, so their gaits are locked to the same body
state, and the PD targets are averaged joint by joint.

A blend is a directory with a ``config.json`` only::

    {"format": "navzoo-amp-blend", "version": 1, "obs_dim": 141, "act_dim": 28,
     "components": [{"path": "../amp_pedestrian", "weight": 0.5, "weights_sha256": "..."}, ...]}

Component paths are relative to the blend directory (or absolute); each component is an exported
policy (``navzoo-amp-policy``) that is loaded and verified as :func:`load_policy` does, and its
``weights_sha256`` must match the one the blend recorded, so a replaced component is refused. Each
component keeps its own steering trim; the blend may carry one more (``steering_trim.rad``), applied to
the observation before the components see it. :func:`load_policy` returns a :class:`BlendedPolicy`
for a blend directory, so every tool that takes an exported policy takes a blend.
"""

from __future__ import annotations

import json
import os
from pathlib import Path
from typing import Any

import numpy as np

BLEND_FORMAT = "navzoo-amp-blend"
BLEND_VERSION = 1


class BlendedPolicy:
    """Deterministic policy ``obs -> sum_i w_i * policy_i(obs)`` over exported AMP policies (each action
    already clipped to [-1, 1], so the blend is too). Same call interface as
    :class:`navzoo.agents.amp.checkpoint.AmpPolicy`; it cannot be made symmetric."""

    def __init__(self, components: list[Any], weights: list[float], config: dict[str, Any]) -> None:
        from navzoo.agents.amp.checkpoint import waypoint_layout

        if len(components) != len(weights) or not components:
            raise ValueError(f"a blend needs one weight per component, got {len(weights)} for {len(components)}")
        w = np.asarray(weights, dtype=np.float64)
        if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
            raise ValueError(f"blend weights must be finite, >= 0 and not all 0, got {list(weights)}")
        dims = {(int(c.obs_dim), int(c.act_dim)) for c in components}
        if len(dims) != 1:
            raise ValueError(f"blended policies must share obs_dim and act_dim, got {sorted(dims)}")
        self.components = list(components)
        self.weights = (w / w.sum()).astype(np.float32)
        self.obs_dim, self.act_dim = dims.pop()
        self.config = config
        trim = config.get("steering_trim")
        if trim is not None and not isinstance(trim, dict):
            raise ValueError(f"steering_trim must be an object with 'rad', got {trim!r}")
        self._waypoints = waypoint_layout(self.obs_dim, config)
        self.steering_trim = (trim or {}).get("rad", 0.0)

    @property
    def steering_trim(self) -> float:
        """rad the observed target points are turned to the left before the components see them."""
        return self._steering_trim

    @steering_trim.setter
    def steering_trim(self, value: float) -> None:
        from navzoo.agents.amp.checkpoint import check_steering_trim

        self._steering_trim = check_steering_trim(value)

    @property
    def symmetric(self) -> bool:
        return False

    @property
    def waypoints(self) -> tuple[int, int]:
        return self._waypoints

    def override(self, steering_trim: float | None = None, symmetric: bool | None = None) -> None:
        """Replace the blend's own steering trim for this run; a blend cannot be made symmetric."""
        if symmetric:
            raise ValueError("a blended policy cannot be made symmetric (make its components symmetric instead)")
        if steering_trim is not None:
            self.steering_trim = steering_trim

    def __call__(self, obs: np.ndarray) -> np.ndarray:
        from navzoo.agents.amp.checkpoint import obs_batch, rotate_waypoints

        x, single = obs_batch(obs, self.obs_dim)
        if self.steering_trim:
            x = rotate_waypoints(x, *self._waypoints, self.steering_trim)
        act = sum(w * c(x) for w, c in zip(self.weights, self.components, strict=True))
        act = np.clip(act, -1.0, 1.0).astype(np.float32)
        return act[0] if single else act


def _component_path(root: Path, entry: Any, where: str) -> Path:
    if not isinstance(entry, dict) or not isinstance(entry.get("path"), str) or not entry["path"]:
        raise ValueError(f"{where}: each component must be an object with a 'path' string, got {entry!r}")
    p = Path(entry["path"])
    return p if p.is_absolute() else (root / p)


def load_blend(root: str | os.PathLike[str], cfg: dict[str, Any], device: str = "cpu") -> BlendedPolicy:
    """Build the :class:`BlendedPolicy` of the blend directory ``root`` whose parsed config is ``cfg``.
    Raises :class:`~navzoo.agents.amp.checkpoint.CheckpointError` naming the problem (a missing or
    replaced component, a bad weight, a nested blend, mismatched dims)."""
    from navzoo.agents.amp.checkpoint import POLICY_CONFIG, CheckpointError, _read_json, load_policy

    root = Path(root)
    where = str(root / POLICY_CONFIG)
    if cfg.get("version") != BLEND_VERSION:
        raise CheckpointError(f"{where}: blend version {cfg.get('version')!r}, this navzoo reads {BLEND_VERSION}")
    entries = cfg.get("components")
    if not isinstance(entries, list) or len(entries) < 2:
        raise CheckpointError(f"{where}: 'components' must list at least two exported policies")
    comps, weights = [], []
    for k, entry in enumerate(entries):
        try:
            path = _component_path(root, entry, where)
            weight = float(entry.get("weight", 1.0))
        except (ValueError, TypeError) as e:
            raise CheckpointError(f"{where}: component {k}: {e}") from e
        if not (path / POLICY_CONFIG).is_file():
            raise CheckpointError(f"{where}: component {k} ({path}) is not an exported AMP policy folder")
        sub = _read_json(path / POLICY_CONFIG, "policy config")
        if sub.get("format") == BLEND_FORMAT:
            raise CheckpointError(f"{where}: component {k} ({path}) is itself a blend; list its policies instead")
        pol = load_policy(path, device=device)
        want = entry.get("weights_sha256")
        if want is not None and want != pol.config.get("weights_sha256"):
            raise CheckpointError(f"{where}: component {k} ({path}) has other weights than the blend was made "
                                  f"with (sha256 {pol.config.get('weights_sha256')}, recorded {want})")
        comps.append(pol)
        weights.append(weight)
    try:
        blend = BlendedPolicy(comps, weights, cfg)
    except ValueError as e:
        raise CheckpointError(f"{where}: {e}") from e
    for key in ("obs_dim", "act_dim"):
        if key in cfg and int(cfg[key]) != getattr(blend, key):
            raise CheckpointError(f"{where}: {key} {cfg[key]} does not match its components' "
                                  f"{getattr(blend, key)}")
    return blend


def write_blend(paths: list[str | os.PathLike[str]], out: str | os.PathLike[str],
                weights: list[float] | None = None) -> Path:
    """Write a blend of the exported policies ``paths`` (with ``weights``, default equal) to the directory
    ``out``; component paths are stored relative to ``out``. Returns the config path. The blend is
    loaded back before this returns, so a blend that cannot load is never left behind."""
    from navzoo.agents.amp.checkpoint import POLICY_CONFIG, load_policy

    if len(paths) < 2:
        raise ValueError(f"a blend needs at least two policies, got {len(paths)}")
    if weights is None:
        weights = [1.0] * len(paths)
    if len(weights) != len(paths):
        raise ValueError(f"{len(weights)} weights for {len(paths)} policies")
    out = Path(out)
    pols = [load_policy(p) for p in paths]
    if any(isinstance(p, BlendedPolicy) for p in pols):
        raise ValueError("a blend's components must be exported policies, not blends")
    BlendedPolicy(pols, list(weights), {"obs_dim": pols[0].obs_dim})  # checks weights and dims
    out.mkdir(parents=True, exist_ok=True)
    comps = [{"path": os.path.relpath(Path(p).resolve(), out.resolve()), "weight": float(w),
              "weights_sha256": pol.config.get("weights_sha256"),
              "trained_iterations": pol.config.get("trained_iterations")}
             for p, w, pol in zip(paths, weights, pols, strict=True)]
    cfg = {"format": BLEND_FORMAT, "version": BLEND_VERSION, "obs_dim": pols[0].obs_dim,
           "act_dim": pols[0].act_dim, "components": comps}
    path = out / POLICY_CONFIG
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(cfg, indent=1, sort_keys=True) + "\n")
    os.replace(tmp, path)
    try:
        load_policy(out)
    except Exception:
        path.unlink()
        raise
    return path
