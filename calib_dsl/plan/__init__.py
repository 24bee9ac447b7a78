"""Planning a measurement campaign (issue #43): which configurations to measure, and how
many, for the guaranteed enclosure to be smallest."""
