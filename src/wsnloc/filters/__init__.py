"""State estimators with explicit matrices (F, Q, H, R, P), filterpy-style attributes."""
