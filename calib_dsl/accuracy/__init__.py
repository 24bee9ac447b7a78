"""The robot's accuracy: the solve's accuracy statement in the model's length unit
(statement.py, points.py, fit.py) and guaranteed predictions at other poses."""
