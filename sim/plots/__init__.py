"""Figures and movies made from a run's files (the future home of every figure; for now the movie)."""
