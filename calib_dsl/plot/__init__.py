"""Figures of results (`calibc plot`, `solve --plot`, `validate --plot`), drawn from what the
JSON of a solve or a validation holds: one module per kind of figure, `figure.py` to pick the
kinds a result supports and save them. matplotlib is an optional extra (calibc[plot]), always
used through its object API and the Agg canvas: no window, no global state.
"""
