"""Interval arithmetic: outward rounding, intervals, per-operator projections, the rotation
primitive.
"""
