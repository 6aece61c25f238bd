"""Registry estimators over many cells at once: `run_many` (registry.run over the runs of a
cell) and `run_cells` / `cell_tracks` (registry.run over (run, parameter set) cells, e.g. every
run x row of a paper's table).

- The Bayesian filters (bayes.run_filter) run through bayes.run_filters: the epoch-mode cells
  that share a motion model, period, initiator and deleter go through one core.epoch_loop
  (the bare EKF as array_ekf.ArrayEKF: one predict and one update per epoch cost a few array
  operations for all cells);
- the KF over fixes (`kf_tracker`) of cells with the same KF matrices is stepped together
  (kalman_tracks);
- other estimators run one cell at a time.
`stacked` builds one frame of several cells' tracks with their labels.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from wsnloc.estimators import bayes, fixes, registry, trackers
from wsnloc.estimators.array_ekf import joseph_update, predict
from wsnloc.estimators.core import COLUMNS, Track
from wsnloc.estimators.run_data import RunData

__all__ = ["Track", "cell_tracks", "kalman_tracks", "run_cells", "run_many", "stacked"]


def stacked(tracks: list[Track], labels: dict[str, list[str]], columns=tuple(COLUMNS)) -> pd.DataFrame:
    """The tracks one after the other, their `columns` (of COLUMNS, floats; a 3-D track's height
    is not among them) then each
    label column (labels[name][c] on the rows of track c, strings): pd.concat of the tracks'
    finished frames, each with its labels assigned, built at once from the arrays. attrs:
    the tracks' attrs when they all agree (as pd.concat)."""
    rows = np.concatenate([track.rows[:, :len(COLUMNS)] for track in tracks])     # 3-D tracks: z, p_zz left out
    track = np.repeat(np.arange(len(tracks)), [len(t.rows) for t in tracks])
    frame = pd.DataFrame({**{name: rows[:, COLUMNS.index(name)] for name in columns},
                          **{name: pd.array(values, dtype="str")[track] for name, values in labels.items()}})
    if all(t.attrs and t.attrs == tracks[0].attrs for t in tracks):
        frame.attrs = copy.deepcopy(tracks[0].attrs)
    return frame


def run_many(name: str, datas: list[RunData], overrides: dict | None = None, where: str = "") -> list[pd.DataFrame]:
    """registry.run(name, data, overrides, where) for every run of `datas` (run_cells)."""
    return run_cells(name, [(data, overrides or {}) for data in datas], where)


def run_cells(name: str, cells: list[tuple[RunData, dict]], where: str = "") -> list[pd.DataFrame]:
    """[registry.run(name, data, overrides, where) for data, overrides in cells] (e.g. every run
    x row of a paper's table), the filters and the KF over fixes stepped together (module
    docstring)."""
    estimator = registry.get(name)
    if estimator.function is bayes.run_filter or name == "kf_tracker":
        return [track.finished() for track in cell_tracks(name, cells, where)]
    return [registry.run(name, data, overrides, where) for data, overrides in cells]


def cell_tracks(name: str, cells: list[tuple[RunData, dict]], where: str = "") -> list[Track]:
    """run_cells(name, cells, where) as Tracks (the COLUMNS arrays and attrs of each cell),
    stepped together as there; the filters build no frame at all."""
    estimator = registry.get(name)
    params = [estimator.resolve(overrides, where) for _, overrides in cells]
    if estimator.function is bayes.run_filter:
        fitted = [bayes.self_fitted(p) for p in params]       # several passes each (estimators.self_fit)
        plain = [i for i, f in enumerate(fitted) if not f]
        tracks = dict(zip(plain, bayes.run_filters([(cells[i][0], params[i]) for i in plain])))
        return [tracks[i] if i in tracks else Track.of(bayes.run_filter(cells[i][0], params[i]))
                for i in range(len(cells))]
    if name == "kf_tracker":
        return [Track.of(frame) for frame in _kalman_cells([data for data, _ in cells], params)]
    return [Track.of(estimator.function(data, p)) for (data, _), p in zip(cells, params)]


def kalman_tracks(fix_tables: list[pd.DataFrame], matrices: tuple) -> list[pd.DataFrame]:
    """trackers.kalman_track(fixes, matrices) for every table of per-epoch fixes (t, x, y;
    NaN without a fix), stepped together: a run starts at its first fix, predicts at every
    later epoch of its grid and is updated with each fix (z = H x + v); output at its fixes."""
    F, Q, H, R, P0 = matrices
    n_runs, n_epochs = len(fix_tables), max([len(f) for f in fix_tables] + [0])
    t, z = np.full((n_runs, n_epochs), np.nan), np.full((n_runs, n_epochs, 2), np.nan)
    for i, f in enumerate(fix_tables):
        t[i, :len(f)], z[i, :len(f)] = f["t"].to_numpy(float), f[["x", "y"]].to_numpy(float)
    live, has_fix = np.arange(n_epochs)[None, :] < np.array([len(f) for f in fix_tables])[:, None], \
        np.isfinite(z).all(axis=2)
    x, P, started = np.zeros((n_runs, 4)), np.zeros((n_runs, 4, 4)), np.zeros(n_runs, bool)
    out = np.full((n_runs, n_epochs, 6), np.nan)
    for k in range(n_epochs):
        rolling = np.flatnonzero(started & live[:, k])
        x[rolling], P[rolling] = predict(x[rolling], P[rolling], F, Q)
        first = has_fix[:, k] & ~started
        x[first], P[first], started[first] = np.column_stack([z[first, k], np.zeros((first.sum(), 2))]), P0, True
        rows = np.flatnonzero(has_fix[:, k] & ~first)
        if len(rows):
            x[rows], P[rows], _ = joseph_update(x[rows], P[rows], z[rows, k] - x[rows] @ H.T, H[None], R[None])
        out[:, k] = np.column_stack([t[:, k], x[:, 0], x[:, 1], P[:, 0, 0], P[:, 0, 1], P[:, 1, 1]])
    return [pd.DataFrame(out[i, has_fix[i]], columns=["t", "x", "y", "p_xx", "p_xy", "p_yy"]) for i in range(n_runs)]


def _kalman_cells(datas: list[RunData], params: list[dict]) -> list[pd.DataFrame]:
    """kf_tracker of every (run, resolved parameters) cell: cells with the same KF matrices are
    stepped together (kalman_tracks)."""
    groups: dict[tuple, list[int]] = {}
    for i, p in enumerate(params):
        key = (p["epoch_s"], p["accel_sigma_mps2"], p["position_sigma_m"], p["initial_speed_sigma_mps"])
        groups.setdefault(key, []).append(i)
    frames: list[pd.DataFrame] = [pd.DataFrame()] * len(params)
    for key, members in groups.items():
        tracks = kalman_tracks([fixes.epoch_fixes(datas[i], params[i], params[i]["fixes"]) for i in members],
                               trackers.kalman_matrices(*key))
        for i, track in zip(members, tracks):
            frames[i] = track
    return frames
