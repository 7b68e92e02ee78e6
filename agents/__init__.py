"""Stable-Baselines3 training, evaluation and open-loop baselines for the dipenv environments.

Command lines: ``python -m agents.train``, ``python -m agents.open_loop``, ``python -m agents.evaluate``
and the end-to-end ``python -m agents.demo``; independent tasks run through :mod:`agents.tasks`.
"""
