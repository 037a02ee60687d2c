"""Actor, critic and discriminator MLPs of the AMP learner, and the discriminator's gradient penalty.

All three are plain ReLU MLPs on *normalised* inputs (normalisation lives in
:mod:`navzoo.agents.amp.normalizer`, outside the networks, so that the same weights can be shipped
with their statistics). Initialisation follows CleanRL for actor and critic (orthogonal, gain
sqrt(2) in hidden layers, 0.01 for the action mean so that a fresh policy acts near zero, 1 for the
value) and IsaacGymEnvs ``amp_network_builder.py`` for the discriminator's logit layer (uniform in
[-1, 1], zero bias).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import torch
from torch import nn

_ACTIVATIONS: dict[str, type[nn.Module]] = {"relu": nn.ReLU, "elu": nn.ELU, "tanh": nn.Tanh}


def _linear(in_dim: int, out_dim: int, gain: float, generator: torch.Generator | None) -> nn.Linear:
    layer = nn.Linear(in_dim, out_dim)
    nn.init.orthogonal_(layer.weight, gain=gain, generator=generator)
    nn.init.zeros_(layer.bias)
    return layer


def mlp_trunk(
    in_dim: int, hidden: Sequence[int], activation: str = "relu", generator: torch.Generator | None = None
) -> nn.Sequential:
    """Hidden layers only: ``Linear -> act`` for every width in ``hidden``.

    Raises:
        ValueError: unknown activation or non-positive width.
    """
    if activation not in _ACTIVATIONS:
        raise ValueError(f"activation must be one of {sorted(_ACTIVATIONS)}, got {activation!r}")
    if in_dim <= 0 or any(int(h) <= 0 for h in hidden):
        raise ValueError(f"dimensions must be positive, got in_dim={in_dim}, hidden={list(hidden)}")
    layers: list[nn.Module] = []
    d = in_dim
    for h in hidden:
        layers += [_linear(d, int(h), math.sqrt(2.0), generator), _ACTIVATIONS[activation]()]
        d = int(h)
    return nn.Sequential(*layers)


class Actor(nn.Module):
    """Gaussian policy: an MLP gives the mean action, ``log_std`` is a state-independent parameter.

    With ``learn_std=False`` (IsaacGymEnvs AMP: ``fixed_sigma``, ``sigma_init -2.9``) the log-std is
    a parameter with ``requires_grad=False``: it is part of the ``state_dict`` but never optimised.
    Actions live in the normalised box [-1, 1]; the mean is unbounded and kept inside by the bounds
    loss.
    """

    def __init__(
        self,
        obs_dim: int,
        act_dim: int,
        hidden: Sequence[int],
        activation: str = "relu",
        init_log_std: float = -2.9,
        learn_std: bool = False,
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        self.trunk = mlp_trunk(obs_dim, hidden, activation, generator)
        last = int(hidden[-1]) if len(hidden) else obs_dim
        self.mean = _linear(last, act_dim, 0.01, generator)
        self.log_std = nn.Parameter(torch.full((act_dim,), float(init_log_std)), requires_grad=learn_std)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        """Mean action (N, act_dim) of normalised observations (N, obs_dim)."""
        return self.mean(self.trunk(obs))

    def dist(self, obs: torch.Tensor) -> torch.distributions.Normal:
        mu = self(obs)
        return torch.distributions.Normal(mu, self.log_std.exp().expand_as(mu))


class Critic(nn.Module):
    """State-value MLP; outputs (N,) values in the value normaliser's units."""

    def __init__(
        self,
        obs_dim: int,
        hidden: Sequence[int],
        activation: str = "relu",
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        self.trunk = mlp_trunk(obs_dim, hidden, activation, generator)
        last = int(hidden[-1]) if len(hidden) else obs_dim
        self.value = _linear(last, 1, 1.0, generator)

    def forward(self, obs: torch.Tensor) -> torch.Tensor:
        return self.value(self.trunk(obs)).squeeze(-1)


class Discriminator(nn.Module):
    """AMP discriminator: MLP trunk + a linear logit layer; ``D(x)`` is a logit (N,)."""

    def __init__(
        self,
        amp_obs_dim: int,
        hidden: Sequence[int],
        activation: str = "relu",
        generator: torch.Generator | None = None,
    ) -> None:
        super().__init__()
        self.trunk = mlp_trunk(amp_obs_dim, hidden, activation, generator)
        last = int(hidden[-1]) if len(hidden) else amp_obs_dim
        self.logits = nn.Linear(last, 1)
        nn.init.uniform_(self.logits.weight, -1.0, 1.0, generator=generator)
        nn.init.zeros_(self.logits.bias)

    def forward(self, amp_obs: torch.Tensor) -> torch.Tensor:
        return self.logits(self.trunk(amp_obs)).squeeze(-1)

    def logit_weights(self) -> torch.Tensor:
        """Flattened weights of the logit layer (for the logit regulariser)."""
        return self.logits.weight.flatten()

    def all_weights(self) -> torch.Tensor:
        """Flattened weights (not biases) of every linear layer (for the weight decay term)."""
        ws = [m.weight.flatten() for m in self.modules() if isinstance(m, nn.Linear)]
        return torch.cat(ws)


def style_reward(logits: torch.Tensor) -> torch.Tensor:
    """AMP style reward of the BCE discriminator: ``-log(max(1 - sigmoid(D), 1e-4))``.

    Computed as ``softplus(D)`` (= ``-log(1 - sigmoid(D))`` exactly) clipped at ``-log(1e-4)``, which
    is the same function without the cancellation of ``1 - sigmoid`` for large logits. Bounded in
    [0, 9.21]: a reward spike from the discriminator is impossible by construction.
    """
    return torch.clamp(nn.functional.softplus(logits), max=-math.log(1e-4))


def gradient_penalty(logits: torch.Tensor, inputs: torch.Tensor, create_graph: bool = True) -> torch.Tensor:
    """``mean_i || d D(x_i) / d x_i ||^2``: the AMP penalty on reference samples.

    ``logits`` (N,) must have been computed from ``inputs`` (N, d), a tensor that requires grad (the
    normalised discriminator input). With ``create_graph`` the result can be back-propagated into the
    discriminator's weights (double back-prop). A discriminator whose output does not depend on its
    input has zero penalty.
    """
    if not logits.requires_grad:
        return torch.zeros((), device=logits.device)
    (grad,) = torch.autograd.grad(logits.sum(), inputs, create_graph=create_graph, allow_unused=True)
    if grad is None:
        return torch.zeros((), device=logits.device)
    return grad.square().sum(dim=-1).mean()


def bounds_loss(mu: torch.Tensor, soft_bound: float = 1.1) -> torch.Tensor:
    """rl_games' bounds loss: squared excess of the mean action beyond ``±soft_bound``, summed over
    action dimensions and averaged over the batch."""
    high = torch.clamp_min(mu - soft_bound, 0.0).square()
    low = torch.clamp_max(mu + soft_bound, 0.0).square()
    return (high + low).sum(dim=-1).mean()
