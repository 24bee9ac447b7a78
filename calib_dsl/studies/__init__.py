"""What a user asks beside a solve: simulated data and campaigns, numeric kinematics,
identifiability advice, a model's robots as frames, a linearized yardstick (predictions
live in accuracy/). Nothing the solver runs imports them."""
