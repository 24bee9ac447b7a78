"""Analyses beside the solve: identifiability, least squares, reference hulls, kinematics,
simulation.
"""
