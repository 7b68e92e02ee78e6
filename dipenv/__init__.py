"""Gymnasium environments for electric-field control of suspension rheology (not yet implemented)."""
