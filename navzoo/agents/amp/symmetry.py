"""Left/right mirror symmetry of the AMP controller's observations and actions.

A humanoid walking in a world reflected through its sagittal plane (world ``y -> -y``, left and right
limbs swapped; :func:`navzoo.agents.motion_lib.mirror_frames`) should do the mirror image of what it
does in the original world. Both the policy observation (:func:`navzoo.agents.amp.features.policy_observation`)
and the action (:func:`navzoo.agents.amp.sim.actions_to_targets`) transform under that reflection by a
*signed permutation*: every column goes to one column, possibly with its sign flipped. This module
builds those two maps, so that

* a trained policy can be made symmetric at inference (:class:`SymmetricActor`:
  ``a = (pi(o) + M_a pi(M_o o)) / 2``), which removes any constant left/right bias such as a drift to
  one side of every path;
* the learner can penalise asymmetry while it trains (the mirror loss of Yu, Turk and Liu 2018,
  "Learning Symmetric and Low-Energy Locomotion": ``|pi(o) - M_a pi(M_o o)|^2``; ``AmpConfig.mirror_coef``).

How each part of the observation mirrors (heading-frame vectors ``(x, y, z) -> (x, -y, z)``; angular
velocities are pseudovectors, ``(x, y, z) -> (-x, y, -z)`` in the heading frame; a local joint
rotation ``R -> S R S`` with ``S = diag(1, 1, -1)`` in the URDF's joint frames, so its x-axis column
``(a, b, c) -> (a, b, -c)``, its z-axis column ``-> (-a, -b, c)`` and its child-frame angular
velocity ``-> (-x, -y, z)``; right and left joints and key bodies swap):

====================  ==============================================================================
part                  mirror
====================  ==============================================================================
root height           unchanged
root forward / up     y components negated
root velocities       linear: y negated; angular: x and z negated
8 ball joints (6-D)   swap right/left; x column: z negated; z column: x and y negated
4 hinges              swap right/left, values kept
ball joint velocity   swap right/left; x and y negated
hinge velocity        swap right/left
key bodies            right/left hands and feet swapped; y negated
target points         y negated
obstacle rays         ray k (k x 22.5 deg counter-clockwise from the heading) <-> ray (16 - k) mod 16
====================  ==============================================================================

Actions: ball joint exponential maps swap right/left with x and y negated; hinge actions swap.
Both maps are involutions (applying one twice is the identity); the property that matters, that the
observation of a mirrored state is the mirrored observation, is tested against the mirrored motion
clips in ``tests/agents/test_amp_symmetry.py``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import torch
from torch import nn

from navzoo.agents.amp.features import FEATURE_DIM, FEATURE_SLICES, N_FEATURE_KEYS, N_RAYS, REV, SPH
from navzoo.agents.motion_lib import _REV_SWAP, _SPH_SWAP

__all__ = [
    "SignedPermutation",
    "SymmetricActor",
    "action_mirror",
    "observation_mirror",
    "self_observation_mirror",
]

#: Key bodies of the features: right hand, left hand, right foot, left foot.
_KEY_SWAP = np.array([1, 0, 3, 2])
#: Target points the policies were trained with (``PathTaskConfig.n_waypoints``).
DEFAULT_WAYPOINTS = 10


class SignedPermutation:
    """``y[..., i] = sign[i] * x[..., index[i]]``: a linear map that is a signed permutation.

    Works on numpy arrays and torch tensors with the columns on the last axis.
    """

    def __init__(self, index: np.ndarray, sign: np.ndarray) -> None:
        index = np.asarray(index, dtype=np.int64)
        sign = np.asarray(sign, dtype=np.float64)
        n = index.size
        if index.shape != (n,) or sign.shape != (n,) or sorted(index.tolist()) != list(range(n)):
            raise ValueError("a signed permutation needs a permutation of 0..n-1 and n signs")
        if not np.all(np.abs(sign) == 1.0):
            raise ValueError("signs must be +1 or -1")
        self.index = index
        self.sign = sign
        self._torch: dict[Any, tuple[torch.Tensor, torch.Tensor]] = {}

    @property
    def dim(self) -> int:
        return int(self.index.size)

    def __call__(self, x: Any) -> Any:
        if isinstance(x, torch.Tensor):
            key = (x.device, x.dtype)
            if key not in self._torch:
                self._torch[key] = (torch.as_tensor(self.index, device=x.device),
                                    torch.as_tensor(self.sign, device=x.device, dtype=x.dtype))
            idx, sgn = self._torch[key]
            return x.index_select(-1, idx) * sgn
        x = np.asarray(x)
        if x.shape[-1] != self.dim:
            raise ValueError(f"expected {self.dim} columns, got shape {x.shape}")
        return (x[..., self.index] * self.sign).astype(x.dtype, copy=False)

    def matrix(self) -> np.ndarray:
        """The (n, n) matrix M with ``y = M x``."""
        m = np.zeros((self.dim, self.dim))
        m[np.arange(self.dim), self.index] = self.sign
        return m


def _vectors(start: int, n: int, per: int, flips: tuple[float, ...], swap: np.ndarray | None
             ) -> tuple[np.ndarray, np.ndarray]:
    """index/sign of ``n`` groups of ``per`` columns from ``start``, groups permuted by ``swap``
    (output group g reads input group ``swap[g]``) and columns signed by ``flips``."""
    order = np.arange(n) if swap is None else np.asarray(swap)
    index = (start + order[:, None] * per + np.arange(per)[None, :]).reshape(-1)
    sign = np.tile(np.asarray(flips, dtype=np.float64), n)
    return index, sign


def self_observation_mirror() -> SignedPermutation:
    """The mirror of the 105 self-observation / AMP feature columns (layout in :mod:`features`)."""
    idx, sgn = np.arange(FEATURE_DIM), np.ones(FEATURE_DIM)

    def put(name: str, part: tuple[np.ndarray, np.ndarray]) -> None:
        sl = FEATURE_SLICES[name]
        idx[sl], sgn[sl] = part

    put("root_rot", _vectors(FEATURE_SLICES["root_rot"].start, 2, 3, (1, -1, 1), None))
    put("root_lin_vel", _vectors(FEATURE_SLICES["root_lin_vel"].start, 1, 3, (1, -1, 1), None))
    put("root_ang_vel", _vectors(FEATURE_SLICES["root_ang_vel"].start, 1, 3, (-1, 1, -1), None))
    put("sph_rot", _vectors(FEATURE_SLICES["sph_rot"].start, len(SPH), 6, (1, 1, -1, -1, -1, 1), _SPH_SWAP))
    put("rev_angle", _vectors(FEATURE_SLICES["rev_angle"].start, len(REV), 1, (1,), _REV_SWAP))
    put("sph_vel", _vectors(FEATURE_SLICES["sph_vel"].start, len(SPH), 3, (-1, -1, 1), _SPH_SWAP))
    put("rev_vel", _vectors(FEATURE_SLICES["rev_vel"].start, len(REV), 1, (1,), _REV_SWAP))
    put("key_pos", _vectors(FEATURE_SLICES["key_pos"].start, N_FEATURE_KEYS, 3, (1, -1, 1), _KEY_SWAP))
    return SignedPermutation(idx, sgn)


def observation_mirror(obs_dim: int, n_waypoints: int = DEFAULT_WAYPOINTS) -> SignedPermutation:
    """The mirror of a policy observation of ``obs_dim`` columns: the 105 self-observation columns,
    ``n_waypoints`` target points (x, y) and, when ``obs_dim`` has room for them, the 16 obstacle rays."""
    base = FEATURE_DIM + 2 * int(n_waypoints)
    if obs_dim not in (base, base + N_RAYS):
        raise ValueError(f"cannot mirror an observation of {obs_dim} columns: expected {base} "
                         f"(self-observation + {n_waypoints} target points) or {base + N_RAYS} (+ {N_RAYS} rays)")
    own = self_observation_mirror()
    wp_idx, wp_sgn = _vectors(FEATURE_DIM, int(n_waypoints), 2, (1, -1), None)
    parts_idx, parts_sgn = [own.index, wp_idx], [own.sign, wp_sgn]
    if obs_dim == base + N_RAYS:
        parts_idx.append(base + (-np.arange(N_RAYS)) % N_RAYS)
        parts_sgn.append(np.ones(N_RAYS))
    return SignedPermutation(np.concatenate(parts_idx), np.concatenate(parts_sgn))


def action_mirror() -> SignedPermutation:
    """The mirror of the 28 actions (8 ball joints x 3 exponential-map components, 4 hinges); the
    action scales and offsets of :mod:`navzoo.agents.amp.sim` are left/right symmetric (checked here)."""
    from navzoo.agents.amp.sim import REV_ACTION_OFFSET, REV_ACTION_SCALE, SPH_ACTION_SCALE

    if not (np.array_equal(SPH_ACTION_SCALE, SPH_ACTION_SCALE[_SPH_SWAP])
            and np.array_equal(REV_ACTION_OFFSET, REV_ACTION_OFFSET[_REV_SWAP])
            and np.array_equal(REV_ACTION_SCALE, REV_ACTION_SCALE[_REV_SWAP])):
        raise ValueError("the action scales/offsets are not left/right symmetric: actions cannot be mirrored")
    s_idx, s_sgn = _vectors(0, len(SPH), 3, (-1, -1, 1), _SPH_SWAP)
    r_idx, r_sgn = _vectors(3 * len(SPH), len(REV), 1, (1,), _REV_SWAP)
    return SignedPermutation(np.concatenate([s_idx, r_idx]), np.concatenate([s_sgn, r_sgn]))


class SymmetricActor(nn.Module):
    """An actor made left/right symmetric: ``mean(o) = (actor(o) + M_a actor(M_o' o)) / 2``.

    ``obs_norm`` normalises raw observations (the actor's inputs are normalised ones); the mirror is
    applied to the raw observation, so the normaliser need not be symmetric. ``forward`` takes *raw*
    observations and returns the symmetric mean action.
    """

    def __init__(self, actor: nn.Module, obs_norm: Any, obs_dim: int, n_waypoints: int = DEFAULT_WAYPOINTS):
        super().__init__()
        self.actor = actor
        self.obs_norm = obs_norm
        self.obs_mirror = observation_mirror(obs_dim, n_waypoints)
        self.act_mirror = action_mirror()

    def forward(self, raw_obs: torch.Tensor) -> torch.Tensor:
        a = self.actor(self.obs_norm.normalize(raw_obs))
        b = self.actor(self.obs_norm.normalize(self.obs_mirror(raw_obs)))
        return 0.5 * (a + self.act_mirror(b))
