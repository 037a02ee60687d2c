"""Multi-agent training of robots and pedestrians with Ray RLlib (optional extra ``navzoo[ray]``).

- :mod:`navzoo.rl.config`: :class:`JointConfig`, which side learns and what drives the frozen one
  (no Ray needed).
- :mod:`navzoo.rl.rllib_env`: navzoo as an RLlib ``MultiAgentEnv`` (registered as ``"navzoo"``).
- :mod:`navzoo.rl.train`: PPO with a ``"robot"`` and a ``"human"`` policy on a local or remote Ray
  cluster (``python -m navzoo.rl.train``).

See docs/scaling.md.
"""

from navzoo.rl.config import JointConfig, policy_mapping_fn

__all__ = ["JointConfig", "policy_mapping_fn"]
