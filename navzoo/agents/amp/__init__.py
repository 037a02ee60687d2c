"""Adversarial Motion Prior (AMP) pedestrian controller: physics humanoids, features, training."""
