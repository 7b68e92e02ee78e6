"""Contacts kernels of the simulator."""
