"""Evaluation: metrics (pure functions of recorded episodes), episode recording, runners and reports."""
