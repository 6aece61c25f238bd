"""Plane geometry of a campaign: walls, paths, and (later) position solvers."""
