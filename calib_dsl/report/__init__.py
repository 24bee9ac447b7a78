"""Text and JSON output of a solve."""
