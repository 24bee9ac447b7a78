"""Relaxations: gradients, first- and second-order Taylor models of the program over a box."""
