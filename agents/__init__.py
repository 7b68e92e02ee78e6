"""Stable-Baselines3 training, evaluation and open-loop baselines (not yet implemented)."""
