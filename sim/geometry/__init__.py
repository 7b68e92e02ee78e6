"""Geometry kernels of the simulator."""
