"""Linear programs: the HiGHS solve of a relaxation and its certified bounds."""
