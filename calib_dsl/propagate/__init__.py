"""The fixed-point propagator: the loop, its vectorized kernels, the diagnosis of an
inconsistency."""
