"""Summary statistics of errors and confidence intervals over Monte Carlo runs."""

from __future__ import annotations

import numpy as np


def mean_ci95(values) -> tuple[float, float, float]:
    """Mean and two-sided 95% Student-t interval of the mean: m +- t_{0.975, n-1} s / sqrt(n).

    NaN values are ignored. With a single value the interval is (nan, nan).
    t_{q, dof} = stdtrit(dof, q), the Student-t quantile (what scipy.stats.t.ppf evaluates;
    scipy.special alone imports in a fraction of scipy.stats' time). Imported here, not at
    module level: most jobs import this module through wsnloc.results without needing it.
    """
    from scipy.special import stdtrit

    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(v.mean())
    if len(v) < 2:
        return mean, float("nan"), float("nan")
    half = float(stdtrit(len(v) - 1, 0.975) * v.std(ddof=1) / np.sqrt(len(v)))
    return mean, mean - half, mean + half


ERROR_STATS = ("rmse", "mean", "median", "p75", "p90", "p95", "max", "n")


def error_summary(errors) -> dict[str, float]:
    """RMSE, mean, median, 75th, 90th and 95th percentiles and max of error magnitudes (m).

    IPIN/EvAAL practice: report the distribution (the third quartile p75 is EvAAL's score),
    not only the RMSE.
    """
    e = np.asarray(errors, dtype=float)
    e = e[np.isfinite(e)]
    if len(e) == 0:
        return {k: float("nan") if k != "n" else 0.0 for k in ERROR_STATS}
    a = np.abs(e)
    return {
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mean": float(a.mean()),
        "median": float(np.median(a)),
        "p75": float(np.percentile(a, 75)),
        "p90": float(np.percentile(a, 90)),
        "p95": float(np.percentile(a, 95)),
        "max": float(a.max()),
        "n": float(len(e)),
    }
