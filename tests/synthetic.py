"""Synthetic runs in the canonical tables, built from a trajectory and anchors (no simulator).

Used to test estimators on geometry whose answer is known: noise-free ranges and RSS,
ranges one anchor at a time, unsorted rows, gaps.
"""

from __future__ import annotations

from pathlib import Path

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


HALL = {f"H{i + 1}": xy for i, xy in enumerate([(0.0, 0.0), (10.0, -1.0), (20.0, 0.0), (21.0, 8.0), (20.0, 16.0),
                                                 (10.0, 17.0), (0.0, 16.0), (-1.0, 8.0)])}


def lissajous(t: np.ndarray) -> np.ndarray:
    """(N, 2) a closed walk inside HALL (m): up to ~1.6 m/s, turning all the time."""
    t = np.asarray(t, dtype=float)
    return np.column_stack([10.0 + 7.0 * np.sin(t / 7.0), 8.0 + 5.0 * np.sin(2.0 * t / 7.0 + 0.5)])


def write_real_like_run(folder, seed: int, duration_s: float = 60.0, rate_hz: float = 85.0,
                        order: str = "round_robin", scale: float = 1.0, bias_sd_m: float = 0.15,
                        noise_m: float = 0.05, nlos_share: float = 0.08, nlos_mean_m: float = 0.8,
                        failed_share: float = 0.05):
    """A generic run (anchors.csv, ranges.csv, truth.csv) in `folder` of two-way ranges with the
    errors of real indoor UWB: 8 anchors around a 22 m x 18 m hall (HALL), the tag on `lissajous`,
    one anchor ranged at a time (`round_robin`: in turn at rate_hz in all with 1 ms jitter;
    `poisson`: a random anchor, Poisson arrivals at rate_hz), failed_share of exchanges lost,
    r = scale d + b_a + noise + NLOS excess: per-anchor offsets b_a ~ N(0, bias_sd_m) (antenna
    delays: 1 ns is 0.3 m), Gaussian noise, and on nlos_share of the ranges an exponential excess
    (mean nlos_mean_m; heavy-tailed, positive: a longer path). Returns the folder."""
    rng = np.random.default_rng(seed)
    ids = np.array(list(HALL), dtype=object)
    if order == "round_robin":
        t = np.arange(0.0, duration_s, 1.0 / rate_hz)
        t, a = np.sort(t + rng.normal(0.0, 0.001, len(t))), ids[np.arange(len(t)) % len(ids)]
    else:
        t = np.cumsum(rng.exponential(1.0 / rate_hz, int(duration_s * rate_hz * 1.5)))
        t = t[t < duration_s]
        a = rng.choice(ids, len(t))
    kept = rng.random(len(t)) >= failed_share
    t, a = t[kept], a[kept]
    bias = dict(zip(ids, rng.normal(0.0, bias_sd_m, len(ids))))
    d = np.hypot(*(lissajous(t) - np.array([HALL[x] for x in a])).T)
    r = scale * d + np.array([bias[x] for x in a]) + rng.normal(0.0, noise_m, len(t))
    nlos = rng.random(len(t)) < nlos_share
    r[nlos] += rng.exponential(nlos_mean_m, nlos.sum())
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    pd.DataFrame({"anchor_id": ids, "tech": "uwb", "x": [HALL[i][0] for i in ids],
                  "y": [HALL[i][1] for i in ids]}).to_csv(folder / "anchors.csv", index=False)
    pd.DataFrame({"t": t, "anchor_id": a, "range_m": r}).to_csv(folder / "ranges.csv", index=False)
    t_truth = np.arange(0.0, duration_s, 0.05)
    xy = lissajous(t_truth)
    pd.DataFrame({"t": t_truth, "x": xy[:, 0], "y": xy[:, 1]}).to_csv(folder / "truth.csv", index=False)
    return folder
