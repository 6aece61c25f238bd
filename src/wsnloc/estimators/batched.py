"""Registry estimators over many cells at once: `run_many` (registry.run over the runs of a
cell) and `run_cells` / `cell_tracks` (registry.run over (run, parameter set) cells, e.g. every
run x row of a paper's table).

- The Bayesian filters (bayes.run_filter) run through bayes.run_filters: the epoch-mode cells
  that share a motion model, period, initiator and deleter go through one core.epoch_loop
  (the bare EKF as array_ekf.ArrayEKF: one predict and one update per epoch cost a few array
  operations for all cells);
- the KF over fixes (`kf_tracker`): the cells with the same KF settings go through one
  core.epoch_loop (trackers.kalman_tracks);
- other estimators run one cell at a time.
`stacked` builds one frame of several cells' tracks with their labels.
"""

from __future__ import annotations

import copy

import numpy as np
import pandas as pd

from wsnloc.estimators import bayes, registry, trackers
from wsnloc.estimators.core import COLUMNS, Track
from wsnloc.estimators.run_data import RunData

__all__ = ["Track", "cell_tracks", "run_cells", "run_many", "stacked"]


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
        return trackers.kalman_tracks([data for data, _ in cells], params)
    return [Track.of(estimator.function(data, p)) for (data, _), p in zip(cells, params)]
