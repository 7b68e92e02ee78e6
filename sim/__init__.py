"""Stokesian-dynamics simulator of ideally conductive spheres under shear (public API)."""
