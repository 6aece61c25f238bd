"""Reference results on real data, scored exactly as our estimators are (metrics.tracking:
2-D error with the truth interpolated at the estimate times, RMSE over the estimates inside
the truth span), to stand beside ours in the real-data study and benchmarks/realdata.py.

- published tracks: a dataset's own baseline tracks as `wsnloc convert` stores them beside a
  run (`published_<name>.csv`: t (s), x, y (m); cucudasluv's LS.csv per-epoch least squares and
  ESKF.csv IMU-aided filter), and the values the dataset itself publishes
  (`published_values.csv`: name, value; cucudasluv's RMSD_results.txt) as reference columns.
- `path_loss_ekf`: a plain gated EKF on RSS, written here independently of the registry's
  filters: state [x, y, vx, vy], white-acceleration PV model, one scalar update per RSS sample
  at its own time with h(p) = P0 - 10 n log10(d / d0), d the 3-D distance to the receiver, the
  log-distance model (P0, n, sigma) fitted on a donor track with truth (experiments.calibration),
  and a chi-square gate (1 dof) at 0.999.
- `weighted_centroid`: per 1 s bin, the mean RSS of each receiver; the 3 strongest receivers'
  positions averaged with weights w = 10^(RSS / 20), i.e. w proportional to 1 / d for free-space
  path loss (n = 2): Blumenthal et al.'s weighted centroid with degree 1.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.campaign import Campaign
from wsnloc.experiments.calibration import calibrate
from wsnloc.metrics.tracking import run_metrics, score

PUBLISHED_PREFIX = "published_"
PUBLISHED_VALUES = "published_values.csv"
EKF_ACCEL_SIGMA_MPS2 = 0.5     # walking pace changes (a person carrying the beacon)
EKF_GATE_CHI2 = 10.83          # chi-square (1 dof) 0.999 quantile
EKF_OUTPUT_S = 0.5             # output period (s), the registry's epoch_s default
CENTROID_BIN_S = 1.0
CENTROID_STRONGEST = 3


def rmse_of(track: pd.DataFrame, truth: pd.DataFrame) -> float:
    """RMSE (m) of a track (t, x, y) against the truth, scored as every estimator is."""
    return float(run_metrics(score(track, truth), truth)["rmse"])


def published_tracks(run_dir: str | Path) -> dict[str, pd.DataFrame]:
    """{name: track (t, x, y)} of the dataset's own baselines stored beside a converted run."""
    return {path.stem[len(PUBLISHED_PREFIX):]: pd.read_csv(path)
            for path in sorted(Path(run_dir).glob(f"{PUBLISHED_PREFIX}*.csv")) if path.name != PUBLISHED_VALUES}


def published_values(run_dir: str | Path) -> dict[str, float]:
    """{name: value} the dataset publishes for the run (reference column only), {} without."""
    path = Path(run_dir) / PUBLISHED_VALUES
    if not path.is_file():
        return {}
    values = pd.read_csv(path)
    return dict(zip(values["name"], values["value"].astype(float)))


def _distances(points: np.ndarray, anchors: np.ndarray, dz: np.ndarray) -> np.ndarray:
    return np.sqrt(((points[:, None, :] - anchors[None, :, :2]) ** 2).sum(-1) + dz[None, :] ** 2)


def weighted_centroid(rss: pd.DataFrame, anchors: pd.DataFrame) -> pd.DataFrame:
    """Weighted centroid of the 3 strongest receivers per 1 s bin (module docstring); t = bin centre."""
    xy = anchors.set_index("anchor_id")[["x", "y"]]
    rss = rss[rss["anchor_id"].isin(xy.index)]
    start = rss["t"].min()
    bins = np.floor((rss["t"] - start) / CENTROID_BIN_S).astype(int)
    means = rss.assign(bin=bins).groupby(["bin", "anchor_id"])["rss_dbm"].mean().reset_index()
    rows = []
    for b, group in means.groupby("bin"):
        top = group.nlargest(CENTROID_STRONGEST, "rss_dbm")
        w = 10.0 ** (top["rss_dbm"].to_numpy() / 20.0)
        p = (xy.loc[top["anchor_id"]].to_numpy() * w[:, None]).sum(0) / w.sum()
        rows.append((start + (b + 0.5) * CENTROID_BIN_S, p[0], p[1]))
    return pd.DataFrame(rows, columns=["t", "x", "y"])


def fit_donor_model(donor_rss: pd.DataFrame, donor_truth: pd.DataFrame, anchors: pd.DataFrame,
                    campaign: Campaign, d0_m: float = 1.0) -> dict:
    """P0 (dBm), n, sigma (dB) of the log-distance model on a donor track with truth."""
    return calibrate(donor_rss, donor_truth, campaign, d0_m, anchors)


def path_loss_ekf(rss: pd.DataFrame, anchors: pd.DataFrame, model: dict, tag_height_m: float | None) -> pd.DataFrame:
    """The plain gated EKF on RSS (module docstring); outputs every EKF_OUTPUT_S s, predicted to
    the output time; starts at the weighted centroid of the first second, sigma 5 m, at rest
    (speed sigma 1 m/s)."""
    table = anchors.set_index("anchor_id")
    rss = rss[rss["anchor_id"].isin(table.index)].sort_values("t", kind="stable")
    positions = table[["x", "y"]].to_numpy(float)
    z = table["z"].to_numpy(float) if "z" in table else np.full(len(table), np.nan)
    dz = np.where(np.isfinite(z), z - (tag_height_m or 0.0), 0.0)
    slot = pd.Index(table.index).get_indexer(rss["anchor_id"])
    p0, n, sigma, d0 = model["p0_dbm"], model["path_loss_exponent"], model["sigma_db"], model.get("d0_m", 1.0)
    first = weighted_centroid(rss[rss["t"] < rss["t"].iloc[0] + CENTROID_BIN_S], anchors)
    x = np.array([first["x"].iloc[0], first["y"].iloc[0], 0.0, 0.0])
    P = np.diag([25.0, 25.0, 1.0, 1.0])
    q = EKF_ACCEL_SIGMA_MPS2 ** 2

    def predict(x, P, dt):
        F = np.eye(4)
        F[0, 2] = F[1, 3] = dt
        Q = q * np.array([[dt ** 3 / 3, 0, dt ** 2 / 2, 0], [0, dt ** 3 / 3, 0, dt ** 2 / 2],
                          [dt ** 2 / 2, 0, dt, 0], [0, dt ** 2 / 2, 0, dt]])
        return F @ x, F @ P @ F.T + Q

    t_now = rss["t"].iloc[0]
    times = rss["t"].to_numpy(float)
    values = rss["rss_dbm"].to_numpy(float)
    outputs = np.arange(t_now + EKF_OUTPUT_S, times[-1] + 1e-9, EKF_OUTPUT_S)
    rows, k = [], 0
    for t_out in outputs:
        while k < len(times) and times[k] <= t_out:
            x, P = predict(x, P, times[k] - t_now)
            t_now = times[k]
            a = slot[k]
            dxy = x[:2] - positions[a]
            d = max(np.sqrt(dxy @ dxy + dz[a] ** 2), 0.1)
            h = p0 - 10.0 * n * np.log10(d / d0)
            H = np.zeros(4)
            H[:2] = -10.0 * n / np.log(10.0) * dxy / d ** 2
            S = H @ P @ H + sigma ** 2
            y = values[k] - h
            if y * y / S <= EKF_GATE_CHI2:
                K = P @ H / S
                x = x + K * y
                P = (np.eye(4) - np.outer(K, H)) @ P
            k += 1
        xo, _ = predict(x, P, t_out - t_now)
        rows.append((t_out, xo[0], xo[1]))
    return pd.DataFrame(rows, columns=["t", "x", "y"])
