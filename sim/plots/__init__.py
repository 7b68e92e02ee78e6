"""Figures and movies made from a run's files: a run's and a flow curve's figures (:mod:`sim.plots.figures`),
a sweep's figures and summary (:mod:`sim.plots.sweep`, ``python -m sim figures``) and the movie of a
trajectory (:mod:`sim.plots.movie`, ``python -m sim movie``)."""
