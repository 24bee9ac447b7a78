"""calibc: guaranteed robot calibration by interval constraint propagation."""

__version__ = "0.1.0"
