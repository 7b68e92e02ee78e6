"""Hydrodynamics kernels of the simulator."""
