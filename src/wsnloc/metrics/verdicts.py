"""Three-valued verdicts on a paper's claims, decided from paired Monte Carlo runs.

A comparison "A < B" (e.g. A has lower RMSE than B) is decided from the paired
differences d_r = a_r - b_r of runs sharing a seed r, through the mean difference and
its two-sided 95% Student-t interval  d_bar +- t_{0.975, n-1} s_d / sqrt(n)
(`wsnloc.metrics.stats.mean_ci95`):
  holds          the interval lies entirely on the claimed side of 0,
  does not hold  the interval lies entirely on the other side,
  inconclusive   the interval contains 0, or fewer than 2 paired runs.
A claim made of several comparisons ("in every cell", "A < B < C") holds only if every
part holds, does not hold if any part does not hold, and is inconclusive otherwise.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from wsnloc.metrics.stats import mean_ci95

HOLDS = "holds"
DOES_NOT_HOLD = "does not hold"
INCONCLUSIVE = "inconclusive"
VERDICTS = (HOLDS, DOES_NOT_HOLD, INCONCLUSIVE)
SIDES = {"<": -1, ">": +1}


@dataclass(frozen=True)
class Comparison:
    """Verdict on "A <side> B" from paired differences, with its deciding numbers.

    mean_diff, ci95_low, ci95_high: mean of a_r - b_r and its 95% interval (units of the
    metric, e.g. m); runs: number of paired runs with both values finite.
    """

    label: str
    side: str
    verdict: str
    mean_diff: float
    ci95_low: float
    ci95_high: float
    runs: int

    def text(self) -> str:
        """The deciding numbers, e.g. "A - B = -0.12 m [-0.20, -0.04], 20 paired runs: holds"."""
        if self.runs < 2:
            return f"{self.label}: {self.runs} paired run(s), {self.verdict}"
        return (f"{self.label}: mean difference {self.mean_diff:+.3g} "
                f"[{self.ci95_low:+.3g}, {self.ci95_high:+.3g}] (95%), "
                f"{self.runs} paired runs: {self.verdict}")

    def as_dict(self) -> dict:
        return {"label": self.label, "side": self.side, "verdict": self.verdict,
                "mean_diff": self.mean_diff, "ci95_low": self.ci95_low,
                "ci95_high": self.ci95_high, "runs": self.runs}


@dataclass(frozen=True)
class Claim:
    """Verdict on a claim made of one or more comparisons, and the comparisons themselves."""

    verdict: str
    parts: tuple[Comparison, ...] = field(default_factory=tuple)

    def text(self) -> str:
        return "; ".join(part.text() for part in self.parts) + f" => {self.verdict}"

    def as_dict(self) -> dict:
        return {"verdict": self.verdict, "parts": [part.as_dict() for part in self.parts]}


def compare_paired(a, b, side: str = "<", label: str = "A - B") -> Comparison:
    """Decide "A <side> B" (side "<" or ">") from per-run values a[r], b[r] of the same seeds.

    Runs where either value is not finite are dropped from both.
    """
    if side not in SIDES:
        raise ValueError(f"comparison side must be one of {sorted(SIDES)}, got {side!r}")
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    if a.shape != b.shape:
        raise ValueError(f"{label}: paired runs need equal lengths, got {a.shape} and {b.shape}")
    diff = a - b
    diff = diff[np.isfinite(diff)]
    mean, low, high = mean_ci95(diff)
    return Comparison(label, side, interval_verdict(low, high, side), mean, low, high, len(diff))


def interval_verdict(low: float, high: float, side: str) -> str:
    """Verdict of a 95% interval [low, high] of A - B on the claim "A <side> B"."""
    if not (np.isfinite(low) and np.isfinite(high)):
        return INCONCLUSIVE
    sign = SIDES[side]
    if sign * low > 0 and sign * high > 0:
        return HOLDS
    if sign * low < 0 and sign * high < 0:
        return DOES_NOT_HOLD
    return INCONCLUSIVE


def combine(verdicts) -> str:
    """All parts hold -> holds; any part does not hold -> does not hold; else inconclusive."""
    verdicts = list(verdicts)
    unknown = set(verdicts) - set(VERDICTS)
    if unknown:
        raise ValueError(f"unknown verdict(s) {sorted(unknown)}; expected {VERDICTS}")
    if not verdicts:
        return INCONCLUSIVE
    if DOES_NOT_HOLD in verdicts:
        return DOES_NOT_HOLD
    if all(v == HOLDS for v in verdicts):
        return HOLDS
    return INCONCLUSIVE


def claim(comparisons) -> Claim:
    """A claim made of several comparisons (e.g. one per cell), combined with `combine`."""
    parts = tuple(comparisons)
    return Claim(combine(part.verdict for part in parts), parts)


def ordering(runs_by_name: dict, order) -> Claim:
    """Claim "order[0] < order[1] < ..." on per-run values runs_by_name[name] (same seeds).

    Decided as the chain of adjacent paired comparisons.
    """
    order = list(order)
    if len(order) < 2:
        raise ValueError(f"an ordering needs at least two names, got {order}")
    missing = [name for name in order if name not in runs_by_name]
    if missing:
        raise KeyError(f"no runs for {missing}; available: {sorted(runs_by_name)}")
    return claim(compare_paired(runs_by_name[lo], runs_by_name[hi], "<", f"{lo} - {hi}")
                 for lo, hi in zip(order, order[1:]))


def paper_value_inside(paper_value, low: float, high: float) -> bool:
    """True when the paper's value lies within our 95% interval [low, high] (bounds included).

    False when either the paper value or the interval is missing (no basis to call it a match).
    """
    try:
        value = float(paper_value)
    except (TypeError, ValueError):
        return False
    if not all(np.isfinite(x) for x in (value, low, high)):
        return False
    return low <= value <= high
