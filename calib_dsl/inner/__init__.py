"""Certified inner bounds: values each unknown provably takes at solutions (bounds.py, its LPs
in lp.py, warm-started from the solve's bases, starts.py), and a result shaved towards them
(shave.py)."""
