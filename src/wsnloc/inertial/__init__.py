"""Inertial processing: dead reckoning, sensor bias estimation (and motion detection)."""
