"""What a user asks beside a solve: predictions, simulated data and campaigns, numeric
kinematics, identifiability advice, a model's robots as frames, a linearized yardstick.
Nothing the solver runs imports them."""
