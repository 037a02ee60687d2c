"""The paper's spatio-temporal transformer state encoder, as a Stable-Baselines3 features extractor.

:class:`SpatioTemporalExtractor` maps one navzoo robot observation to the state representation
``h`` of the NavIsaacLab paper ("Pedestrians Observation Encoder" and "Scene Context Encoder"):

1. **Agent states** ``S`` of shape (1 + K, T, 7): row 0 is the robot, rows 1..K the observed
   people/robots of ``agents``, each step ``x, y, u, v, cos θ, sin θ, radius`` in the robot's frame
   at the current step. The observation holds only the robot's *current* state, so row 0 is
   ``(0, 0, v_x, v_y, 1, 0, robot_radius)`` at the last step and masked at the earlier ones;
   the robot's radius is not observed and comes from the ``robot_radius`` argument (default: the
   ``RobotSpec`` default, 0.3 m).
2. A shared MLP embeds every ``(agent, step)`` entry into ``D`` dimensions, a learnable temporal
   position embedding is added (and a learnable robot embedding on row 0, the paper's fixed index).
3. ``n_blocks`` (3) factorised blocks: causal temporal self-attention per agent (a step attends to
   itself and earlier observed steps only), then agent-wise self-attention per step (over the
   agents observed at that step), then a feed-forward layer, each pre-norm with a residual.
   Entries masked by ``agents_mask`` are never attended to and are zeroed after each block; every
   query may always attend to itself, so a fully masked row cannot produce NaN.
4. The last-step tokens of the K neighbours ``U`` and a map token ``M`` (small CNN over the
   occupancy crop) form the scene memory; the query ``q = MLP([s_0; ω; e_g])`` (robot state, yaw rate,
   goal ``e_g = [x_g, y_g, d_g, sin θ_g, cos θ_g]``) attends over it (cross-attention, neighbours not
   observed at the last step are masked; the map token is always there), and the gated update
   ``α = σ(W_α [z; q])``, ``h = α ⊙ q + (1 − α) ⊙ z`` gives the features (``features_dim``).

Nothing derives an agent's orientation from its velocity: the ``cos θ, sin θ`` channels are used as
given, so the body orientation written by :class:`navzoo.perception.PerceptionWrapper` (same format,
same slots) enters the model unchanged. No neighbour slot has a position embedding, so the output is
invariant to the order of the K slots.

Observations: the Dict of ``navzoo.make`` (``MultiInputPolicy``) or the flat Box of
``flat_obs=True`` / :func:`navzoo.envs.vector.sb3_vec_env` (``MlpPolicy``); the Box is split back
into its entries with the layout of ``gymnasium.spaces.flatten`` on the env's Dict space (see
:func:`flat_layout`). Training (:mod:`navzoo.agents.robot_train`) uses the flat Box.
"""

from __future__ import annotations

import math
from typing import Any

import gymnasium
import numpy as np
import torch
from gymnasium import spaces
from stable_baselines3.common.torch_layers import BaseFeaturesExtractor
from torch import nn
from torch.nn import functional as F

from navzoo.envs import observations as obs_terms

__all__ = [
    "OBS_KEYS",
    "FactorizedBlock",
    "SpatioTemporalExtractor",
    "flat_layout",
    "observation_dict_space",
    "transformer_policy_kwargs",
]

OBS_KEYS = ("goal", "velocity", "agents", "agents_mask", "map")
FEATURES = obs_terms.NEIGHBOR_FEATURES  # x, y, u, v, cos θ, sin θ, radius
DEFAULT_K = 6
DEFAULT_T = 8
DEFAULT_ROBOT_RADIUS = 0.3


def observation_dict_space(k_neighbors: int = DEFAULT_K, history: int = DEFAULT_T, map_cells: int = 32,
                           scan_rays: int = 0) -> spaces.Dict:
    """The robot observation space of a navzoo env with these sizes (the env's own bounds).

    ``scan_rays > 0`` adds the ``"scan"`` entry (``NavConfig.scan_rays``).

    Mirrors ``NavEnv._build_observation_space``; used to rebuild a policy's spaces without an env
    and for the flat layout. ``tests/agents/test_transformer.py`` checks it against the env.
    """
    for name, v in (("k_neighbors", k_neighbors), ("history", history), ("map_cells", map_cells)):
        if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
            raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
    if not isinstance(scan_rays, (int, np.integer)) or isinstance(scan_rays, bool) or scan_rays < 0:
        raise ValueError(f"scan_rays must be an integer >= 0, got {scan_rays!r}")
    f32 = np.float32
    b, v, g = obs_terms.POS_BOUND, obs_terms.VEL_BOUND, obs_terms.GOAL_BOUND
    lo = np.broadcast_to(np.array([-b, -b, -v, -v, -1, -1, 0], f32), (k_neighbors, history, FEATURES)).copy()
    hi = np.broadcast_to(np.array([b, b, v, v, 1, 1, 2.0], f32), (k_neighbors, history, FEATURES)).copy()
    entries = {
        "goal": spaces.Box(np.array([-g, -g, 0, -1, -1], f32), np.array([g, g, 1.5 * g, 1, 1], f32), dtype=f32),
        "velocity": spaces.Box(-v, v, shape=(3,), dtype=f32),
        "agents": spaces.Box(lo, hi, dtype=f32),
        "agents_mask": spaces.Box(0.0, 1.0, shape=(k_neighbors, history), dtype=f32),
        "map": spaces.Box(0.0, 1.0, shape=(map_cells, map_cells), dtype=f32),
    }
    if scan_rays:
        entries["scan"] = spaces.Box(0.0, 1.0, shape=(int(scan_rays),), dtype=f32)
    return spaces.Dict(entries)


def flat_layout(k_neighbors: int, history: int, map_cells: int,
                scan_rays: int = 0) -> dict[str, tuple[int, int, tuple[int, ...]]]:
    """``{key: (start, end, shape)}`` of each entry in the flat observation.

    The order is the one ``gymnasium.spaces.flatten`` uses for the env's Dict space, i.e. the Dict's
    key order (Gymnasium sorts the keys: agents, agents_mask, goal, map, [scan,] velocity), not the
    order the keys are listed in the docs.
    """
    out: dict[str, tuple[int, int, tuple[int, ...]]] = {}
    start = 0
    for key, sub in observation_dict_space(k_neighbors, history, map_cells, scan_rays).spaces.items():
        n = int(np.prod(sub.shape))
        out[key] = (start, start + n, tuple(sub.shape))
        start += n
    return out


def _layout_from_space(observation_space: gymnasium.Space, k_neighbors: int | None,
                       history: int | None, scan_rays: int | None = None) -> tuple[int, int, int, int, bool]:
    """(K, T, C, R, is_flat) of a navzoo robot observation space (Dict, or its flattened Box); R = scan rays."""
    if isinstance(observation_space, spaces.Dict):
        missing = [k for k in OBS_KEYS if k not in observation_space.spaces]
        if missing:
            raise ValueError(f"observation space lacks {missing}; expected the navzoo robot Dict with keys {list(OBS_KEYS)}")
        shp = {k: tuple(observation_space[k].shape) for k in OBS_KEYS}
        if len(shp["agents"]) != 3 or shp["agents"][2] != FEATURES:
            raise ValueError(f"'agents' must have shape (K, T, {FEATURES}), got {shp['agents']}")
        k, t, _ = shp["agents"]
        c = shp["map"][0] if shp["map"] else 0
        expected = {"goal": (5,), "velocity": (3,), "agents_mask": (k, t), "map": (c, c)}
        for key, want in expected.items():
            if shp[key] != want:
                raise ValueError(f"'{key}' must have shape {want}, got {shp[key]}")
        r = 0
        if "scan" in observation_space.spaces:
            sshape = tuple(observation_space["scan"].shape)
            if len(sshape) != 1 or sshape[0] < 1:
                raise ValueError(f"'scan' must have shape (R,) with R >= 1, got {sshape}")
            r = sshape[0]
        for name, given, found in (("k_neighbors", k_neighbors, k), ("history", history, t), ("scan_rays", scan_rays, r)):
            if given is not None and given != found:
                raise ValueError(f"{name}={given} does not match the observation space ({found})")
        return k, t, c, r, False
    if isinstance(observation_space, spaces.Box) and len(observation_space.shape) == 1:
        k = DEFAULT_K if k_neighbors is None else int(k_neighbors)
        t = DEFAULT_T if history is None else int(history)
        r = 0 if scan_rays is None else int(scan_rays)
        if k < 1 or t < 1 or r < 0:
            raise ValueError(f"k_neighbors and history must be >= 1 and scan_rays >= 0, got {k}, {t} and {r}")
        n = int(observation_space.shape[0])
        rest = n - 5 - 3 - k * t * (FEATURES + 1) - r
        c = math.isqrt(rest) if rest > 0 else 0
        if c < 1 or c * c != rest:
            raise ValueError(
                f"a flat observation of size {n} does not fit K={k}, T={t}, R={r} (8 + K*T*8 + C*C + R entries "
                f"with an integer map size C); pass the env's k_neighbors, history and scan_rays to the extractor")
        lay = flat_layout(k, t, c, r)
        lo, hi = observation_space.low, observation_space.high
        for key in ("agents_mask", "map"):  # both are [0, 1] in the env: a cheap check of the layout
            s, e, _ = lay[key]
            if np.all(np.isfinite(lo)) and not (np.all(lo[s:e] == 0) and np.all(hi[s:e] == 1)):
                raise ValueError(f"the flat observation's bounds at '{key}' [{s}:{e}] are not [0, 1]: not the "
                                 "navzoo flat layout (agents, agents_mask, goal, map, velocity)")
        return k, t, c, r, True
    raise ValueError(f"expected the navzoo robot observation (Dict or its flat Box), got {observation_space}")


class MaskedSelfAttention(nn.Module):
    """Multi-head self-attention with a boolean ``allowed[b, query, key]`` mask (True = attend)."""

    def __init__(self, dim: int, n_heads: int) -> None:
        super().__init__()
        self.n_heads = n_heads
        self.qkv = nn.Linear(dim, 3 * dim)
        self.out = nn.Linear(dim, dim)

    def forward(self, x: torch.Tensor, allowed: torch.Tensor) -> torch.Tensor:
        b, n, d = x.shape
        q, k, v = self.qkv(x).view(b, n, 3, self.n_heads, d // self.n_heads).permute(2, 0, 3, 1, 4)
        y = F.scaled_dot_product_attention(q, k, v, attn_mask=allowed[:, None])
        return self.out(y.transpose(1, 2).reshape(b, n, d))


class FactorizedBlock(nn.Module):
    """One factorised spatio-temporal block on tokens ``x`` (B, N, T, D) with validity ``valid`` (B, N, T).

    Causal temporal self-attention per agent, agent-wise self-attention per step, feed-forward; pre-norm
    residuals. Invalid entries are excluded as keys and zeroed in the output.
    """

    def __init__(self, dim: int, n_heads: int, ff_mult: int = 2) -> None:
        super().__init__()
        self.norm_t, self.norm_a, self.norm_f = nn.LayerNorm(dim), nn.LayerNorm(dim), nn.LayerNorm(dim)
        self.temporal = MaskedSelfAttention(dim, n_heads)
        self.agentwise = MaskedSelfAttention(dim, n_heads)
        self.ff = nn.Sequential(nn.Linear(dim, ff_mult * dim), nn.GELU(), nn.Linear(ff_mult * dim, dim))

    def forward(self, x: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        b, n, t, d = x.shape
        eye_t = torch.eye(t, dtype=torch.bool, device=x.device)
        causal = torch.ones(t, t, dtype=torch.bool, device=x.device).tril()
        # Temporal: step i attends to observed steps j <= i of the same agent (always to itself).
        allowed = (causal & valid.reshape(b * n, 1, t)) | eye_t
        x = x + self.temporal(self.norm_t(x).reshape(b * n, t, d), allowed).reshape(b, n, t, d)
        # Agent-wise: at each step, every agent attends to the agents observed at that step.
        eye_n = torch.eye(n, dtype=torch.bool, device=x.device)
        va = valid.transpose(1, 2).reshape(b * t, 1, n)
        xa = self.norm_a(x).transpose(1, 2).reshape(b * t, n, d)
        x = x + self.agentwise(xa, va | eye_n).reshape(b, t, n, d).transpose(1, 2)
        x = x + self.ff(self.norm_f(x))
        return x * valid[..., None].to(x.dtype)


class SpatioTemporalExtractor(BaseFeaturesExtractor):
    """The paper's spatio-temporal transformer encoder (see the module docstring).

    Args:
        observation_space: the robot's observation space: the navzoo Dict, or its flattened Box.
        features_dim: D, the token width and the output size.
        n_heads: attention heads (must divide ``features_dim``).
        n_blocks: factorised spatio-temporal blocks (the paper: 3).
        ff_mult: width of the blocks' feed-forward layer, in multiples of D.
        robot_radius: the robot's radius (m), its row's radius feature (not in the observation).
        length_scale: positions, goal coordinates and distance are divided by this (m) before the MLPs.
        k_neighbors: K, for a flat Box only (default 6); with a Dict it must match or be None.
        history: T, for a flat Box only (default 8); with a Dict it must match or be None.
        scan_rays: R, the range scan's rays (``NavConfig.scan_rays``), for a flat Box only (default 0);
            with a Dict it must match or be None. The scan enters the query through its own MLP, whose
            output layer starts at zero: a policy trained without a scan keeps its behaviour when its
            weights are loaded into one with a scan (:func:`navzoo.agents.robot_train.init_weights_from`).

    Raises:
        ValueError: for a space that is not a navzoo robot observation, or bad sizes.
    """

    def __init__(self, observation_space: gymnasium.Space, features_dim: int = 128, n_heads: int = 4,
                 n_blocks: int = 3, ff_mult: int = 2, robot_radius: float = DEFAULT_ROBOT_RADIUS,
                 length_scale: float = 5.0, k_neighbors: int | None = None, history: int | None = None,
                 scan_rays: int | None = None) -> None:
        for name, v in (("features_dim", features_dim), ("n_heads", n_heads), ("n_blocks", n_blocks),
                        ("ff_mult", ff_mult)):
            if not isinstance(v, (int, np.integer)) or isinstance(v, bool) or v < 1:
                raise ValueError(f"{name} must be an integer >= 1, got {v!r}")
        if features_dim % n_heads:
            raise ValueError(f"features_dim ({features_dim}) must be divisible by n_heads ({n_heads})")
        if not (math.isfinite(robot_radius) and robot_radius > 0):
            raise ValueError(f"robot_radius must be a finite number > 0, got {robot_radius!r}")
        if not (math.isfinite(length_scale) and length_scale > 0):
            raise ValueError(f"length_scale must be a finite number > 0, got {length_scale!r}")
        k, t, c, r, is_flat = _layout_from_space(observation_space, k_neighbors, history, scan_rays)
        super().__init__(observation_space, features_dim)
        self.k_neighbors, self.history, self.map_cells, self.is_flat = k, t, c, is_flat
        self.scan_rays = r
        self.n_heads, self.n_blocks, self.ff_mult = int(n_heads), int(n_blocks), int(ff_mult)
        self.robot_radius = float(robot_radius)
        self.length_scale = float(length_scale)
        self._layout = flat_layout(k, t, c, r)
        d = features_dim
        self.embed = nn.Sequential(nn.Linear(FEATURES, d), nn.ReLU(), nn.Linear(d, d))
        self.time_embedding = nn.Parameter(torch.randn(t, d) * 0.02)
        self.robot_embedding = nn.Parameter(torch.randn(d) * 0.02)
        self.blocks = nn.ModuleList(FactorizedBlock(d, n_heads, ff_mult) for _ in range(n_blocks))
        self.map_encoder = nn.Sequential(
            nn.Conv2d(1, 16, 5, stride=2, padding=2), nn.ReLU(),
            nn.Conv2d(16, 32, 3, stride=2, padding=1), nn.ReLU(),
            nn.Conv2d(32, 32, 3, stride=2, padding=1), nn.ReLU(),
            nn.AdaptiveAvgPool2d(4), nn.Flatten(), nn.Linear(32 * 16, d),
        )
        self.query = nn.Sequential(nn.Linear(FEATURES + 1 + 5, d), nn.ReLU(), nn.Linear(d, d))
        self.norm_q, self.norm_kv = nn.LayerNorm(d), nn.LayerNorm(d)
        self.cross = nn.MultiheadAttention(d, n_heads, batch_first=True)
        self.gate = nn.Linear(2 * d, d)
        if r:
            self.scan_encoder = nn.Sequential(nn.Linear(r, d), nn.ReLU(), nn.Linear(d, d))
            nn.init.zeros_(self.scan_encoder[2].weight)
            nn.init.zeros_(self.scan_encoder[2].bias)

    # ------------------------------------------------------------------ inputs
    def split(self, observations: torch.Tensor | dict[str, torch.Tensor]) -> dict[str, torch.Tensor]:
        """The observation's entries as (B, ...) tensors, from a Dict batch or a flat (B, n) batch."""
        if isinstance(observations, dict):
            keys = OBS_KEYS + (("scan",) if self.scan_rays else ())
            return {key: observations[key].float() for key in keys}
        if observations.dim() != 2:
            raise ValueError(f"flat observations must be (batch, n), got shape {tuple(observations.shape)}")
        b = observations.shape[0]
        return {key: observations[:, s:e].float().reshape(b, *shape) for key, (s, e, shape) in self._layout.items()}

    def agent_states(self, obs: dict[str, torch.Tensor]) -> tuple[torch.Tensor, torch.Tensor]:
        """``(S (B, 1+K, T, 7), valid (B, 1+K, T))`` with the robot at row 0 (current step only)."""
        agents, mask, vel = obs["agents"], obs["agents_mask"] > 0.5, obs["velocity"]
        b, _, t, _ = agents.shape
        robot = torch.zeros(b, 1, t, FEATURES, dtype=agents.dtype, device=agents.device)
        robot[:, 0, -1, 2:4] = vel[:, :2]
        robot[:, 0, -1, 4] = 1.0
        robot[:, 0, -1, 6] = self.robot_radius
        robot_valid = torch.zeros(b, 1, t, dtype=torch.bool, device=agents.device)
        robot_valid[:, 0, -1] = True
        valid = torch.cat([robot_valid, mask], dim=1)
        # Masked entries are zero in the env already; zeroing them here makes that a guarantee.
        states = torch.cat([robot, agents], dim=1) * valid[..., None].to(agents.dtype)
        return states, valid

    def _scale(self, states: torch.Tensor) -> torch.Tensor:
        scale = torch.ones(FEATURES, dtype=states.dtype, device=states.device)
        scale[:2] = 1.0 / self.length_scale
        return states * scale

    # ------------------------------------------------------------------ model
    def encode_agents(self, states: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
        """Tokens (B, 1+K, T, D) after the factorised blocks."""
        x = self.embed(self._scale(states)) + self.time_embedding
        x = torch.cat([x[:, :1] + self.robot_embedding, x[:, 1:]], dim=1)
        for block in self.blocks:
            x = block(x, valid)
        return x

    def forward(self, observations: torch.Tensor | dict[str, torch.Tensor]) -> torch.Tensor:
        obs = self.split(observations)
        states, valid = self.agent_states(obs)
        tokens = self.encode_agents(states, valid)
        b = states.shape[0]
        u = tokens[:, 1:, -1]  # last-step tokens of the K neighbours
        m = self.map_encoder(obs["map"][:, None])
        memory = torch.cat([u, m[:, None]], dim=1)
        pad = torch.cat([~valid[:, 1:, -1], torch.zeros(b, 1, dtype=torch.bool, device=u.device)], dim=1)
        goal = obs["goal"] * torch.tensor([1 / self.length_scale] * 3 + [1.0, 1.0], device=u.device)
        q = self.query(torch.cat([self._scale(states[:, 0, -1]), obs["velocity"][:, 2:3], goal], dim=1))
        if self.scan_rays:
            q = q + self.scan_encoder(obs["scan"])
        kv = self.norm_kv(memory)
        z, _ = self.cross(self.norm_q(q)[:, None], kv, kv, key_padding_mask=pad, need_weights=False)
        z = z[:, 0]
        alpha = torch.sigmoid(self.gate(torch.cat([z, q], dim=1)))
        return alpha * q + (1.0 - alpha) * z

    def config(self) -> dict[str, Any]:
        """The constructor arguments (JSON-able) that rebuild this extractor for the same space."""
        return {"features_dim": int(self.features_dim), "n_heads": self.n_heads, "n_blocks": self.n_blocks,
                "ff_mult": self.ff_mult, "robot_radius": self.robot_radius, "length_scale": self.length_scale,
                "k_neighbors": self.k_neighbors, "history": self.history,
                **({"scan_rays": self.scan_rays} if self.scan_rays else {})}


def transformer_policy_kwargs(features_dim: int = 128, n_heads: int = 4, n_blocks: int = 3, ff_mult: int = 2,
                              net_arch: tuple[int, ...] | list[int] = (128, 128),
                              robot_radius: float = DEFAULT_ROBOT_RADIUS, length_scale: float = 5.0,
                              k_neighbors: int | None = None, history: int | None = None,
                              scan_rays: int | None = None) -> dict[str, Any]:
    """``policy_kwargs`` for SB3 (``PPO("MlpPolicy" | "MultiInputPolicy", env, policy_kwargs=...)``).

    The extractor's output ``h`` feeds separate actor and critic MLPs of widths ``net_arch``; the
    extractor is shared by both (SB3's default for on-policy algorithms).

    Args:
        features_dim, n_heads, n_blocks, ff_mult, robot_radius, length_scale, k_neighbors, history, scan_rays:
            see :class:`SpatioTemporalExtractor`.
        net_arch: hidden widths of the actor and of the critic heads.
    """
    arch = [int(w) for w in net_arch]
    if any(w < 1 for w in arch):
        raise ValueError(f"net_arch widths must be >= 1, got {list(net_arch)}")
    return {
        "features_extractor_class": SpatioTemporalExtractor,
        "features_extractor_kwargs": {"features_dim": features_dim, "n_heads": n_heads, "n_blocks": n_blocks,
                                      "ff_mult": ff_mult, "robot_radius": robot_radius,
                                      "length_scale": length_scale, "k_neighbors": k_neighbors,
                                      "history": history, **({"scan_rays": scan_rays} if scan_rays else {})},
        "net_arch": {"pi": list(arch), "vf": list(arch)},
        "share_features_extractor": True,
    }
