"""Trained policies shipped with navzoo, one folder each (weights, config, model card)."""
