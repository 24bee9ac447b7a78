"""What the solver relies on beside its contractors: identifiability (rank, combinations),
least squares and priors about it, Chebyshev fits, points proven to be solutions, the
smallest consistent error bound, residual ranges and leverage."""
