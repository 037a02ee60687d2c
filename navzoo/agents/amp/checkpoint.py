"""Checkpoints and exported policies of the AMP learner: tensors + JSON, never pickled objects.

Training checkpoint — a directory ``<ckpt_dir>/ckpt_<iteration:08d>/`` holding

- ``state.pt``: ``torch.save`` of a nested ``dict`` whose leaves are tensors (and plain ints/floats/
  strings inside optimiser ``state_dict``\\ s), read back with ``torch.load(weights_only=True)``;
- ``meta.json``: format tag and version, the config, step counters, the numpy RNG state, JSON parts
  of the env state, and the sha256 of ``state.pt``.

A checkpoint is written into a hidden temporary directory, flushed to disk, and renamed into place
with ``os.replace``; then ``latest.json`` is replaced the same way. A crash at any point leaves the
previous checkpoint and pointer intact (at worst a stale ``.tmp-*`` directory, ignored and cleaned up
later).

Exported policy — a directory with ``policy.pt`` (flat ``dict[str, Tensor]``: actor weights and the
observation normaliser) and ``config.json`` (dims, architecture, normaliser settings, sha256 of
``policy.pt``). :func:`load_policy` rebuilds a numpy-in/numpy-out deterministic policy from it.
"""

from __future__ import annotations

import hashlib
import json
import os
import re
import shutil
import time
import warnings
from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import torch

from navzoo.agents.amp.networks import Actor
from navzoo.agents.amp.normalizer import RunningMeanStd

CHECKPOINT_FORMAT = "navzoo-amp-checkpoint"
CHECKPOINT_VERSION = 1
POLICY_FORMAT = "navzoo-amp-policy"
POLICY_VERSION = 1
STATE_FILE = "state.pt"
META_FILE = "meta.json"
LATEST_FILE = "latest.json"
POLICY_WEIGHTS = "policy.pt"
POLICY_CONFIG = "config.json"
_CKPT_RE = re.compile(r"^ckpt_(\d{8})$")


class CheckpointError(RuntimeError):
    """A checkpoint or exported policy that cannot be trusted (missing, corrupted, foreign, mismatched)."""


def sha256_file(path: str | os.PathLike[str]) -> str:
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            h.update(chunk)
    return h.hexdigest()


def _fsync_dir(path: Path) -> None:
    try:
        fd = os.open(path, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


def _write_bytes_synced(path: Path, data: bytes) -> None:
    with open(path, "wb") as f:
        f.write(data)
        f.flush()
        os.fsync(f.fileno())


def atomic_write_text(path: str | os.PathLike[str], text: str) -> None:
    """Write a text file so that readers see either the old or the new content, never a mix."""
    path = Path(path)
    tmp = path.with_name(f".tmp-{path.name}-{os.getpid()}")
    _write_bytes_synced(tmp, text.encode())
    os.replace(tmp, path)
    _fsync_dir(path.parent)


def _torch_save_synced(obj: Any, path: Path) -> None:
    with open(path, "wb") as f:
        torch.save(obj, f)
        f.flush()
        os.fsync(f.fileno())


def _load_tensors(path: Path) -> Any:
    try:
        return torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # torch raises UnpicklingError, RuntimeError, EOFError, ...
        raise CheckpointError(
            f"{path}: not a tensor-only torch file ({type(e).__name__}: {str(e).splitlines()[0][:200]})"
        ) from e


def _read_json(path: Path, what: str) -> dict[str, Any]:
    if not path.is_file():
        raise CheckpointError(f"{path}: missing {what}")
    try:
        data = json.loads(path.read_text())
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{path}: {what} is not valid JSON ({e})") from e
    if not isinstance(data, dict):
        raise CheckpointError(f"{path}: {what} must be a JSON object, got {type(data).__name__}")
    return data


# --------------------------------------------------------------------------- training checkpoints


def checkpoint_name(iteration: int) -> str:
    return f"ckpt_{iteration:08d}"


def save_checkpoint(
    ckpt_dir: str | os.PathLike[str],
    iteration: int,
    tensors: dict[str, Any],
    meta: dict[str, Any],
    keep: int = 3,
) -> Path:
    """Write ``ckpt_<iteration>`` atomically, point ``latest.json`` at it, keep the newest ``keep``.

    Returns the checkpoint directory.
    """
    root = Path(ckpt_dir)
    root.mkdir(parents=True, exist_ok=True)
    name = checkpoint_name(iteration)
    final = root / name
    tmp = root / f".tmp-{name}-{os.getpid()}-{time.monotonic_ns()}"
    tmp.mkdir()
    try:
        _torch_save_synced(tensors, tmp / STATE_FILE)
        meta = {
            "format": CHECKPOINT_FORMAT,
            "version": CHECKPOINT_VERSION,
            **meta,
            "iteration": int(iteration),
            "state_sha256": sha256_file(tmp / STATE_FILE),
        }
        _write_bytes_synced(tmp / META_FILE, json.dumps(meta, indent=1, sort_keys=True).encode())
        _fsync_dir(tmp)
        if final.exists():  # re-saving the same iteration (e.g. after an interrupt): swap it out
            old = root / f".old-{name}-{os.getpid()}-{time.monotonic_ns()}"
            os.replace(final, old)
            os.replace(tmp, final)
            shutil.rmtree(old, ignore_errors=True)
        else:
            os.replace(tmp, final)
        _fsync_dir(root)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    atomic_write_text(root / LATEST_FILE, json.dumps({"checkpoint": name, "iteration": int(iteration)}))
    _prune(root, keep, protect=name)
    return final


def _prune(root: Path, keep: int, protect: str) -> None:
    ckpts = sorted(p for p in root.iterdir() if p.is_dir() and _CKPT_RE.match(p.name))
    for p in ckpts[: max(0, len(ckpts) - max(keep, 1))]:
        if p.name != protect:
            shutil.rmtree(p, ignore_errors=True)
    for p in root.iterdir():  # leftovers of crashed saves by dead processes
        if (
            p.is_dir()
            and p.name.startswith((".tmp-ckpt_", ".old-ckpt_"))
            and f"-{os.getpid()}-" not in p.name
        ):
            shutil.rmtree(p, ignore_errors=True)


def latest_checkpoint(ckpt_dir: str | os.PathLike[str]) -> Path | None:
    """The checkpoint ``latest.json`` points at; if the pointer is missing, the highest-numbered one.

    Returns ``None`` when the directory holds no checkpoint.
    """
    root = Path(ckpt_dir)
    if not root.is_dir():
        return None
    pointer = root / LATEST_FILE
    if pointer.is_file():
        data = _read_json(pointer, "checkpoint pointer")
        name = data.get("checkpoint")
        if not isinstance(name, str) or not _CKPT_RE.match(name):
            raise CheckpointError(
                f"{pointer}: 'checkpoint' must name a ckpt_XXXXXXXX directory, got {name!r}"
            )
        path = root / name
        if path.is_dir():
            return path
        # Only possible after a crash in the middle of re-saving the same iteration: fall back to
        # the newest complete checkpoint.
        warnings.warn(
            f"{pointer} points at {path}, which does not exist; using the newest checkpoint", stacklevel=2
        )
    ckpts = sorted(p for p in root.iterdir() if p.is_dir() and _CKPT_RE.match(p.name))
    return ckpts[-1] if ckpts else None


def join_split_checkpoint(src: str | os.PathLike[str], dst: str | os.PathLike[str]) -> Path:
    """Write ``dst/state.pt`` and ``dst/meta.json`` from a committed training folder ``src`` whose state is split
    in ``state.pt.part-*`` files (the device tool returns files of at most 16 MiB); returns ``dst``, a checkpoint
    directory for :func:`load_checkpoint` (which checks the joined state against the sha256 in ``meta.json``)."""
    src, dst = Path(src), Path(dst)
    parts = sorted(src.glob(f"{STATE_FILE}.part-*"))
    if not parts or not (src / META_FILE).is_file():
        raise FileNotFoundError(f"{src} holds no training checkpoint ({STATE_FILE}.part-* and {META_FILE})")
    dst.mkdir(parents=True, exist_ok=True)
    with open(dst / STATE_FILE, "wb") as out:
        for part in parts:
            with open(part, "rb") as f:
                shutil.copyfileobj(f, out)
    shutil.copy(src / META_FILE, dst / META_FILE)
    return dst


def load_checkpoint(path: str | os.PathLike[str]) -> tuple[dict[str, Any], dict[str, Any]]:
    """Read and verify one checkpoint (a ``ckpt_*`` directory, or its ``state.pt``/``meta.json``).

    Returns ``(tensors, meta)``. Raises :class:`CheckpointError` naming the offending file when the
    metadata is not ours, the hash does not match, or the state is not a tensor-only torch file.
    """
    path = Path(path)
    if path.is_file():
        path = path.parent
    meta_path, state_path = path / META_FILE, path / STATE_FILE
    meta = _read_json(meta_path, "checkpoint metadata")
    if meta.get("format") != CHECKPOINT_FORMAT:
        raise CheckpointError(
            f"{meta_path}: not a navzoo AMP checkpoint (format {meta.get('format')!r}, "
            f"expected {CHECKPOINT_FORMAT!r})"
        )
    if meta.get("version") != CHECKPOINT_VERSION:
        raise CheckpointError(
            f"{meta_path}: checkpoint version {meta.get('version')!r}, this code reads {CHECKPOINT_VERSION}"
        )
    if not state_path.is_file():
        raise CheckpointError(f"{state_path}: missing checkpoint state")
    digest = sha256_file(state_path)
    if digest != meta.get("state_sha256"):
        raise CheckpointError(
            f"{state_path}: sha256 {digest[:16]}… does not match {meta_path.name} "
            f"({str(meta.get('state_sha256'))[:16]}…): the file is corrupted or was replaced"
        )
    tensors = _load_tensors(state_path)
    if not isinstance(tensors, dict):
        raise CheckpointError(f"{state_path}: expected a dict of tensors, got {type(tensors).__name__}")
    return tensors, meta


# --------------------------------------------------------------------------- exported policies


def export_policy_files(
    path: str | os.PathLike[str],
    actor: Actor,
    obs_norm: RunningMeanStd,
    config: dict[str, Any],
) -> Path:
    """Write ``policy.pt`` + ``config.json`` into directory ``path`` (see the module docstring)."""
    out = Path(path)
    out.mkdir(parents=True, exist_ok=True)
    tensors = {f"actor.{k}": v.detach().cpu().clone() for k, v in actor.state_dict().items()}
    tensors |= {f"obs_norm.{k}": v.detach().cpu().clone() for k, v in obs_norm.state_dict().items()}
    tmp = out / f".tmp-{POLICY_WEIGHTS}-{os.getpid()}"
    _torch_save_synced(tensors, tmp)
    digest = sha256_file(tmp)
    os.replace(tmp, out / POLICY_WEIGHTS)
    cfg = {
        "format": POLICY_FORMAT,
        "version": POLICY_VERSION,
        **config,
        "obs_norm_eps": obs_norm.eps,
        "obs_clip": obs_norm.clip,
        "weights_file": POLICY_WEIGHTS,
        "weights_sha256": digest,
    }
    atomic_write_text(out / POLICY_CONFIG, json.dumps(cfg, indent=1, sort_keys=True))
    return out


#: Largest steering trim (rad) an exported policy may carry (:mod:`navzoo.agents.amp.steering`).
MAX_STEERING_TRIM = 0.5
#: Key of a policy config's ``steering_trim`` object listing crowd models (``NavConfig.crowd_model``)
#: whose target trajectories the trim is not applied to (it was calibrated on social-force targets and
#: measured to hurt others); read by :class:`navzoo.agents.amp.pedestrian_policy.AmpPedestrianPolicy`.
TRIM_OFF_KEY = "off_for_crowd_models"


def check_steering_trim(value: float) -> float:
    """``value`` as a float steering trim (rad), or a ValueError unless finite and within ±MAX_STEERING_TRIM."""
    trim = float(value)
    if not (np.isfinite(trim) and abs(trim) <= MAX_STEERING_TRIM):
        raise ValueError(f"steering_trim must be finite and within ±{MAX_STEERING_TRIM} rad, got {value!r}")
    return trim


def obs_batch(obs: np.ndarray, obs_dim: int) -> tuple[np.ndarray, bool]:
    """``obs`` of shape ``(obs_dim,)`` or ``(N, obs_dim)`` as a float32 ``(N, obs_dim)`` batch, and whether it
    was a single observation; a ValueError naming the shape otherwise."""
    x = np.asarray(obs, dtype=np.float32)
    if x.shape[-1] != obs_dim or x.ndim not in (1, 2):
        raise ValueError(f"obs must have shape (obs_dim,) or (N, obs_dim) with obs_dim={obs_dim}, got {x.shape}")
    return x.reshape(-1, obs_dim), x.ndim == 1


def waypoint_layout(obs_dim: int, config: dict[str, Any] | None = None) -> tuple[int, int]:
    """(first column, number K) of the target points in a policy observation of ``obs_dim`` columns:
    the ``steering_trim`` entry of ``config`` when it names them, else the layout of
    :func:`navzoo.agents.amp.features.policy_observation` (self-observation, K = 10 points, rays)."""
    from navzoo.agents.amp.features import FEATURE_DIM, N_RAYS

    trim = (config or {}).get("steering_trim") or {}
    if "waypoint_start" in trim and "n_waypoints" in trim:
        return int(trim["waypoint_start"]), int(trim["n_waypoints"])
    k = 10
    if obs_dim not in (FEATURE_DIM + 2 * k, FEATURE_DIM + 2 * k + N_RAYS):
        raise ValueError(f"cannot tell where the target points are in an observation of {obs_dim} columns")
    return FEATURE_DIM, k


def rotate_waypoints(obs: np.ndarray, start: int, k: int, angle: float) -> np.ndarray:
    """A copy of ``obs`` (N, D) with its K target points (heading frame, columns ``start`` ..
    ``start + 2K``) turned by ``angle`` rad counter-clockwise (to the left) about the body."""
    out = np.array(obs, dtype=np.float32, copy=True)
    wp = out[:, start:start + 2 * k].reshape(-1, k, 2).astype(np.float64)
    c, s = np.cos(angle), np.sin(angle)
    out[:, start:start + 2 * k] = np.stack([c * wp[..., 0] - s * wp[..., 1], s * wp[..., 0] + c * wp[..., 1]],
                                           axis=-1).reshape(-1, 2 * k)
    return out


class AmpPolicy:
    """Deterministic AMP policy: ``policy(obs) -> mean action`` clipped to [-1, 1].

    Accepts ``(obs_dim,)`` or ``(N, obs_dim)`` numpy arrays, returns float32 ``(act_dim,)`` or
    ``(N, act_dim)``. Runs under ``torch.no_grad`` on ``device``.

    ``steering_trim`` (rad, from the config's ``steering_trim.rad``, default 0): the observed target
    points are turned by this angle to the left about the body before the forward pass. It cancels a
    trained policy's constant steering bias (a body that drifts to one side of every path); it is
    calibrated on open-ground paths by :mod:`navzoo.agents.amp.steering`.

    ``symmetric`` (from the config's ``"symmetric": true``, default off): the mean action is averaged
    with the mirror image of the action for the mirrored observation
    (:class:`navzoo.agents.amp.symmetry.SymmetricActor`), which makes the policy exactly left/right
    symmetric, so it has no constant steering bias to trim.
    """

    def __init__(self, actor: Actor, obs_norm: RunningMeanStd, config: dict[str, Any], device: str = "cpu"):
        self.device = torch.device(device)
        self.actor = actor.to(self.device).eval()
        self.obs_norm = obs_norm.to(self.device)
        self.config = config
        self.obs_dim = int(config["obs_dim"])
        self.act_dim = int(config["act_dim"])
        trim = config.get("steering_trim")
        if trim is not None and not isinstance(trim, dict):
            raise ValueError(f"steering_trim must be an object with 'rad', got {trim!r}")
        self.steering_trim = (trim or {}).get("rad", 0.0)
        self._waypoints: tuple[int, int] | None = None
        self._symmetric: Any = None
        self.symmetric = config.get("symmetric", False)
        if self.steering_trim or trim:
            self._waypoints = waypoint_layout(self.obs_dim, config)
            start, k = self._waypoints
            if start < 0 or k < 1 or start + 2 * k > self.obs_dim:
                raise ValueError(f"steering_trim names target points at columns {start}..{start + 2 * k}, "
                                 f"outside the {self.obs_dim} observation columns")

    @property
    def steering_trim(self) -> float:
        """rad the observed target points are turned to the left (0 = off); checked when set."""
        return self._steering_trim

    @steering_trim.setter
    def steering_trim(self, value: float) -> None:
        trim = check_steering_trim(value)
        if trim and getattr(self, "_symmetric", None) is not None:
            raise ValueError("a symmetric policy has no steering bias to trim: steering_trim must be 0 "
                             f"when symmetric is on, got {value!r}")
        self._steering_trim = trim

    @property
    def symmetric(self) -> bool:
        """Whether actions are made left/right symmetric (see the class doc); checked when set."""
        return self._symmetric is not None

    @symmetric.setter
    def symmetric(self, value: bool) -> None:
        if not isinstance(value, bool):
            raise ValueError(f"symmetric must be true or false, got {value!r}")
        if not value:
            self._symmetric = None
            return
        if self.steering_trim:
            raise ValueError(f"symmetric needs steering_trim 0 (a symmetric policy has no steering bias), "
                             f"this policy has {self.steering_trim} rad: set steering_trim = 0 first")
        from navzoo.agents.amp.symmetry import SymmetricActor

        _, k = self.waypoints
        self._symmetric = SymmetricActor(self.actor, self.obs_norm, self.obs_dim, k)

    def override(self, steering_trim: float | None = None, symmetric: bool | None = None) -> None:
        """Replace the config's steering trim and/or symmetry for this run (None keeps a setting).
        ``symmetric=True`` drops the config's trim unless a nonzero ``steering_trim`` is given, which
        is refused (a symmetric policy has no bias to trim)."""
        if symmetric:
            if steering_trim:
                raise ValueError("a symmetric policy has no steering bias to trim: steering_trim must be 0 "
                                 f"with symmetric, got {steering_trim!r}")
            self.steering_trim = 0.0
            self.symmetric = True
            return
        if symmetric is not None:
            self.symmetric = False
        if steering_trim is not None:
            self.steering_trim = steering_trim

    @property
    def waypoints(self) -> tuple[int, int]:
        """(first column, K) of the target points in the observation."""
        if self._waypoints is None:
            self._waypoints = waypoint_layout(self.obs_dim, self.config)
        return self._waypoints

    @torch.no_grad()
    def __call__(self, obs: np.ndarray) -> np.ndarray:
        x, single = obs_batch(obs, self.obs_dim)
        if self.steering_trim:
            x = rotate_waypoints(x, *self.waypoints, self.steering_trim)
        t = torch.from_numpy(x).to(self.device)
        mean = self._symmetric(t) if self._symmetric is not None else self.actor(self.obs_norm.normalize(t))
        act = mean.clamp(-1.0, 1.0).cpu().numpy()
        return act[0] if single else act


def load_policy(path: str | os.PathLike[str], device: str = "cpu") -> Callable[[np.ndarray], np.ndarray]:
    """Load a policy written by ``AmpLearner.export_policy`` (a directory, or its ``config.json``), or a
    blend of such policies (:mod:`navzoo.agents.amp.blend`).

    Verifies the format tag and the sha256 of the weights before reading them with
    ``weights_only=True``; raises :class:`CheckpointError` naming the file otherwise.
    """
    root = Path(path)
    if root.is_file():
        root = root.parent
    cfg_path = root / POLICY_CONFIG
    cfg = _read_json(cfg_path, "policy config")
    from navzoo.agents.amp.blend import BLEND_FORMAT, load_blend

    if cfg.get("format") == BLEND_FORMAT:
        return load_blend(root, cfg, device=device)
    if cfg.get("format") != POLICY_FORMAT or cfg.get("version") != POLICY_VERSION:
        raise CheckpointError(
            f"{cfg_path}: not a navzoo AMP policy v{POLICY_VERSION} "
            f"(format {cfg.get('format')!r}, version {cfg.get('version')!r})"
        )
    w_path = root / str(cfg.get("weights_file", POLICY_WEIGHTS))
    if not w_path.is_file():
        raise CheckpointError(f"{w_path}: missing policy weights")
    digest = sha256_file(w_path)
    if digest != cfg.get("weights_sha256"):
        raise CheckpointError(f"{w_path}: sha256 does not match {cfg_path.name}: corrupted or replaced")
    tensors = _load_tensors(w_path)
    try:
        actor = Actor(
            int(cfg["obs_dim"]),
            int(cfg["act_dim"]),
            [int(h) for h in cfg["actor_hidden"]],
            str(cfg["activation"]),
        )
        actor.load_state_dict({k[len("actor.") :]: v for k, v in tensors.items() if k.startswith("actor.")})
        norm = RunningMeanStd(int(cfg["obs_dim"]), eps=float(cfg["obs_norm_eps"]), clip=cfg["obs_clip"])
        norm.load_state_dict(
            {k[len("obs_norm.") :]: v for k, v in tensors.items() if k.startswith("obs_norm.")}
        )
    except (KeyError, RuntimeError, ValueError, TypeError) as e:
        raise CheckpointError(f"{w_path}: does not match {cfg_path.name} ({e})") from e
    try:
        return AmpPolicy(actor, norm, cfg, device)
    except (ValueError, TypeError) as e:
        raise CheckpointError(f"{cfg_path}: {e}") from e


#: Config fields that exported policies must share to be averaged (:func:`average_policies`).
_AVERAGE_MUST_MATCH = ("obs_dim", "act_dim", "actor_hidden", "activation", "obs_norm_eps", "obs_clip")


def average_policies(
    paths: list[str | os.PathLike[str]],
    out: str | os.PathLike[str],
    weights: list[float] | None = None,
) -> Path:
    """Write the weighted average of exported AMP policies (a "model soup") as a new exported policy.

    Every tensor of the actor and of the observation normaliser (mean and variance) is averaged with
    ``weights`` (default: equal; they must be finite, >= 0, and are normalised to sum 1); the
    normaliser's sample count is the weighted mean too. Averaging is meaningful for policies fine-tuned
    from one starting checkpoint (e.g. snapshots of runs branching from the shipped one), whose weights
    stay close; it is not for independently trained ones. The policies must share dims, architecture
    and normaliser settings, and none may be a symmetric (mirrored) policy. Each input is verified
    (format, sha256) as :func:`load_policy` does. The output carries no steering trim (calibrate it with
    ``navzoo train amp-trim``) and lists its sources under ``averaged_from``.
    """
    if len(paths) < 2:
        raise ValueError(f"average_policies needs at least two policies, got {len(paths)}")
    if weights is None:
        weights = [1.0] * len(paths)
    if len(weights) != len(paths):
        raise ValueError(f"{len(weights)} weights for {len(paths)} policies")
    w = np.asarray(weights, dtype=np.float64)
    if not np.all(np.isfinite(w)) or np.any(w < 0) or w.sum() <= 0:
        raise ValueError(f"weights must be finite, >= 0 and not all 0, got {list(weights)}")
    w = w / w.sum()
    policies = [load_policy(p) for p in paths]
    first = policies[0].config
    for p, pol in zip(paths[1:], policies[1:], strict=True):
        for key in _AVERAGE_MUST_MATCH:
            if pol.config.get(key) != first.get(key):
                raise CheckpointError(
                    f"{p}: {key} {pol.config.get(key)!r} differs from {paths[0]}'s {first.get(key)!r}; "
                    "only policies of one architecture can be averaged"
                )
    for p, pol in zip(paths, policies, strict=True):
        if pol.config.get("symmetric"):
            raise CheckpointError(f"{p}: a symmetric policy cannot be averaged (its actor is mirrored at run time)")
    def weighted_mean(states: list[dict[str, torch.Tensor]]) -> dict[str, torch.Tensor]:
        return {k: sum(float(wi) * s[k].double() for wi, s in zip(w, states, strict=True)).to(v.dtype)
                for k, v in states[0].items()}

    actor, obs_norm = policies[0].actor, policies[0].obs_norm
    actor.load_state_dict(weighted_mean([pol.actor.state_dict() for pol in policies]))
    obs_norm.load_state_dict(weighted_mean([pol.obs_norm.state_dict() for pol in policies]))
    config = {k: first[k] for k in ("obs_dim", "act_dim", "actor_hidden", "activation", "action_low", "action_high")
              if k in first}
    config["trained_iterations"] = max(int(pol.config.get("trained_iterations", 0)) for pol in policies)
    config["trained_steps"] = max(int(pol.config.get("trained_steps", 0)) for pol in policies)
    config["averaged_from"] = [
        {"path": str(p), "weight": float(wi), "weights_sha256": pol.config["weights_sha256"],
         "trained_iterations": pol.config.get("trained_iterations")}
        for p, wi, pol in zip(paths, w, policies, strict=True)
    ]
    return export_policy_files(out, actor.cpu(), obs_norm.cpu(), config)


def checkpoint_with_policy(
    ckpt_dir: str | os.PathLike[str],
    policy_dir: str | os.PathLike[str],
    out_dir: str | os.PathLike[str],
) -> Path:
    """A copy of training checkpoint ``ckpt_dir`` whose actor and observation normaliser are those of the
    exported policy ``policy_dir``; written as ``out_dir/ckpt_<iteration>`` (returned).

    This is how training continues from a policy that has no training checkpoint of its own, such as a
    weight average (:func:`average_policies`) of branches of ``ckpt_dir``: the critic, discriminator,
    their normalisers, the optimisers, the replay sample and the counters stay those of ``ckpt_dir``.
    Both inputs are verified (format, sha256); the policy's tensors must have the checkpoint actor's
    names and shapes. The new meta records the policy under ``actor_from_policy``.
    """
    tensors, meta = load_checkpoint(ckpt_dir)
    policy = load_policy(policy_dir)
    for key, module in (("actor", policy.actor), ("obs_norm", policy.obs_norm)):
        theirs = {k: v.detach().cpu() for k, v in module.state_dict().items()}
        ours = tensors.get(key)
        if not isinstance(ours, dict) or set(ours) != set(theirs) or any(
                tuple(ours[k].shape) != tuple(theirs[k].shape) for k in theirs):
            raise CheckpointError(
                f"{policy_dir}: its {key} does not fit checkpoint {ckpt_dir} "
                f"(tensor names or shapes differ); only a policy of the checkpoint's architecture can be put in"
            )
        tensors[key] = {k: v.to(ours[k].dtype).clone() for k, v in theirs.items()}
    iteration = int(meta["iteration"])
    meta = {k: v for k, v in meta.items() if k not in ("format", "version", "iteration", "state_sha256")}
    meta["actor_from_policy"] = {"path": str(policy_dir), "weights_sha256": policy.config["weights_sha256"],
                                 "checkpoint": Path(ckpt_dir).name}
    return save_checkpoint(out_dir, iteration, tensors, meta, keep=1)
