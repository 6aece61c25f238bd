"""Synthetic runs in the canonical tables, built from a trajectory and anchors (no simulator).

Used to test estimators on geometry whose answer is known: noise-free ranges and RSS,
ranges one anchor at a time, unsorted rows, gaps.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators.run_data import RunData

SQUARE = {"A1": (0.0, 0.0), "A2": (20.0, 0.0), "A3": (20.0, 20.0), "A4": (0.0, 20.0)}
RSS_MODEL = {"p0_dbm": -40.0, "path_loss_exponent": 2.5, "sigma_db": 3.0, "d0_m": 1.0}


def walk(t: np.ndarray, speed: float = 0.5) -> np.ndarray:
    """(N, 2) a walk around the 10 m x 10 m square centred in SQUARE (m), `speed` m/s."""
    s = np.mod(speed * np.asarray(t, dtype=float), 40.0)
    side, u = np.floor_divide(s, 10.0), np.mod(s, 10.0)
    corners = np.array([[5.0, 5.0], [15.0, 5.0], [15.0, 15.0], [5.0, 15.0], [5.0, 5.0]])
    a, b = corners[side.astype(int)], corners[side.astype(int) + 1]
    return a + (b - a) * (u / 10.0)[:, None]


def tables_for(times: np.ndarray, anchor_ids: np.ndarray, positions, anchors: dict = SQUARE,
               noise_m: float = 0.0, rng=None, rss_times: np.ndarray | None = None,
               truth_step_s: float = 0.05) -> dict[str, pd.DataFrame]:
    """Canonical tables: a range from anchor_ids[i] at times[i] (noise N(0, noise_m^2)), RSS of
    every anchor at rss_times by the noise-free RSS_MODEL, truth every truth_step_s."""
    positions_at = positions if callable(positions) else (lambda t: np.repeat([positions], len(t), axis=0))
    xy = np.array([anchors[a] for a in anchor_ids]).reshape(-1, 2)
    true = np.hypot(*(positions_at(times) - xy).T)
    noise = rng.normal(0.0, noise_m, len(times)) if noise_m else 0.0
    ranges = pd.DataFrame({"t": times, "anchor_id": anchor_ids, "range_m": true + noise,
                           "status": np.zeros(len(times), dtype=np.int32), "line": np.arange(1, len(times) + 1)})
    rss_rows = []
    for t in ([] if rss_times is None else rss_times):
        p = positions_at(np.array([t]))[0]
        for k, (a, axy) in enumerate(anchors.items()):
            d = max(np.hypot(*(p - np.array(axy))), 1e-3)
            rss_rows.append((t, -1, a, RSS_MODEL["p0_dbm"] - 10 * RSS_MODEL["path_loss_exponent"] * np.log10(d), k))
    rss = pd.DataFrame(rss_rows, columns=["t", "seq", "anchor_id", "rss_dbm", "line"]).astype(
        {"t": float, "seq": np.int32, "rss_dbm": float, "line": np.int32})
    t_truth = np.arange(min(times.min(), 0.0), times.max() + truth_step_s, truth_step_s)
    p = positions_at(t_truth)
    truth = pd.DataFrame({"t": t_truth, "s": np.arange(len(t_truth)) * 0.0, "x": p[:, 0], "y": p[:, 1],
                          "line": np.arange(1, len(t_truth) + 1)})
    anchor_table = pd.DataFrame({"anchor_id": list(anchors), "tech": "uwb", "x": [v[0] for v in anchors.values()],
                                 "y": [v[1] for v in anchors.values()], "z": np.nan})
    return {"ranges": ranges, "rss": rss, "truth": truth, "anchors": anchor_table}


def bursts(duration_s: float, period_s: float = 0.5, anchors: dict = SQUARE) -> tuple[np.ndarray, np.ndarray]:
    """Every anchor ranged once per period, all at the period's end (t = k period)."""
    epochs = np.arange(1, int(duration_s / period_s) + 1) * period_s
    return np.repeat(epochs, len(anchors)), np.tile(np.array(list(anchors), dtype=object), len(epochs))


def one_at_a_time(duration_s: float, rate_hz: float, rng, anchors: dict = SQUARE,
                  gap: tuple[float, float] | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Ranges to one random anchor at a time, Poisson arrivals at rate_hz, none inside `gap`."""
    times = np.cumsum(rng.exponential(1.0 / rate_hz, int(duration_s * rate_hz * 1.5)))
    times = times[times < duration_s]
    if gap is not None:
        times = times[(times < gap[0]) | (times > gap[1])]
    return times, rng.choice(np.array(list(anchors), dtype=object), len(times))


def run_data(tables: dict, rss_model: dict | None = None, name: str = "synthetic") -> RunData:
    return RunData(tables, None, rss_model, name)


def k_smallest(ranges, k: int) -> np.ndarray:
    """Reference: indices of the k smallest finite ranges of one epoch, increasing, ties in order."""
    finite = np.flatnonzero(np.isfinite(ranges))
    return finite[np.argsort(ranges[finite], kind="stable")][:k]


def epoch_stamped_bursts(n_epochs: int, seed: int = 3) -> tuple[RunData, np.ndarray]:
    """A run whose range bursts (0.1 m noise, SQUARE) carry exactly the epoch end times of its
    0.5 s grid, and those ends (s). The grid starts at the run's first measurement, one RSS
    sample at t0 = 0.3 s, so epoch k ends at t0 - 1e-9 + 0.5 k."""
    ends = (0.3 - 1e-9) + 0.5 * np.arange(1, n_epochs + 1)
    ids = np.tile(np.array(list(SQUARE), dtype=object), len(ends))
    tables = tables_for(np.repeat(ends, len(SQUARE)), ids, walk, SQUARE, noise_m=0.1, rng=np.random.default_rng(seed))
    tables["rss"] = pd.DataFrame({"t": [0.3], "seq": [-1], "anchor_id": ["A1"], "rss_dbm": [-60.0], "line": [1]})
    return run_data(tables), ends


def tdoa_table(times: np.ndarray, positions, anchors: dict = SQUARE, reference: str | None = None,
               noise_m: float = 0.0, rng=None) -> pd.DataFrame:
    """Range differences d(anchor) - d(reference) of every other anchor at each time (one group
    per time), each anchor's arrival with its own noise N(0, noise_m^2) (so pairs sharing the
    reference are correlated, as the TDOA model assumes); `reference`: default the first anchor."""
    reference = reference or next(iter(anchors))
    others = [a for a in anchors if a != reference]
    xy = np.array([anchors[a] for a in [reference] + others])
    d = np.hypot(*(positions(times)[:, None, :] - xy[None]).transpose(2, 0, 1))      # (T, 1 + m)
    if noise_m:
        d = d + rng.normal(0.0, noise_m, d.shape)
    values = (d[:, 1:] - d[:, :1]).ravel()
    n = len(values)
    return pd.DataFrame({"t": np.repeat(times, len(others)), "anchor_id": np.tile(np.array(others, dtype=object),
                         len(times)), "ref_anchor_id": reference, "tdoa_m": values,
                         "line": np.arange(2, n + 2, dtype=np.int32)})
