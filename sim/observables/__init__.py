"""Observables kernels of the simulator."""
