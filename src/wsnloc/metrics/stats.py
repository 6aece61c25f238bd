"""Summary statistics of errors and confidence intervals over Monte Carlo runs.

The Student-t quantile of the intervals is computed here in plain Python (`student_t_quantile`):
importing scipy.special for it cost each job that writes results rows ~0.17 s.
"""

from __future__ import annotations

import functools
import math
from statistics import NormalDist

import numpy as np

# Stirling series of ln Gamma(x) - [(x - 1/2) ln x - x + ln(2 pi)/2] = sum_k B_2k / (2k (2k-1) x^(2k-1)):
# coefficients B_2k / (2k (2k-1)), k = 1..7; for x >= _STIRLING_FROM the first omitted term is < 4e-17.
_STIRLING = (1 / 12, -1 / 360, 1 / 1260, -1 / 1680, 1 / 1188, -691 / 360360, 1 / 156)
_STIRLING_FROM = 10.0
_EPS = 2.0 ** -52           # double precision: continued-fraction convergence test
_TINY = 1e-300              # Lentz's guard against a zero denominator
_MAX_TERMS = 10_000         # continued-fraction terms (at most 54 used for 1 <= dof <= 1e6, q <= 0.999)
_NEWTON_STOP = 1e-9         # relative Newton step after which the next error is ~(step)^2 << ulp
_MAX_NEWTON = 100           # Newton steps (at most 12 used for 1 <= dof <= 1e6, q <= 0.999)
# 1 / Phi^-1(3/4) = 1.4826: the median absolute deviation of a normal sample times this estimates its sigma
MAD_TO_SIGMA = 1.0 / NormalDist().inv_cdf(0.75)


def robust_sigma(deviations) -> float:
    """The normalised median absolute deviation MAD_TO_SIGMA * median |deviations| of deviations
    from a centre the caller chose (the sample's median, a per-group median or a fitted line): a
    standard deviation that outliers do not inflate. As scipy.stats.median_abs_deviation(x,
    scale="normal") for deviations x - median(x); not imported here (scipy.stats costs each job
    a few tenths of a second)."""
    return float(MAD_TO_SIGMA * np.median(np.abs(deviations)))


def _stirling_remainder(x: float) -> float:
    """Delta(x) = ln Gamma(x) - (x - 1/2) ln x + x - ln(2 pi)/2 for x >= 10 (Stirling series)."""
    y = 1.0 / (x * x)
    total = 0.0
    for coefficient in reversed(_STIRLING):
        total = total * y + coefficient
    return total / x


def _t_density_constant(dof: float) -> float:
    """c(nu) = Gamma((nu+1)/2) / (sqrt(nu pi) Gamma(nu/2)), the Student-t density at 0 (nu = dof).

    With a = nu/2 and g(a) = Gamma(a + 1/2) / (Gamma(a) sqrt(a)), c = g(a) / sqrt(2 pi), where
      ln g(a) = a ln(1 + 1/(2a)) - 1/2 + Delta(a + 1/2) - Delta(a)       (Stirling, a >= 10)
      g(a) = g(a + 1) sqrt(a (a + 1)) / (a + 1/2)                       (Gamma(x+1) = x Gamma(x)).
    Unlike lgamma differences (ulp of ln Gamma(a) ~ a ln a), this keeps c to a few ulp for any nu.
    """
    a = 0.5 * dof
    factor = 1.0
    while a < _STIRLING_FROM:
        factor *= math.sqrt(a * (a + 1.0)) / (a + 0.5)
        a += 1.0
    log_g = a * math.log1p(0.5 / a) - 0.5 + _stirling_remainder(a + 0.5) - _stirling_remainder(a)
    return factor * math.exp(log_g) / math.sqrt(2.0 * math.pi)


def _beta_continued_fraction(a: float, b: float, x: float, y: float) -> float:
    """F in I_x(a, b) = x^a y^b / (B(a, b) F), the regularized incomplete beta function (y = 1 - x).

    F = beta_0 + alpha_1/(beta_1 + alpha_2/(beta_2 + ...)) with
      alpha_m = (a+m-1)(a+b+m-1) m (b-m) x^2 / (a+2m-1)^2,
      beta_m = m + m (b-m) x / (a+2m-1) + (a+m)(a y - b x + 1 + m (2-x)) / (a+2m+1),
    DiDonato & Morris' form (ACM TOMS 708, BFRAC; Boost's ibeta_fraction2), evaluated by the
    modified Lentz method. Unlike Numerical Recipes' betacf (6.4), written in x alone, it takes y
    exactly: with x = nu/(nu+t^2) ~ 1 the rounding of x cost betacf ~nu/2 ulp. It converges fast
    for x < (a+1)/(a+b+2).
    """
    fraction = a * (a * y - b * x + 1.0) / (a + 1.0)
    c, d = fraction, 0.0
    for m in range(1, _MAX_TERMS):
        alpha = (a + m - 1.0) * (a + b + m - 1.0) * m * (b - m) * x * x / (a + 2 * m - 1.0) ** 2
        beta = (m + m * (b - m) * x / (a + 2 * m - 1.0)
                + (a + m) * (a * y - b * x + 1.0 + m * (2.0 - x)) / (a + 2 * m + 1.0))
        d = beta + alpha * d
        d = 1.0 / (d if abs(d) > _TINY else _TINY)
        c = beta + alpha / c
        c = c if abs(c) > _TINY else _TINY
        fraction *= c * d
        if abs(c * d - 1.0) <= _EPS:
            return fraction
    raise ArithmeticError(f"incomplete beta continued fraction did not converge (a={a}, b={b}, x={x})")


def _t_cdf_residual(t: float, dof: float, tail: float, center: float) -> tuple[float, float]:
    """F(t) - q and the density f(t) of Student's t with nu = dof at t >= 0 (q = 1 - tail = 1/2 + center).

    f(t) = c(nu) (1 + t^2/nu)^(-(nu+1)/2). With x = nu/(nu+t^2) and y = t^2/(nu+t^2), the
    incomplete beta prefactor of the t distribution is x^(nu/2) y^(1/2) / B(nu/2, 1/2) = t f(t), so
      1 - F(t) = I_x(nu/2, 1/2) / 2 = t f(t) / (2 F(nu/2, 1/2, x, y))      (tail form)
      F(t) - 1/2 = I_y(1/2, nu/2) / 2 = t f(t) / (2 F(1/2, nu/2, y, x))    (center form),
    F of `_beta_continued_fraction`, each used where it converges fast: the tail form for
    x < (nu/2+1)/(nu/2+5/2), i.e. t^2 (nu+2) > 3 nu.
    """
    s = t * t
    density = _t_density_constant(dof) * math.exp(-0.5 * (dof + 1.0) * math.log1p(s / dof))
    x, y = dof / (dof + s), s / (dof + s)
    if s * (dof + 2.0) > 3.0 * dof:
        return tail - 0.5 * t * density / _beta_continued_fraction(0.5 * dof, 0.5, x, y), density
    return 0.5 * t * density / _beta_continued_fraction(0.5, 0.5 * dof, y, x) - center, density


@functools.lru_cache(maxsize=1024)    # ~70 us a call; mean_ci95 asks for few (0.975, n-1)
def student_t_quantile(q: float, dof: float) -> float:
    """t_{q, nu}: the q quantile of Student's t distribution with nu = dof >= 1 degrees of freedom.

    What scipy.special.stdtrit(dof, q) (scipy.stats.t.ppf) evaluates (within 1e-14 relative for
    q in [0.6, 0.995]). Closed forms: nu = 1, t = tan(pi (q - 1/2)) = cot(pi (1-q)); nu = 2,
    t = (2q - 1) sqrt(2 / (1 - (2q-1)^2)) = (q - 1/2) sqrt(2 / (q (1-q))). Otherwise Newton's
    iteration t <- t - (F(t) - q) / f(t) on the CDF F (`_t_cdf_residual`) from the normal
    quantile z_q: for q > 1/2 and t > 0, F is concave and F(z_q) < q, so the iterates increase
    monotonically to the root. q < 1/2 by
    symmetry, t_q = -t_{1-q}; the iteration works on tail = min(q, 1-q) and center = |q - 1/2|,
    exact in floating point for q in [1/4, 1].
    """
    if not (0.0 < q < 1.0 and 1.0 <= dof < math.inf):
        raise ValueError(f"student_t_quantile needs 0 < q < 1 and finite dof >= 1, got q={q}, dof={dof}")
    tail, center = min(q, 1.0 - q), abs(q - 0.5)
    sign = 1.0 if q > 0.5 else -1.0
    if center == 0.0:
        return 0.0
    if dof == 1:
        return sign * math.cos(math.pi * tail) / math.sin(math.pi * tail)
    if dof == 2:
        return sign * center * math.sqrt(2.0 / (tail * (1.0 - tail)))
    t = NormalDist().inv_cdf(1.0 - tail)
    for _ in range(_MAX_NEWTON):
        residual, density = _t_cdf_residual(t, dof, tail, center)
        step = residual / density
        t -= step
        if abs(step) <= _NEWTON_STOP * t:
            return sign * t
    raise ArithmeticError(f"student_t_quantile: Newton did not converge (q={q}, dof={dof})")


def mean_ci95(values) -> tuple[float, float, float]:
    """Mean and two-sided 95% Student-t interval of the mean: m +- t_{0.975, n-1} s / sqrt(n).

    NaN values are ignored. With a single value the interval is (nan, nan).
    t_{q, dof} = `student_t_quantile`(q, dof).
    """
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), float("nan")
    mean = float(v.mean())
    if len(v) < 2:
        return mean, float("nan"), float("nan")
    half = student_t_quantile(0.975, len(v) - 1) * float(v.std(ddof=1)) / math.sqrt(len(v))
    return mean, mean - half, mean + half


MIN_INTERVAL_RUNS = 5
"""Fewest runs a results row gets a 95% interval from: with 2-4 runs the Student-t quantile
(12.7, 4.3, 3.2) times a standard deviation estimated from as few values gives an interval
that says little but looks precise; the mean is still reported, with its number of runs."""

DOMAINS = ("real", "nonnegative", "share")


def mean_interval(values, domain: str = "real", min_runs: int = MIN_INTERVAL_RUNS) -> tuple[float, float, float]:
    """Mean over runs and a two-sided 95% interval of it that stays inside the metric's range.

    NaN values are ignored; with fewer than `min_runs` values the interval is (nan, nan).
    With m the mean, s the standard deviation, n the runs, se = s / sqrt(n), t = t_{0.975, n-1}:
      real:         m -+ t se                                   (mean_ci95)
      nonnegative:  m exp(-+ t se / m)     (Student-t interval of ln m by the delta method,
                                            d ln m = dm / m; always > 0, wider above the mean)
      share:        expit(logit m -+ t se / (m (1 - m)))        (the same on the logit scale,
                                            d logit m = dm / (m (1 - m)); inside [0, 1])
    A mean on the boundary (m = 0; or m = 0 or 1 for a share) means every run gave that value:
    the interval is [m, m]. ValueError when a value lies outside the domain (a signed metric
    declared non-negative).
    """
    if domain not in DOMAINS:
        raise ValueError(f"mean_interval: domain must be one of {', '.join(DOMAINS)}, got {domain!r}")
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    if len(v) == 0:
        return float("nan"), float("nan"), float("nan")
    low_limit = -math.inf if domain == "real" else 0.0
    high_limit = 1.0 if domain == "share" else math.inf
    if v.min() < low_limit or v.max() > high_limit:
        raise ValueError(f"mean_interval: values outside the {domain} range [{low_limit}, {high_limit}] "
                         f"(min {v.min():g}, max {v.max():g})")
    mean = float(v.mean())
    if len(v) < max(2, min_runs):
        return mean, float("nan"), float("nan")
    t_se = student_t_quantile(0.975, len(v) - 1) * float(v.std(ddof=1)) / math.sqrt(len(v))
    if domain == "real":
        return mean, mean - t_se, mean + t_se
    if mean <= low_limit or mean >= high_limit or t_se == 0.0:
        return mean, mean, mean
    if domain == "nonnegative":
        factor = math.exp(t_se / mean)
        return mean, mean / factor, mean * factor
    centre, half = math.log(mean / (1.0 - mean)), t_se / (mean * (1.0 - mean))
    return mean, 1.0 / (1.0 + math.exp(-(centre - half))), 1.0 / (1.0 + math.exp(-(centre + half)))


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
    p75, p90, p95 = np.percentile(a, [75, 90, 95])    # one partition; each value as np.percentile(a, q)
    return {
        "rmse": float(np.sqrt(np.mean(e**2))),
        "mean": float(a.mean()),
        "median": float(np.median(a)),
        "p75": float(p75),
        "p90": float(p90),
        "p95": float(p95),
        "max": float(a.max()),
        "n": float(len(e)),
    }
