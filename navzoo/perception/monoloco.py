"""Monoloco-style estimation of a person's 3D position and body orientation from 2D keypoints.

After Bertoni et al., "MonoLoco: Monocular 3D Pedestrian Localization and Uncertainty Estimation"
(ICCV 2019) and its successor Monoloco++ (orientation). A small fully connected network reads the 17
COCO keypoints of one detected person, converted to *normalised image coordinates* with the inverse
camera matrix (``x = (u - c_x) / f_x``, ``y = (v - c_y) / f_y``, so the input does not depend on the
resolution or the focal length), and returns

* the distance ``d`` (m) from the camera's optical centre to the person's pelvis, as a Laplace
  distribution: location ``mu`` and a *relative* spread ``b`` (Monoloco's loss ``|1 - mu/d| / b + log b``;
  the absolute standard deviation is ``sqrt(2) b mu``);
* the direction of the pelvis as its normalised image coordinates ``(xi, eta)``, so that the camera-frame
  position is ``mu * (xi, eta, 1) / |(xi, eta, 1)|``;
* the body orientation as ``(sin, cos)`` of its *allocentric* yaw: the body heading relative to the
  line of sight from the camera to the person (what the image shows; the world heading is that angle
  plus the bearing of the person).

Missing keypoints are zeros with a 0 flag: the input is 17 x (x, y) + 17 flags = 51 numbers. The
architecture follows Monoloco (linear layer, residual blocks of linear + normalisation + ReLU +
dropout, linear output), 256 wide. Training data come from navzoo scenes
(:mod:`navzoo.perception.dataset`); the shipped weights live in ``policies/monoloco``.
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch
from torch import nn

from navzoo.agents.amp.checkpoint import sha256_file
from navzoo.sensors.camera_model import NUM_KEYPOINTS, PinholeCamera

__all__ = [
    "DEFAULT_MODEL_DIR",
    "INPUT_DIM",
    "MonolocoConfig",
    "MonolocoEstimate",
    "MonolocoEstimator",
    "MonolocoNet",
    "decode_outputs",
    "export_model",
    "keypoint_features",
    "laplace_loss",
    "load_estimator",
    "save_model",
]

INPUT_DIM = NUM_KEYPOINTS * 3
OUTPUT_DIM = 6  # mu, log b, xi, eta, sin, cos
DEFAULT_MODEL_DIR = Path(__file__).resolve().parents[2] / "policies" / "monoloco"


@dataclass(frozen=True)
class MonolocoConfig:
    """Network size.

    Attributes:
        hidden: Width of the hidden layers.
        blocks: Number of residual blocks.
        dropout: Dropout probability inside the blocks (training only).
    """

    hidden: int = 256
    blocks: int = 3
    dropout: float = 0.1

    def __post_init__(self) -> None:
        if int(self.hidden) != self.hidden or self.hidden < 8:
            raise ValueError(f"hidden must be an integer >= 8, got {self.hidden!r}")
        if int(self.blocks) != self.blocks or self.blocks < 0:
            raise ValueError(f"blocks must be an integer >= 0, got {self.blocks!r}")
        if not 0.0 <= self.dropout < 1.0:
            raise ValueError(f"dropout must be in [0, 1), got {self.dropout!r}")


class _Block(nn.Module):
    def __init__(self, width: int, dropout: float) -> None:
        super().__init__()
        self.net = nn.Sequential(
            nn.Linear(width, width), nn.LayerNorm(width), nn.ReLU(), nn.Dropout(dropout),
            nn.Linear(width, width), nn.LayerNorm(width), nn.ReLU(), nn.Dropout(dropout),
        )

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return x + self.net(x)


class MonolocoNet(nn.Module):
    """Keypoint features (B, 51) -> (B, 6): ``mu`` (m), ``log b``, ``xi``, ``eta``, ``sin``, ``cos``."""

    def __init__(self, config: MonolocoConfig | None = None) -> None:
        super().__init__()
        self.config = config or MonolocoConfig()
        c = self.config
        self.inp = nn.Sequential(nn.Linear(INPUT_DIM, c.hidden), nn.ReLU())
        self.blocks = nn.Sequential(*[_Block(c.hidden, c.dropout) for _ in range(c.blocks)])
        self.out = nn.Linear(c.hidden, OUTPUT_DIM)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.out(self.blocks(self.inp(x)))
        # Distance through softplus (positive, about 1-15 m); the raw log b, direction and orientation.
        mu = nn.functional.softplus(y[:, :1]) + 0.1
        log_b = y[:, 1:2].clamp(-6.0, 3.0)
        return torch.cat([mu, log_b, y[:, 2:4], y[:, 4:6]], dim=1)


def keypoint_features(uv: np.ndarray, detected: np.ndarray, camera: PinholeCamera) -> np.ndarray:
    """Network input of detected people: normalised image coordinates and keypoint flags.

    Args:
        uv: (N, 17, 2) pixel coordinates (NaN or anything where not detected).
        detected: (N, 17) bool.
        camera: The camera that saw them (its intrinsics).

    Returns:
        (N, 51) float32: x_1..x_17 interleaved with y (34 numbers, 0 where missing), then 17 flags.
    """
    uv = np.asarray(uv, dtype=np.float64)
    det = np.asarray(detected, dtype=bool)
    if uv.ndim != 3 or uv.shape[1:] != (NUM_KEYPOINTS, 2) or det.shape != uv.shape[:2]:
        raise ValueError(f"uv must be (N, {NUM_KEYPOINTS}, 2) and detected (N, {NUM_KEYPOINTS}), "
                         f"got {uv.shape} and {det.shape}")
    x = (uv[..., 0] - camera.cx) / camera.fx
    y = (uv[..., 1] - camera.cy) / camera.fy
    xy = np.stack([x, y], axis=-1)
    xy = np.where(det[..., None] & np.isfinite(xy), xy, 0.0)
    return np.concatenate([xy.reshape(len(uv), 2 * NUM_KEYPOINTS), det.astype(np.float64)], axis=1).astype(np.float32)


def laplace_loss(mu: torch.Tensor, log_b: torch.Tensor, target: torch.Tensor) -> torch.Tensor:
    """Monoloco's Laplace negative log-likelihood on the relative error: ``|1 - mu/d| e^{-log b} + log b``."""
    return (torch.abs(1.0 - mu / target) * torch.exp(-log_b) + log_b).mean()


@dataclass(frozen=True)
class MonolocoEstimate:
    """Estimates for N detected people, in the camera frame and in the world.

    Attributes:
        distance: (N,) estimated distance from the optical centre to the pelvis (m).
        distance_std: (N,) its standard deviation, ``sqrt(2) b mu`` (m).
        position_cam: (N, 3) pelvis in the camera's optical frame (x right, y down, z forward).
        position_world: (N, 3) pelvis in the world.
        yaw_world: (N,) body orientation (heading) in the world (rad).
        allocentric_yaw: (N,) body orientation relative to the line of sight (rad).
    """

    distance: np.ndarray
    distance_std: np.ndarray
    position_cam: np.ndarray
    position_world: np.ndarray
    yaw_world: np.ndarray
    allocentric_yaw: np.ndarray


def bearing_of(position_world: np.ndarray, camera_centre: np.ndarray) -> np.ndarray:
    """World bearing (rad) of points seen from the camera's optical centre."""
    d = np.asarray(position_world)[..., :2] - np.asarray(camera_centre)[:2]
    return np.arctan2(d[..., 1], d[..., 0])


def wrap_angle(a: np.ndarray) -> np.ndarray:
    """Angles wrapped to [-pi, pi)."""
    return (np.asarray(a) + np.pi) % (2.0 * np.pi) - np.pi


class MonolocoEstimator:
    """A trained :class:`MonolocoNet` with the conversions to camera and world coordinates."""

    def __init__(self, net: MonolocoNet, meta: dict | None = None, device: str = "cpu") -> None:
        self.net = net.to(device).eval()
        self.meta = dict(meta or {})
        self.device = device

    @torch.no_grad()
    def raw(self, features: np.ndarray) -> np.ndarray:
        """Network outputs (N, 6) for features (N, 51)."""
        f = np.asarray(features, dtype=np.float32)
        if f.ndim != 2 or f.shape[1] != INPUT_DIM:
            raise ValueError(f"features must have shape (N, {INPUT_DIM}), got {f.shape}")
        if len(f) == 0:
            return np.zeros((0, OUTPUT_DIM), dtype=np.float32)
        # A handful of people per image: one CPU thread. Torch's intra-op pool only adds its
        # synchronisation (about 100 ms per call measured on a busy 2-core VM against 0.6 ms).
        prev = torch.get_num_threads()
        single = self.device == "cpu" and len(f) < 1024 and prev != 1
        if single:
            torch.set_num_threads(1)
        try:
            return self.net(torch.from_numpy(f).to(self.device)).cpu().numpy()
        finally:
            if single:
                torch.set_num_threads(prev)

    def estimate(self, uv: np.ndarray, detected: np.ndarray, camera: PinholeCamera,
                 robot_pose: np.ndarray | tuple[float, float, float]) -> MonolocoEstimate:
        """Position and orientation of each detected person.

        Args:
            uv: (N, 17, 2) detected keypoints (pixels).
            detected: (N, 17) bool.
            camera: The camera.
            robot_pose: ``(x, y, yaw)`` of the robot carrying the camera.

        Returns:
            :class:`MonolocoEstimate` for the N people.
        """
        out = self.raw(keypoint_features(uv, detected, camera)).astype(np.float64)
        return decode_outputs(out, camera, robot_pose)


def decode_outputs(out: np.ndarray, camera: PinholeCamera, robot_pose) -> MonolocoEstimate:
    """Turn network outputs (N, 6) of one camera into a :class:`MonolocoEstimate`."""
    mu, log_b, xi, eta, s, c = (out[:, k] for k in range(OUTPUT_DIM))
    ray = np.stack([xi, eta, np.ones_like(xi)], axis=1)
    pc = mu[:, None] * ray / np.linalg.norm(ray, axis=1, keepdims=True)
    rot, t = camera.extrinsics(robot_pose)
    pw = pc @ rot + t
    allo = np.arctan2(s, c)
    yaw = wrap_angle(allo + bearing_of(pw, t))
    return MonolocoEstimate(mu, math.sqrt(2.0) * np.exp(log_b) * mu, pc, pw, yaw, allo)


# ---------------------------------------------------------------------- weights

def save_model(net: MonolocoNet, out_dir: str | Path, meta: dict | None = None, half: bool = False) -> Path:
    """Write ``model.pt`` (state_dict tensors only) and ``config.json`` (architecture, sha256, ``meta``).

    ``half=True`` stores the floating-point tensors as float16 (half the size, for shipping; they are
    loaded back as float32).
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    weights = out / "model.pt"
    tmp = out / "model.pt.tmp"
    state = {k: v.detach().cpu() for k, v in net.state_dict().items()}
    if half:
        state = {k: v.half() if v.is_floating_point() else v for k, v in state.items()}
    torch.save(state, tmp)
    tmp.replace(weights)
    config = {"architecture": asdict(net.config), "input_dim": INPUT_DIM, "output_dim": OUTPUT_DIM,
              "sha256": sha256_file(weights), "dtype": "float16" if half else "float32", **(meta or {})}
    (out / "config.json").write_text(json.dumps(config, indent=2) + "\n")
    return weights


def load_estimator(model_dir: str | Path | None = None, device: str = "cpu") -> MonolocoEstimator:
    """Load a saved model (default: the shipped ``policies/monoloco``), checking its sha256.

    Raises:
        FileNotFoundError: When the folder has no ``model.pt`` / ``config.json``.
        ValueError: When the weights do not match the recorded sha256 or the architecture.
    """
    d = Path(model_dir) if model_dir is not None else DEFAULT_MODEL_DIR
    w, cfg_path = d / "model.pt", d / "config.json"
    if not w.is_file() or not cfg_path.is_file():
        raise FileNotFoundError(f"no Monoloco model in {d} (need model.pt and config.json; "
                                "train one with `navzoo train perception`)")
    try:
        meta = json.loads(cfg_path.read_text())
    except json.JSONDecodeError as err:
        raise ValueError(f"{cfg_path} is not valid JSON: {err}") from err
    if meta.get("sha256") != sha256_file(w):
        raise ValueError(f"{w} does not match the sha256 in {cfg_path} (corrupted or replaced)")
    try:
        net = MonolocoNet(MonolocoConfig(**meta.get("architecture", {})))
        state = torch.load(w, map_location="cpu", weights_only=True)
        net.load_state_dict({k: v.float() if v.is_floating_point() else v for k, v in state.items()})
    except (TypeError, RuntimeError) as err:
        raise ValueError(f"{w} does not fit the architecture in {cfg_path}: {err}") from err
    return MonolocoEstimator(net, meta, device)


def export_model(src_dir: str | Path, dst_dir: str | Path, half: bool = True) -> Path:
    """Copy a trained model (``navzoo train perception``'s ``<out>/model``) to ``dst_dir`` for shipping,
    as float16 by default, keeping its metadata (validation figures, epoch)."""
    est = load_estimator(src_dir)
    meta = {k: v for k, v in est.meta.items()
            if k not in ("architecture", "input_dim", "output_dim", "sha256", "dtype")}
    return save_model(est.net, dst_dir, meta, half=half)


if __name__ == "__main__":  # python -m navzoo.perception.monoloco export SRC DST
    import sys

    if len(sys.argv) != 4 or sys.argv[1] != "export":
        raise SystemExit("usage: python -m navzoo.perception.monoloco export SRC_MODEL_DIR DST_DIR")
    print(export_model(sys.argv[2], sys.argv[3]))
