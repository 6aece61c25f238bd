"""Metrics: error statistics, confidence intervals over Monte Carlo runs, data quality."""
