"""The rows at fault: which rows (or priors, or units) make the data inconsistent
(conflict.py), and solves that let at most K rows fail (solve.py, proof.py, dropping.py,
classify.py), naming the rows as the user counts them (rows.py)."""
