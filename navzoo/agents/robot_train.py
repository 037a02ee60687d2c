"""``navzoo train robot``: PPO with the spatio-temporal transformer on the paper's three training scenes.

The robot policy of the NavIsaacLab paper (:mod:`navzoo.agents.transformer` + SB3 PPO, the env's
reward, which is the paper's) trained on a vector env that mixes the station, home and grocery scenes:

* ``--n-envs`` copies of every scene, interleaved (station, home, grocery, station, ...), each copy
  one SuperSuit ``pettingzoo_env_to_vec_env_v1`` env (``--robots-per-env`` robots as vector
  entries, default 1), concatenated by SuperSuit (``ConcatVecEnv``, or ``ProcConcatVec`` over
  ``--num-cpus`` worker processes); copy ``i`` is seeded ``seed + i`` whatever the process layout;
  then ``VecMonitor`` and ``VecCheckNan(raise_exception=True)``. Observations are the flat Box
  (``flat_obs=True``, ``MlpPolicy``); the extractor splits it back into its entries.
* ``n_steps`` 32 and ``n_epochs`` 6 as in the paper (flags); TensorBoard under ``--out/tb``; one JSON
  line per rollout on stdout (and in ``--out/metrics.jsonl``).
* Checkpoints ``--out/checkpoints/step_<N>.pt`` (tensors only: policy and optimiser state dicts,
  loaded with ``weights_only=True``) + ``step_<N>.json`` (timesteps, model options, sha256); SB3's
  own ``.zip`` is not used because its ``data`` entry holds cloudpickled objects that ``PPO.load``
  unpickles. A rerun with the same ``--out`` resumes from the newest valid checkpoint, timesteps
  included; ``--total-steps`` is the total to reach. SIGINT and ``--time-limit-s`` stop at the next
  env step and save.
* At the end the policy is exported to ``--out/policy`` (:func:`export_policy`: ``policy.pt``
  state dict + ``config.json`` with its sha256), the format shipped in ``policies/transformer_ppo``
  and loaded by :func:`load_policy` / the ``"transformer-ppo"`` benchmark method
  (:func:`register_transformer_ppo`).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import signal
import sys
import threading
import time
import warnings
from collections import deque
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.callbacks import BaseCallback
from stable_baselines3.common.vec_env import VecCheckNan, VecEnv, VecMonitor
from torch import nn

from navzoo.agents.amp.checkpoint import sha256_file
from navzoo.agents.policy import SB3Policy
from navzoo.agents.transformer import (
    SpatioTemporalExtractor,
    flat_layout,
    observation_dict_space,
    transformer_policy_kwargs,
)
from navzoo.envs.wrappers import _NavWrapper

__all__ = [
    "DEFAULT_POLICY_DIR",
    "TRAIN_SCENES",
    "TrainArgs",
    "add_arguments",
    "export_policy",
    "init_weights_from",
    "latest_checkpoint",
    "load_policy",
    "check_resume",
    "copy_crowds",
    "main",
    "make_mixed_vec_env",
    "parse_scenes",
    "register_transformer_ppo",
    "run_cli",
    "shipped_policy_available",
    "train",
]

TRAIN_SCENES = ("navzoo/Station-v0", "navzoo/Home-v0", "navzoo/Grocery-v0")
DEFAULT_POLICY_DIR = Path(__file__).resolve().parents[2] / "policies" / "transformer_ppo"
POLICY_FORMAT = "navzoo-sb3-actor-critic"
POLICY_VERSION = 1
TRAIN_COMMAND = "navzoo train robot --out runs/robot (then copy runs/robot/policy to policies/transformer_ppo)"
_ACTIVATIONS: dict[str, type[nn.Module]] = {"tanh": nn.Tanh, "relu": nn.ReLU, "elu": nn.ELU, "gelu": nn.GELU,
                                            "leaky_relu": nn.LeakyReLU}
FORWARD_ONLY_ACTIONS = spaces.Box(np.array([0.0, -1.0], np.float32), np.array([1.0, 1.0], np.float32), dtype=np.float32)
_DTYPES = {"float32": torch.float32, "float16": torch.float16}
_ALIASED = ("pi_features_extractor.", "vf_features_extractor.")


def _write_json(path: Path, data: Mapping[str, Any]) -> None:
    tmp = path.with_name(path.name + ".tmp")
    tmp.write_text(json.dumps(data, indent=2, sort_keys=True) + "\n")
    tmp.replace(path)


# ---------------------------------------------------------------------------------------------
# The mixed-scene vector env.


class _SeededCopy(_NavWrapper):
    """One copy of the mixed vector env: seeds itself ``seed + copy_index`` and names itself in errors.

    SuperSuit adds an offset to the seed it passes down (the copy's position in its ``ConcatVecEnv``
    plus its worker's index), so copies in different workers would overlap; ``seed_shift`` is that
    offset, taken back out here.
    """

    def __init__(self, env: Any, env_id: str, copy_index: int, seed_shift: int) -> None:
        super().__init__(env)
        self.possible_agents = list(env.possible_agents)
        self.env_id, self.copy_index, self.seed_shift = env_id, copy_index, seed_shift
        self.first_seed: int | None = None
        self.episode = -1

    @property
    def agents(self) -> list[str]:
        return self.env.agents

    def _where(self) -> str:
        return f"env copy {self.copy_index} ({self.env_id}, first seed {self.first_seed}, episode {self.episode})"

    def reset(self, seed: int | None = None, options: dict | None = None):
        if seed is not None:
            seed = seed - self.seed_shift + self.copy_index
            self.first_seed, self.episode = seed, -1
        self.episode += 1
        try:
            return self.env.reset(seed=seed, options=options)
        except Exception as exc:
            raise RuntimeError(f"{self._where()} failed in reset: {type(exc).__name__}: {exc}") from exc

    def step(self, actions: dict[str, Any]):
        try:
            return self.env.step(actions)
        except Exception as exc:
            raise RuntimeError(f"{self._where()} failed in step: {type(exc).__name__}: {exc}") from exc


@dataclass
class _CopyFactory:
    """Builds one env copy (in the worker process that steps it)."""

    env_id: str
    copy_index: int
    seed_shift: int
    overrides: dict[str, Any]
    expected_obs: spaces.Space
    expected_act: spaces.Space
    crowd_policy: str | None = None

    def __call__(self) -> Any:
        import supersuit as ss

        from navzoo.envs.registry import make
        from navzoo.envs.wrappers import PadFinishedAgents

        if self.crowd_policy is None:
            env = make(self.env_id, **self.overrides)
        else:  # pedestrians trained with RLlib, frozen, act for themselves (as the benchmark's rllib: crowds)
            from navzoo.envs.wrappers import FrozenAgents
            from navzoo.rl.joint import FlatObsPolicy, RLModulePolicy

            crowd = FlatObsPolicy(RLModulePolicy(self.crowd_policy[len(CROWD_POLICY_PREFIX):], "human"))
            env = FrozenAgents(make(self.env_id, raw=True, **self.overrides), lambda a: a.startswith("human_"), crowd)
        for a in env.possible_agents:
            if env.observation_space(a) != self.expected_obs or env.action_space(a) != self.expected_act:
                raise ValueError(f"{self.env_id}: agent {a} has observation space {env.observation_space(a)} and "
                                 f"action space {env.action_space(a)}; every scene of the mix must have "
                                 f"{self.expected_obs} and {self.expected_act}")
        if len(env.possible_agents) > 1:
            env = PadFinishedAgents(env)  # robots that finish early stay as zero entries
        return ss.pettingzoo_env_to_vec_env_v1(_SeededCopy(env, self.env_id, self.copy_index, self.seed_shift))


CROWD_POLICY_PREFIX = "rllib:"


def check_crowd_policy(spec: str) -> None:
    """``ValueError`` unless ``spec`` is ``"rllib:PATH"`` with an RLlib ``human`` module at PATH."""
    if not isinstance(spec, str) or not spec.startswith(CROWD_POLICY_PREFIX):
        raise ValueError(f"--crowd-policy takes rllib:PATH (pedestrians trained with navzoo train joint), got {spec!r}")
    from navzoo.rl.config import resolve_module_dir

    try:
        resolve_module_dir(spec[len(CROWD_POLICY_PREFIX):], "human")
    except FileNotFoundError as exc:
        raise ValueError(f"--crowd-policy {spec}: {exc}") from exc


def make_mixed_vec_env(env_ids: Sequence[str] = TRAIN_SCENES, n_envs: int = 1, seed: int | None = 0,
                       num_cpus: int = 0, robots_per_env: int = 1, crowd_policy: str | None = None,
                       densities: Sequence[float] | None = None, max_humans: int | None = None,
                       **overrides: Any) -> VecEnv:
    """An SB3 ``VecEnv`` mixing several navzoo scenes with the same spaces (flat observations).

    Copy ``i`` (``n_envs`` per scene, interleaved: scene ``i % len(env_ids)``) is seeded ``seed + i``
    at the first reset, also across worker processes. Every robot of every copy is one vector entry
    (``num_envs = len(env_ids) * n_envs * robots_per_env``).

    Args:
        env_ids: registered ids (the scenes must give identical observation and action spaces).
        n_envs: copies per scene.
        seed: seed of the first reset (None: unseeded).
        num_cpus: worker processes (SuperSuit ``num_cpus``; 0 or 1: all in this process).
        robots_per_env: robots per copy (``n_robots``).
        crowd_policy: ``"rllib:PATH"``: the pedestrians are a crowd trained with RLlib (``navzoo train
            joint``), frozen, instead of the scene's crowd model; None: the crowd model.
        densities: crowd densities (people per m² of each scene's crowd area), as the benchmark's
            density levels: a scene's ``j``-th copy gets ``densities[j % len(densities)]``, i.e. the
            count ``navzoo benchmark --density`` runs there (capped at ``max_humans``). None: each
            scene's default crowd (or ``n_humans`` from the overrides).
        max_humans: cap on those counts (the benchmark's ``--max-humans``); only with ``densities``.
        **overrides: NavConfig fields for every scene (``k_neighbors``, ``n_humans``, ...).

    Raises:
        ValueError: for bad counts or densities, unknown ids, or scenes whose spaces differ.
    """
    from supersuit.vector import ConcatVecEnv, ProcConcatVec

    from navzoo.envs.config import NavConfig
    from navzoo.envs.nav_env import NavEnv
    from navzoo.envs.registry import SCENARIOS
    from navzoo.envs.vector import SeededSB3VecEnv

    if not env_ids:
        raise ValueError("env_ids must name at least one scene")
    unknown = [e for e in env_ids if e not in SCENARIOS]
    if unknown:
        raise ValueError(f"unknown env id(s) {unknown}; registered ids: {sorted(SCENARIOS)}")
    for name, v, lo in (("n_envs", n_envs, 1), ("num_cpus", num_cpus, 0), ("robots_per_env", robots_per_env, 1)):
        if not isinstance(v, (int, np.integer)) or v < lo:
            raise ValueError(f"{name} must be an integer >= {lo}, got {v!r}")
    per_copy = copy_crowds(env_ids, n_envs, densities, max_humans, overrides)
    overrides = {**overrides, "flat_obs": True, "n_robots": int(robots_per_env)}
    defaults = NavConfig.__dataclass_fields__
    sizes = [overrides.get(k, defaults[k].default) for k in ("k_neighbors", "history", "map_cells", "scan_rays")]
    obs_space = spaces.flatten_space(observation_dict_space(*sizes))
    act_space = spaces.Box(-1.0, 1.0, shape=(2,), dtype=np.float32)
    n_copies = len(env_ids) * n_envs
    workers = min(int(num_cpus), n_copies)
    per_worker = n_copies if workers <= 1 else -(-n_copies // workers)

    def shift(i: int) -> int:  # what SuperSuit adds to the seed on its way to copy i
        return i if workers <= 1 else i // per_worker + i % per_worker

    if crowd_policy is not None:
        check_crowd_policy(crowd_policy)
    fns = [_CopyFactory(env_ids[i % len(env_ids)], i, shift(i), {**overrides, **per_copy[i]}, obs_space, act_space,
                        crowd_policy) for i in range(n_copies)]
    if workers <= 1:
        vec = ConcatVecEnv(fns)
    else:
        from supersuit.vector.constructors import call_wrap

        chunks = [fns[s:s + per_worker] for s in range(0, n_copies, per_worker)]
        # The workers ignore SIGINT: Ctrl-C (or `timeout -s INT`) reaches the whole process group, and a
        # worker killed by it breaks the pipe before the trainer can save its stop checkpoint. The
        # trainer handles the signal and closes the workers itself.
        with _sigint_ignored():
            vec = ProcConcatVec([call_wrap(ConcatVecEnv, c) for c in chunks], obs_space, act_space,
                                n_copies * int(robots_per_env), NavEnv.metadata)
    return SeededSB3VecEnv(vec, seed)


def check_densities(densities: Sequence[float] | None, max_humans: int | None,
                    overrides: Mapping[str, Any] | None = None) -> None:
    """``ValueError`` naming the problem unless the training crowd levels are valid: densities finite and
    > 0, ``max_humans`` an integer >= 1 given with densities, and no ``n_humans`` override beside them."""
    if densities is not None:
        ds = list(densities)
        if not ds or any(isinstance(d, bool) or not isinstance(d, (int, float, np.integer, np.floating))
                         or not math.isfinite(d) or d <= 0 for d in ds):
            raise ValueError(f"--density must be one or more numbers > 0 (people per m²), got {densities!r}")
        if overrides and overrides.get("n_humans") is not None:
            raise ValueError("--density sets each copy's n_humans: drop --set n_humans (or --density)")
    if max_humans is not None:
        if isinstance(max_humans, bool) or not isinstance(max_humans, (int, np.integer)) or max_humans < 1:
            raise ValueError(f"--max-humans must be an integer >= 1, got {max_humans!r}")
        if densities is None:
            raise ValueError("--max-humans caps the counts of --density levels: give --density too")


def copy_crowds(env_ids: Sequence[str], n_envs: int, densities: Sequence[float] | None = None,
                max_humans: int | None = None, overrides: Mapping[str, Any] | None = None) -> list[dict[str, Any]]:
    """Per-copy NavConfig overrides of :func:`make_mixed_vec_env` (copy ``i``: scene ``i % len(env_ids)``,
    density ``densities[(i // len(env_ids)) % len(densities)]``): ``{"n_humans": n}``, or ``{}`` without
    densities."""
    check_densities(densities, max_humans, overrides)
    n_copies = len(env_ids) * int(n_envs)
    if densities is None:
        return [{} for _ in range(n_copies)]
    from navzoo.benchmark.runner import density_humans
    from navzoo.envs.registry import SCENARIOS
    from navzoo.world.library import get_scene

    areas = {e: float(get_scene(SCENARIOS[e]["scene"]).crowd_area()) for e in dict.fromkeys(env_ids)}
    ds = list(densities)
    return [{"n_humans": density_humans(areas[env_ids[i % len(env_ids)]], ds[(i // len(env_ids)) % len(ds)],
                                        max_humans)} for i in range(n_copies)]


@contextlib.contextmanager
def _sigint_ignored() -> Iterator[None]:
    """Ignore SIGINT in this block, so that processes started in it inherit SIG_IGN (main thread only)."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    old = signal.signal(signal.SIGINT, signal.SIG_IGN)
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, old)


# ---------------------------------------------------------------------------------------------
# Exported policies: state dict + JSON config, loaded without unpickling.


def _weights_to_save(policy: Any, dtype: str) -> dict[str, torch.Tensor]:
    """The state dict without SB3's aliases of a shared extractor (``pi_``/``vf_features_extractor``), cast."""
    if dtype not in _DTYPES:
        raise ValueError(f"weights dtype must be one of {sorted(_DTYPES)}, got {dtype!r}")
    state = policy.state_dict()
    if policy.share_features_extractor:
        state = {k: v for k, v in state.items() if not k.startswith(_ALIASED)}
    return {k: (v.detach().cpu().to(_DTYPES[dtype]) if v.is_floating_point() else v.detach().cpu()).clone()
            for k, v in state.items()}


def _restore_aliases(state: dict[str, torch.Tensor], shared: bool) -> dict[str, torch.Tensor]:
    """Add back the aliased keys of a shared extractor (older exports hold them already) and cast to float32."""
    state = {k: (v.float() if v.is_floating_point() else v) for k, v in state.items()}
    if shared:
        for k, v in list(state.items()):
            if k.startswith("features_extractor."):
                for alias in _ALIASED:
                    state.setdefault(alias + k[len("features_extractor."):], v)
    return state


def export_policy(model: Any, out_dir: str | Path, meta: Mapping[str, Any] | None = None,
                  dtype: str = "float32") -> Path:
    """Write ``policy.pt`` (the actor-critic's state dict, tensors only) and ``config.json``.

    A shared features extractor is stored once (SB3's state dict lists it three times).

    Args:
        model: a trained SB3 PPO (or its ``policy``) whose features extractor is
            :class:`~navzoo.agents.transformer.SpatioTemporalExtractor`.
        out_dir: the folder (created).
        meta: JSON-able entries for ``config.json["training"]`` (scenes, hyperparameters, ...; the
            model's ``num_timesteps`` is added).
        dtype: ``"float32"`` or ``"float16"`` (half the size; loaded back as float32).

    Returns:
        The path of ``config.json``.

    Raises:
        ValueError: for a policy this format cannot rebuild (another extractor, gSDE, ...).
    """
    policy = getattr(model, "policy", model)
    ext = policy.features_extractor if policy.share_features_extractor else policy.pi_features_extractor
    if not isinstance(ext, SpatioTemporalExtractor):
        raise ValueError(f"export_policy needs a SpatioTemporalExtractor policy, got {type(ext).__name__}")
    if getattr(policy, "use_sde", False) or getattr(policy, "squash_output", False):
        raise ValueError("export_policy does not support gSDE or squashed outputs")
    activation = {cls: name for name, cls in _ACTIVATIONS.items()}.get(policy.activation_fn)
    if activation is None:
        raise ValueError(f"unsupported activation {policy.activation_fn}; supported: {sorted(_ACTIVATIONS)}")
    act = policy.action_space
    if not isinstance(act, spaces.Box):
        raise ValueError(f"export_policy needs a Box action space, got {act}")
    arch = policy.net_arch
    arch = {"pi": list(arch), "vf": list(arch)} if isinstance(arch, list) else {k: list(v) for k, v in arch.items()}
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    weights = out / "policy.pt"
    tmp = out / "policy.pt.tmp"
    torch.save(_weights_to_save(policy, dtype), tmp)
    tmp.replace(weights)
    config = {
        "format": POLICY_FORMAT, "version": POLICY_VERSION,
        "observation": {"kind": "flat" if ext.is_flat else "dict", "k_neighbors": ext.k_neighbors,
                        "history": ext.history, "map_cells": ext.map_cells,
                        **({"scan_rays": ext.scan_rays} if ext.scan_rays else {})},
        "action": {"shape": list(act.shape), "low": act.low.tolist(), "high": act.high.tolist()},
        "net_arch": arch, "activation": activation,
        "share_features_extractor": bool(policy.share_features_extractor),
        "features_extractor": {"class": "SpatioTemporalExtractor", "kwargs": ext.config()},
        "weights_file": weights.name, "weights_sha256": sha256_file(weights), "weights_dtype": dtype,
        "training": {**({"num_timesteps": int(model.num_timesteps)} if hasattr(model, "num_timesteps") else {}),
                     **dict(meta or {})},
    }
    path = out / "config.json"
    _write_json(path, config)
    return path


def convert_policy(src_dir: str | Path, dst_dir: str | Path, dtype: str = "float16",
                   meta: Mapping[str, Any] | None = None) -> Path:
    """Re-export an exported policy (e.g. ``runs/robot/policy``) to ``dst_dir`` in ``dtype``, adding ``meta``
    to its ``training`` record; the shipped policies are made this way (float16)."""
    src_cfg = json.loads((Path(src_dir) / "config.json").read_text())
    policy = load_policy(src_dir).model
    path = export_policy(policy, dst_dir, {**src_cfg.get("training", {}), **dict(meta or {})}, dtype=dtype)
    return path


def _obs_converter(kind: str, k: int, t: int, c: int, r: int = 0) -> Callable[[Any], Any]:
    """Convert a batch of robot observations (stacked Dict or flat) into the form the policy takes."""
    layout = flat_layout(k, t, c, r)

    def convert(batch: Any) -> Any:
        if isinstance(batch, Mapping):
            if kind == "dict":
                return batch
            n = len(np.asarray(batch["goal"]).reshape(-1, 5))
            return np.concatenate([np.asarray(batch[key], np.float32).reshape(n, -1) for key in layout], axis=1)
        arr = np.asarray(batch, np.float32)
        if kind == "flat":
            return arr
        arr = arr.reshape(-1, arr.shape[-1])
        return {key: arr[:, s:e].reshape(-1, *shape) for key, (s, e, shape) in layout.items()}

    return convert


def shipped_policy_available(model_dir: str | Path | None = None) -> bool:
    """Whether ``model_dir`` (default ``policies/transformer_ppo``) holds ``config.json`` and its weights."""
    d = Path(model_dir) if model_dir is not None else DEFAULT_POLICY_DIR
    if not (d / "config.json").is_file():
        return False
    try:
        name = json.loads((d / "config.json").read_text()).get("weights_file", "policy.pt")
    except (json.JSONDecodeError, AttributeError):
        return False
    return isinstance(name, str) and (d / Path(name).name).is_file()


def load_policy(model_dir: str | Path | None = None, deterministic: bool = True, device: str = "cpu",
                name: str = "transformer-ppo") -> SB3Policy:
    """Rebuild an exported policy from ``config.json`` and load ``policy.pt`` (sha256 checked, weights only).

    The returned :class:`~navzoo.agents.policy.SB3Policy` acts for the robots from their observations,
    flat or Dict (converted to the form the network was trained on). A policy trained with subgoals
    (``--robot-subgoal``) comes wrapped in a :class:`~navzoo.envs.subgoal.GuidedPolicy`, which plans
    the subgoals itself in envs that do not.

    Args:
        model_dir: the folder written by :func:`export_policy` (default ``policies/transformer_ppo``).
        deterministic: act with the mean action.
        device: torch device of the network.
        name: the policy's label in reports.

    Raises:
        FileNotFoundError: when the folder lacks ``config.json`` or the weights (says how to train them).
        ValueError: when the weights do not match the recorded sha256, or the config or the weights do
            not describe this model.
    """
    from stable_baselines3.common.policies import ActorCriticPolicy, MultiInputActorCriticPolicy

    d = Path(model_dir) if model_dir is not None else DEFAULT_POLICY_DIR
    cfg_path = d / "config.json"
    if not cfg_path.is_file():
        raise FileNotFoundError(f"no trained transformer-ppo policy in {d} (config.json missing); train one with "
                                f"`{TRAIN_COMMAND}`")
    try:
        cfg = json.loads(cfg_path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{cfg_path} is not valid JSON: {err}") from err
    if cfg.get("format") != POLICY_FORMAT or cfg.get("version") != POLICY_VERSION:
        raise ValueError(f"{cfg_path}: expected format {POLICY_FORMAT!r} version {POLICY_VERSION}, got "
                         f"{cfg.get('format')!r} version {cfg.get('version')!r}")
    weights = d / Path(str(cfg.get("weights_file", "policy.pt"))).name
    if not weights.is_file():
        raise FileNotFoundError(f"{weights} is missing (named in {cfg_path}); train with `{TRAIN_COMMAND}`")
    if cfg.get("weights_sha256") != sha256_file(weights):
        raise ValueError(f"{weights} does not match the sha256 in {cfg_path} (corrupted or replaced)")
    try:
        ob = cfg["observation"]
        k, t, c, kind = int(ob["k_neighbors"]), int(ob["history"]), int(ob["map_cells"]), ob["kind"]
        r = int(ob.get("scan_rays", 0))
        dict_space = observation_dict_space(k, t, c, r)
        obs_space = spaces.flatten_space(dict_space) if kind == "flat" else dict_space
        a = cfg["action"]
        act_space = spaces.Box(np.array(a["low"], np.float32), np.array(a["high"], np.float32), dtype=np.float32)
        if kind not in ("flat", "dict") or list(act_space.shape) != list(a["shape"]):
            raise ValueError(f"bad observation kind {kind!r} or action shape {a['shape']}")
        if cfg["features_extractor"]["class"] != "SpatioTemporalExtractor":
            raise ValueError(f"unknown features extractor {cfg['features_extractor']['class']!r}")
        cls = ActorCriticPolicy if kind == "flat" else MultiInputActorCriticPolicy
        policy = cls(obs_space, act_space, lr_schedule=lambda _: 0.0, net_arch=cfg["net_arch"],
                     activation_fn=_ACTIVATIONS[cfg["activation"]],
                     features_extractor_class=SpatioTemporalExtractor,
                     features_extractor_kwargs=dict(cfg["features_extractor"]["kwargs"]),
                     share_features_extractor=bool(cfg["share_features_extractor"]))
    except (KeyError, TypeError) as err:
        raise ValueError(f"{cfg_path} does not describe a transformer-ppo policy: {err!r}") from err
    try:
        state = torch.load(weights, map_location="cpu", weights_only=True)
        policy.load_state_dict(_restore_aliases(state, bool(cfg["share_features_extractor"])))
    except (RuntimeError, TypeError, AttributeError) as err:
        raise ValueError(f"{weights} does not fit the architecture in {cfg_path}: {err}") from err
    policy = policy.to(device)
    policy.set_training_mode(False)
    env_overrides = (cfg.get("training") or {}).get("env_overrides") or {}
    # --forward-only is refused for holonomic robots, so such a policy drives (v, omega) of a diff-drive one
    kinematics = ("diff_drive" if (cfg.get("training") or {}).get("forward_only")
                  else (env_overrides.get("robot") or {}).get("kinematics"))
    sb3 = SB3Policy(policy, deterministic=deterministic, obs_transform=_obs_converter(kind, k, t, c, r), name=name,
                    kinematics=kinematics if kinematics in ("diff_drive", "holonomic") else None)
    lookahead = env_overrides.get("robot_subgoal")
    out: Any = sb3
    if lookahead is not None:
        from navzoo.envs.subgoal import GuidedPolicy

        if not (isinstance(lookahead, (int, float)) and math.isfinite(lookahead) and lookahead > 0):
            raise ValueError(f"{cfg_path}: training.env_overrides.robot_subgoal must be a number > 0, got {lookahead!r}")
        out = GuidedPolicy(sb3, float(lookahead), flat_layout(k, t, c, r))
    if r:
        from navzoo.envs.config import NavConfig
        from navzoo.envs.scan import ScanPolicy

        scan_range = env_overrides.get("scan_range", NavConfig.__dataclass_fields__["scan_range"].default)
        if not (isinstance(scan_range, (int, float)) and math.isfinite(scan_range) and scan_range > 0):
            raise ValueError(f"{cfg_path}: training.env_overrides.scan_range must be a number > 0, got {scan_range!r}")
        out = ScanPolicy(out, r, float(scan_range))
    return out


def init_weights_from(policy: Any, model_dir: str | Path) -> list[str]:
    """Load the weights of the exported policy in ``model_dir`` into ``policy`` (an SB3 actor-critic).

    The two must be the same network, except that ``policy`` may have a range-scan input
    (``scan_rays``) that the exported one lacks: that branch keeps its initial weights, whose zero
    output layer leaves the loaded behaviour unchanged. Returns the names of the parameters that were
    not loaded. Raises ``ValueError`` for any other difference, naming it.
    """
    start = load_policy(model_dir).model
    ext_new, ext_old = policy.features_extractor, start.features_extractor
    same = (ext_new.k_neighbors, ext_new.history, ext_new.map_cells) == (ext_old.k_neighbors, ext_old.history,
                                                                         ext_old.map_cells)
    if not same or (ext_old.scan_rays and ext_old.scan_rays != ext_new.scan_rays):
        raise ValueError(f"{model_dir}: its observation space {start.observation_space} does not fit this "
                         f"model's {policy.observation_space}")
    try:
        missing, unexpected = policy.load_state_dict(start.state_dict(), strict=False)
    except RuntimeError as err:
        raise ValueError(f"{model_dir} has another network shape than this model: {err}") from err
    bad = [k for k in missing if ".scan_encoder." not in k]
    if bad or unexpected:
        raise ValueError(f"{model_dir} does not fit this model: missing {bad}, unexpected {list(unexpected)}")
    if missing:  # SB3's orthogonal initialisation overwrote the extractor's zero output layer: zero it again
        with torch.no_grad():
            for module in policy.modules():
                if isinstance(module, SpatioTemporalExtractor) and module.scan_rays:
                    module.scan_encoder[-1].weight.zero_()
                    module.scan_encoder[-1].bias.zero_()
    return list(missing)


def register_transformer_ppo(model_dir: str | Path | None = None) -> None:
    """Register ``"transformer-ppo"`` with :func:`navzoo.agents.baselines.make_policy`, loading from
    ``model_dir`` (default: ``$NAVZOO_TRANSFORMER_PPO_DIR`` or ``policies/transformer_ppo``); see
    :func:`navzoo.agents.baselines.register_learned_policy`."""
    from navzoo.agents.baselines import register_learned_policy

    register_learned_policy("transformer-ppo", model_dir)


# ---------------------------------------------------------------------------------------------
# Training.


@dataclass(frozen=True)
class TrainArgs:
    """Options of ``navzoo train robot`` (one per flag; validated on construction)."""

    out: str = "runs/robot"
    scenes: tuple[str, ...] = TRAIN_SCENES
    n_envs: int = 1
    num_cpus: int = 0
    robots_per_env: int = 1
    total_steps: int = 1_000_000
    n_steps: int = 32
    n_epochs: int = 6
    batch_size: int | None = None  # None: 96 (the paper's 3 scenes x 32 steps), at most one rollout
    lr: float = 3e-4
    gamma: float = 0.99
    ent_coef: float = 0.0
    target_kl: float | None = None
    forward_only: bool = False  # policy's speed command in [0, 1] (no reversing; diff-drive robots only)
    init_from: str | None = None  # an exported policy folder whose weights start a new run (fresh optimiser)
    features_dim: int = 128
    heads: int = 4
    blocks: int = 3
    net_arch: tuple[int, ...] = (128, 128)
    device: str = "auto"
    seed: int = 0
    threads: int | None = None
    save_every: int = 10_000
    keep: int = 3
    time_limit_s: float | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # NavConfig overrides (--kinematics, ..., --set)
    crowd_policy: str | None = None  # "rllib:PATH": a frozen learned crowd instead of the scene's crowd model
    densities: tuple[float, ...] | None = None  # crowd density levels the copies cycle through (people/m²)
    max_humans: int | None = None  # cap on those levels' counts

    def __post_init__(self) -> None:
        for name in ("n_envs", "robots_per_env", "total_steps", "n_epochs", "features_dim", "heads", "blocks",
                     "save_every", "keep"):
            v = getattr(self, name)
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ValueError(f"--{name.replace('_', '-')} must be an integer >= 1, got {v!r}")
        if not isinstance(self.num_cpus, int) or self.num_cpus < 0:
            raise ValueError(f"--num-cpus must be an integer >= 0, got {self.num_cpus!r}")
        if self.n_steps < 2:
            raise ValueError(f"--n-steps must be >= 2, got {self.n_steps}")
        rollout = self.n_steps * self.num_envs
        if self.batch_size is None:
            object.__setattr__(self, "batch_size", min(96, rollout))
        if not 2 <= self.batch_size <= rollout:
            raise ValueError(f"--batch-size must be in [2, n_steps x envs = {self.n_steps} x {self.num_envs} = "
                             f"{rollout}], got {self.batch_size}")
        for name, lo, hi in (("lr", 0.0, math.inf), ("gamma", 0.0, 1.0)):
            v = getattr(self, name)
            if not (math.isfinite(v) and lo < v <= hi):
                raise ValueError(f"--{name} must be in ({lo}, {hi}], got {v!r}")
        if not (math.isfinite(self.ent_coef) and self.ent_coef >= 0):
            raise ValueError(f"--ent-coef must be a finite number >= 0, got {self.ent_coef!r}")
        if self.target_kl is not None and not (math.isfinite(self.target_kl) and self.target_kl > 0):
            raise ValueError(f"--target-kl must be a number > 0, got {self.target_kl!r}")
        if self.features_dim % self.heads:
            raise ValueError(f"--features-dim ({self.features_dim}) must be divisible by --heads ({self.heads})")
        if not self.net_arch or any(w < 1 for w in self.net_arch):
            raise ValueError(f"--net-arch must be positive widths such as 128,128, got {self.net_arch!r}")
        if self.device not in ("cpu", "cuda", "auto"):
            raise ValueError(f"--device must be cpu, cuda or auto, got {self.device!r}")
        if self.device == "cuda" and not torch.cuda.is_available():
            raise ValueError("--device cuda: CUDA is not available on this machine (use cpu or auto)")
        if self.threads is not None and self.threads < 1:
            raise ValueError(f"--threads must be >= 1, got {self.threads}")
        if self.time_limit_s is not None and not (math.isfinite(self.time_limit_s) and self.time_limit_s > 0):
            raise ValueError(f"--time-limit-s must be a number > 0, got {self.time_limit_s!r}")
        from navzoo.envs.registry import SCENARIOS

        if self.crowd_policy is not None:
            check_crowd_policy(self.crowd_policy)
        check_densities(self.densities, self.max_humans, self.extra)
        unknown = [s for s in self.scenes if s not in SCENARIOS]
        if unknown or not self.scenes:
            raise ValueError(f"unknown scene(s) {unknown or '(none given)'}; use scene names or ids such as "
                             f"{', '.join(_scene_names())}")
        if self.forward_only:
            kin = (self.extra.get("robot") or {}).get("kinematics")
            holo = [s for s in self.scenes
                    if (kin or getattr(SCENARIOS[s].get("robot"), "kinematics", "diff_drive")) != "diff_drive"]
            if holo:
                raise ValueError(f"--forward-only needs diff-drive robots; {holo} have holonomic ones "
                                 "(add --kinematics diff_drive)")

    @property
    def num_envs(self) -> int:
        """Vector entries (robots stepped in parallel)."""
        return len(self.scenes) * self.n_envs * self.robots_per_env

    def model_options(self) -> dict[str, Any]:
        """The options that fix the network's shape (must match to resume)."""
        return {"features_dim": self.features_dim, "heads": self.heads, "blocks": self.blocks,
                "net_arch": list(self.net_arch)}


def _scene_names() -> list[str]:
    from navzoo.envs.registry import SCENARIOS

    return [SCENARIOS[i]["scene"] for i in SCENARIOS]


def parse_scenes(text: str) -> tuple[str, ...]:
    """``"station,home"`` or ids ``"navzoo/Station-v0,..."`` → registered ids (unknown names kept, to be reported)."""
    from navzoo.envs.registry import SCENARIOS

    by_name = {SCENARIOS[i]["scene"]: i for i in SCENARIOS}
    return tuple(by_name.get(s.strip().lower(), s.strip()) for s in text.split(",") if s.strip())


def latest_checkpoint(out: str | Path) -> tuple[Path, dict[str, Any]] | None:
    """The newest checkpoint under ``out/checkpoints`` whose weights match its sha256, or None.

    A checkpoint that fails its check (e.g. a run killed while writing) is reported on stderr and
    skipped for the previous one.
    """
    ckdir = Path(out) / "checkpoints"
    if not ckdir.is_dir():
        return None
    for meta_path in sorted(ckdir.glob("step_*.json"), reverse=True):
        try:
            meta = json.loads(meta_path.read_text())
            weights = meta_path.with_suffix(".pt")
            if weights.is_file() and meta.get("sha256") == sha256_file(weights):
                return weights, meta
        except (json.JSONDecodeError, OSError, AttributeError):
            pass
        print(f"navzoo train robot: skipping invalid checkpoint {meta_path}", file=sys.stderr)
    return None


def check_resume(args: TrainArgs) -> tuple[Path, dict[str, Any]] | None:
    """The checkpoint a run with ``args`` resumes from (None: a fresh start).

    Raises:
        ValueError: when that checkpoint was trained with another network shape.
    """
    found = latest_checkpoint(args.out)
    if found and found[1].get("model") != args.model_options():
        raise ValueError(f"the checkpoint {found[0]} was trained with {found[1].get('model')}, not "
                         f"{args.model_options()}; pass the same model options or another --out")
    return found


def _save_checkpoint(model: Any, args: TrainArgs, keep: int) -> Path:
    ckdir = Path(args.out) / "checkpoints"
    ckdir.mkdir(parents=True, exist_ok=True)
    n = int(model.num_timesteps)
    weights = ckdir / f"step_{n:012d}.pt"
    tmp = weights.with_name(weights.name + ".tmp")
    torch.save({"policy": model.policy.state_dict(), "optimizer": model.policy.optimizer.state_dict()}, tmp)
    tmp.replace(weights)
    _write_json(weights.with_suffix(".json"), {
        "num_timesteps": n, "n_updates": int(model._n_updates), "sha256": sha256_file(weights),
        "model": args.model_options(), "scenes": list(args.scenes), "num_envs": args.num_envs,
        "saved_at": time.strftime("%Y-%m-%dT%H:%M:%S"),
    })
    for old in sorted(ckdir.glob("step_*.json"))[:-keep]:
        old.unlink(missing_ok=True)
        old.with_suffix(".pt").unlink(missing_ok=True)
    return weights


class _TrainCallback(BaseCallback):
    """Per-rollout JSON lines, periodic checkpoints, stop on SIGINT or the time limit."""

    def __init__(self, args: TrainArgs, t_start: float, stop: dict[str, Any], log: Any) -> None:
        super().__init__()
        self.args, self.t_start, self.stop, self.log = args, t_start, stop, log
        self.events: deque[str] = deque(maxlen=100)
        self._last_event: dict[int, str] = {}
        self._last_saved = 0
        self._t_learn = time.perf_counter()
        self._steps0 = 0
        self.rollout_end = 0  # num_timesteps at the end of the last whole rollout

    def _on_training_start(self) -> None:
        self._t_learn = time.perf_counter()
        self._steps0 = self._last_saved = self.rollout_end = int(self.model.num_timesteps)

    def _on_step(self) -> bool:
        for i, (info, done) in enumerate(zip(self.locals["infos"], self.locals["dones"], strict=True)):
            event = info.get("event")
            if event and event != "running":
                self._last_event[i] = event
            if done:
                self.events.append(self._last_event.pop(i, "unknown"))
        if self.args.time_limit_s is not None and time.perf_counter() - self.t_start >= self.args.time_limit_s:
            self.stop["reason"] = self.stop["reason"] or "time_limit"
        return self.stop["reason"] is None

    def _on_rollout_end(self) -> None:
        n = self.rollout_end = int(self.model.num_timesteps)
        elapsed = time.perf_counter() - self._t_learn
        eps = list(self.model.ep_info_buffer or [])
        ev = list(self.events)
        row: dict[str, Any] = {
            "timesteps": n, "fps": round((n - self._steps0) / max(elapsed, 1e-9), 2),
            "elapsed_s": round(time.perf_counter() - self.t_start, 1), "learn_s": round(elapsed, 3),
            "episodes": len(ev),
            "ep_rew_mean": round(float(np.mean([e["r"] for e in eps])), 4) if eps else None,
            "ep_len_mean": round(float(np.mean([e["l"] for e in eps])), 2) if eps else None,
            "success_rate": round(ev.count("goal") / len(ev), 4) if ev else None,
            "collision_rate": round(sum(e.startswith("collision") for e in ev) / len(ev), 4) if ev else None,
        }
        for key in ("train/value_loss", "train/policy_gradient_loss", "train/entropy_loss", "train/approx_kl"):
            if key in self.model.logger.name_to_value:
                row[key.split("/")[1]] = round(float(self.model.logger.name_to_value[key]), 6)
        line = json.dumps(row)
        print(line, flush=True)
        self.log.write(line + "\n")
        self.log.flush()
        for key in ("success_rate", "collision_rate"):
            if row[key] is not None:
                self.logger.record(f"rollout/{key}", row[key])
        if n - self._last_saved >= self.args.save_every:
            _save_checkpoint(self.model, self.args, self.args.keep)
            self._last_saved = n


def train(args: TrainArgs) -> dict[str, Any]:
    """Train (resuming from ``args.out``) and export the policy; returns a summary.

    Returns:
        ``{"timesteps", "reason" ("total_steps" | "time_limit" | "interrupted"), "checkpoint", "policy", ...}``.

    Raises:
        ValueError: when the checkpoint in ``args.out`` was trained with another network shape.
    """
    from stable_baselines3 import PPO

    t_start = time.perf_counter()
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    if args.threads:
        torch.set_num_threads(args.threads)
    found = check_resume(args)
    done = int(found[1]["num_timesteps"]) if found else 0
    summary: dict[str, Any] = {"out": str(out), "resumed_from": done if found else None}
    if done >= args.total_steps:
        print(json.dumps({"already_done": done, "total_steps": args.total_steps}), flush=True)
        summary["checkpoint"] = str(found[0]) if found else None
    vec = make_mixed_vec_env(args.scenes, args.n_envs, seed=args.seed + done, num_cpus=args.num_cpus,
                             robots_per_env=args.robots_per_env, crowd_policy=args.crowd_policy,
                             densities=args.densities, max_humans=args.max_humans, **args.extra)
    if args.forward_only:  # SB3 clips the policy's actions to this box (speed >= 0) before the env sees them
        vec.action_space = FORWARD_ONLY_ACTIONS
    with warnings.catch_warnings():  # SuperSuit's vector env has no get_attr: SB3 warns, then uses None
        warnings.filterwarnings("ignore", message="The `render_mode` attribute is not defined")
        vec = VecCheckNan(VecMonitor(vec), raise_exception=True)
    stop: dict[str, Any] = {"reason": None}
    old_handler = None
    log = open(out / "metrics.jsonl", "a")
    try:
        kwargs = transformer_policy_kwargs(features_dim=args.features_dim, n_heads=args.heads, n_blocks=args.blocks,
                                           net_arch=args.net_arch,
                                           k_neighbors=args.extra.get("k_neighbors"), history=args.extra.get("history"),
                                           scan_rays=args.extra.get("scan_rays"))
        model = PPO("MlpPolicy", vec, n_steps=args.n_steps, n_epochs=args.n_epochs, batch_size=args.batch_size,
                    learning_rate=args.lr, gamma=args.gamma, ent_coef=args.ent_coef, target_kl=args.target_kl,
                    policy_kwargs=kwargs,
                    tensorboard_log=str(out / "tb"), device=args.device, seed=args.seed + done, verbose=0)
        if found:
            state = torch.load(found[0], map_location=model.device, weights_only=True)
            model.policy.load_state_dict(state["policy"])
            model.policy.optimizer.load_state_dict(state["optimizer"])
            model.num_timesteps = done
            model._n_updates = int(found[1].get("n_updates", 0))
            print(json.dumps({"resumed_from": str(found[0]), "timesteps": done}), flush=True)
        elif args.init_from:
            try:
                init_weights_from(model.policy, args.init_from)
            except ValueError as err:
                raise ValueError(f"--init-from {args.init_from} (model options {args.model_options()}): {err}") from err
            print(json.dumps({"initialised_from": str(args.init_from)}), flush=True)
        if done < args.total_steps:

            def _on_sigint(signum: int, frame: Any) -> None:
                stop["reason"] = "interrupted"
                signal.signal(signal.SIGINT, signal.default_int_handler)  # a second Ctrl-C aborts

            old_handler = signal.signal(signal.SIGINT, _on_sigint)
            callback = _TrainCallback(args, t_start, stop, log)
            model.learn(args.total_steps - done, callback=callback, reset_num_timesteps=not found,
                        tb_log_name="transformer_ppo")
            if model.num_timesteps > callback.rollout_end:
                # Stopped inside a rollout (time limit, Ctrl-C): those steps were never trained on. Count
                # only the whole rollouts, so that a resumed run collects exactly its budget in whole ones.
                summary["discarded_partial_rollout_steps"] = int(model.num_timesteps - callback.rollout_end)
                model.num_timesteps = callback.rollout_end
            summary["checkpoint"] = str(_save_checkpoint(model, args, args.keep))
        meta = {"scenes": list(args.scenes), "n_steps": args.n_steps, "n_epochs": args.n_epochs,
                "batch_size": args.batch_size, "lr": args.lr, "gamma": args.gamma, "seed": args.seed,
                "env_overrides": args.extra, "forward_only": args.forward_only, "target_kl": args.target_kl,
                "init_from": args.init_from, **({"crowd_policy": args.crowd_policy} if args.crowd_policy else {}),
                **({"densities": list(args.densities), "max_humans": args.max_humans} if args.densities else {}),
                "trained_with": "navzoo train robot"}
        summary["policy"] = str(export_policy(model, out / "policy", meta).parent)
        summary["timesteps"] = int(model.num_timesteps)
        summary["reason"] = stop["reason"] or "total_steps"
        summary["elapsed_s"] = round(time.perf_counter() - t_start, 1)
    finally:
        if old_handler is not None:
            signal.signal(signal.SIGINT, old_handler)
        log.close()
        vec.close()
    print(json.dumps(summary), flush=True)
    return summary


# ---------------------------------------------------------------------------------------------
# Command line.


def _tuple_of(kind: type, example: str) -> Callable[[str], tuple[Any, ...]]:
    """An argparse type: comma-separated ``kind`` values (an error names ``example``)."""

    def parse(text: str) -> tuple[Any, ...]:
        try:
            return tuple(kind(v) for v in text.split(",") if v.strip())
        except ValueError as exc:
            raise argparse.ArgumentTypeError(f"expected comma-separated values such as {example}, got {text!r}") from exc

    return parse


_int_tuple = _tuple_of(int, "128,128")
_float_tuple = _tuple_of(float, "0.05,0.15,0.3")


def add_arguments(parser: argparse.ArgumentParser) -> argparse.ArgumentParser:
    """The options of ``navzoo train robot``."""
    d = TrainArgs()
    p = parser
    p.add_argument("--out", default=d.out, help="output folder: checkpoints, tb/, metrics.jsonl, policy/ (resumes)")
    p.add_argument("--scenes", default="station,home,grocery",
                   help="comma-separated scene names or ids mixed in the vector env (default: the paper's three)")
    p.add_argument("--n-envs", type=int, default=d.n_envs, help="env copies per scene")
    p.add_argument("--num-cpus", type=int, default=d.num_cpus, help="worker processes for the copies (0: none)")
    p.add_argument("--robots-per-env", type=int, default=d.robots_per_env, help="robots per env copy")
    p.add_argument("--kinematics", default=None, choices=["diff_drive", "holonomic"],
                   help="robot kinematics for every scene (default: each scene's own; the CrowdNav presets are "
                        "holonomic, the others diff_drive)")
    p.add_argument("--robot-subgoal", type=float, default=None, metavar="L",
                   help="robots observe an A* subgoal at most L m ahead instead of their goal (NavConfig.robot_subgoal; "
                        "for multi-room scenes); the exported policy keeps its own planner, so it runs in any env")
    p.add_argument("--robot-progress", default=None, choices=["euclidean", "geodesic"],
                   help="distance behind the reward's progress term (NavConfig.robot_progress; default: euclidean, "
                        "the paper)")
    p.add_argument("--wall-proximity", type=float, default=None, metavar="M",
                   help="proximity-penalty distance to walls and obstacles (NavConfig.wall_proximity; default: the "
                        "paper's 0.9 m, as to people)")
    p.add_argument("--scan-rays", type=int, default=None, metavar="R",
                   help="robots also observe a planar range scan of the static scene with R rays (NavConfig.scan_rays; "
                        "exact wall distances, finer than the occupancy crop); the exported policy scans by itself in "
                        "envs without it")
    p.add_argument("--scan-range", type=float, default=None, metavar="M",
                   help="range of that scan (NavConfig.scan_range, default 4 m)")
    p.add_argument("--crowd-policy", default=None, metavar="rllib:PATH",
                   help="the pedestrians are a crowd trained with RLlib (navzoo train joint --humans learn), frozen, "
                        "instead of the scene's crowd model (needs navzoo[ray])")
    p.add_argument("--density", type=_float_tuple, default=None, metavar="D[,D...]",
                   help="train at these crowd densities (people per m² of each scene's crowd area), as navzoo "
                        "benchmark --density: each scene's copies cycle through them (default: each scene's own "
                        "crowd)")
    p.add_argument("--max-humans", type=int, default=None, metavar="N",
                   help="cap on the people of a --density level (as navzoo benchmark --max-humans)")
    p.add_argument("--set", dest="env_set", action="append", default=[], metavar="KEY=VALUE",
                   help="further NavConfig override for every scene (JSON value), e.g. --set human_at_goal=new_goal")
    p.add_argument("--total-steps", type=int, default=d.total_steps, help="total robot steps to reach (with resumed)")
    p.add_argument("--n-steps", type=int, default=d.n_steps, help="rollout length per vector entry (paper: 32)")
    p.add_argument("--n-epochs", type=int, default=d.n_epochs, help="PPO epochs per rollout (paper: 6)")
    p.add_argument("--batch-size", type=int, default=None,
                   help="PPO minibatch size (default 96, the paper's 3 scenes x 32 steps, at most a rollout)")
    p.add_argument("--lr", type=float, default=d.lr, help="Adam learning rate")
    p.add_argument("--gamma", type=float, default=d.gamma)
    p.add_argument("--ent-coef", type=float, default=d.ent_coef)
    p.add_argument("--target-kl", type=float, default=None, help="stop an update's epochs early past this KL (SB3)")
    p.add_argument("--init-from", default=None,
                   help="start a new run from an exported policy folder (e.g. policies/transformer_ppo_crowdnav); "
                        "the optimiser starts fresh; ignored when --out holds a checkpoint")
    p.add_argument("--forward-only", action="store_true",
                   help="diff-drive policies command speeds in [0, max] only (no reversing), as CrowdNav's unicycle")
    p.add_argument("--features-dim", type=int, default=d.features_dim, help="transformer width D (= features)")
    p.add_argument("--heads", type=int, default=d.heads, help="attention heads")
    p.add_argument("--blocks", type=int, default=d.blocks, help="factorised spatio-temporal blocks (paper: 3)")
    p.add_argument("--net-arch", type=_int_tuple, default=d.net_arch, help="actor and critic MLP widths, e.g. 128,128")
    p.add_argument("--device", default=d.device, choices=["cpu", "cuda", "auto"])
    p.add_argument("--seed", type=int, default=d.seed)
    p.add_argument("--threads", type=int, default=None, help="torch threads (1 is fastest on a small shared CPU)")
    p.add_argument("--save-every", type=int, default=d.save_every, help="checkpoint every this many timesteps")
    p.add_argument("--keep", type=int, default=d.keep, help="checkpoints kept")
    p.add_argument("--time-limit-s", type=float, default=None, help="stop (and save) after this wall time")
    return parser


def _env_overrides(args: argparse.Namespace) -> dict[str, Any]:
    """NavConfig overrides named by ``navzoo train robot``'s options (validated by NavConfig)."""
    from navzoo.envs.config import NavConfig, parse_overrides

    extra: dict[str, Any] = {}
    if getattr(args, "kinematics", None):
        extra["robot"] = {"kinematics": args.kinematics}
    for opt in ("robot_subgoal", "robot_progress", "wall_proximity", "scan_rays", "scan_range"):
        if getattr(args, opt, None) is not None:
            extra[opt] = getattr(args, opt)
    for key, value in parse_overrides(getattr(args, "env_set", None)).items():
        if key in ("flat_obs", "n_robots", "scene"):
            raise ValueError(f"--set {key}: navzoo train robot sets it (use --robots-per-env / --scenes)")
        if key == "robot" or key in extra:
            raise ValueError(f"--set {key}: use its own option (--kinematics, --robot-subgoal, ...)")
        extra[key] = value
    if extra:
        NavConfig.from_dict({k: v for k, v in extra.items() if k != "robot"})  # a bad key or value fails here, named
    return extra


def run_cli(args: argparse.Namespace, error: Callable[[str], Any] | None = None) -> int:
    """Run ``navzoo train robot`` from parsed options.

    Bad options go to ``error`` (e.g. ``parser.error``, which exits with status 2) or, without it,
    raise ``ValueError``. Returns 0, or 130 when interrupted (after saving).
    """
    try:
        targs = TrainArgs(
            out=args.out, scenes=parse_scenes(args.scenes), n_envs=args.n_envs, num_cpus=args.num_cpus,
            robots_per_env=args.robots_per_env, total_steps=args.total_steps, n_steps=args.n_steps,
            n_epochs=args.n_epochs, batch_size=args.batch_size, lr=args.lr, gamma=args.gamma,
            ent_coef=args.ent_coef, target_kl=getattr(args, "target_kl", None),
            forward_only=bool(getattr(args, "forward_only", False)), init_from=getattr(args, "init_from", None),
            features_dim=args.features_dim, heads=args.heads, blocks=args.blocks,
            net_arch=tuple(args.net_arch), device=args.device, seed=args.seed, threads=args.threads,
            save_every=args.save_every, keep=args.keep, time_limit_s=args.time_limit_s,
            extra=_env_overrides(args), crowd_policy=getattr(args, "crowd_policy", None),
            densities=getattr(args, "density", None), max_humans=getattr(args, "max_humans", None))
        check_resume(targs)
    except ValueError as exc:
        if error is not None:
            error(str(exc))
        raise
    summary = train(targs)
    return 130 if summary.get("reason") == "interrupted" else 0


def main(argv: Sequence[str] | None = None) -> int:
    """``python -m navzoo.agents.robot_train``."""
    parser = add_arguments(argparse.ArgumentParser(prog="navzoo train robot", description=__doc__.split("\n\n")[0]))
    args = parser.parse_args(argv)
    return run_cli(args, parser.error)


if __name__ == "__main__":
    raise SystemExit(main())


def plot_learning_curve(metrics: str | Path, path_png: str | Path, title: str = "transformer + PPO",
                        marks: Sequence[int] = ()) -> Path:
    """Plot ``metrics.jsonl`` of a run (also several resumed sessions appended): mean episode reward and
    success/collision rates (last 100 episodes) against robot steps; vertical lines at ``marks`` (steps)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from navzoo.world.plot import save_figure

    rows = [json.loads(line) for line in Path(metrics).read_text().splitlines() if line.strip()]
    rows = [r for r in rows if r.get("ep_rew_mean") is not None and r.get("episodes", 0) >= 20]
    if not rows:
        raise ValueError(f"{metrics}: no rollout line with at least 20 finished episodes")
    steps = np.array([r["timesteps"] for r in rows], float)
    fig, (ax1, ax2) = plt.subplots(1, 2, figsize=(11, 3.8))
    ax1.plot(steps, [r["ep_rew_mean"] for r in rows], lw=1)
    ax1.set_xlabel("robot steps")
    ax1.set_ylabel("mean episode reward (last 100)")
    ax2.plot(steps, [r["success_rate"] for r in rows], lw=1, label="success")
    ax2.plot(steps, [r["collision_rate"] for r in rows], lw=1, label="collision")
    ax2.set_xlabel("robot steps")
    ax2.set_ylabel("rate (last 100 training episodes)")
    ax2.set_ylim(0, 1)
    ax2.legend(loc="center right")
    for ax in (ax1, ax2):
        for m in marks:
            ax.axvline(m, color="grey", ls=":", lw=1)
        ax.grid(alpha=0.3)
    fig.suptitle(title)
    fig.tight_layout()
    return save_figure(fig, path_png, dpi=110)
