"""Strategies that compose contractors: hc4, the tight rounds, splitting, the change of unknowns."""
