"""Trackers that smooth a sequence of position fixes."""
