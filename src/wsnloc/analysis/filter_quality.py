"""A Bayesian filter's estimates against its bound and its own uncertainty: efficiency,
NEES / NIS per epoch, and their Monte Carlo summaries over the runs of a cell.

Per epoch of a run (`epoch_quality`):
- pcrb_m2 = trace of the PCRB position block (m^2) at the epoch (analysis.filter_bounds);
- nees = e^T P^-1 e, e the position error (m), P the filter's position covariance (m^2):
  position NEES, chi2(2) for a consistent filter;
- nis and n_meas as the filter output them (NIS of the last update, its measurement count).
Per run (`run_efficiency`): sqrt_pcrb = sqrt(mean over the run's estimates of pcrb_m2) (m), and
efficiency = RMSE / sqrt_pcrb (>= 1 when the filter's model is the data's; see docs/bounds.md).
Over the runs of a cell, epochs are matched by their index k = round(t / T) (T the epoch
period; the runs' grids have different phases): RMSE(k) = sqrt(mean_r error^2) and
sqrt(PCRB)(k) = sqrt(mean_r pcrb_m2) (the bound of the cell is the mean of the runs' bounds),
and ANEES / ANIS with their chi-square bands (metrics.consistency). ANIS needs the dof of
the NIS: n_meas in epoch updates; in sequential updates a filter's output NIS is that of
its last record group while n_meas counts the whole epoch, so ANIS is not computed there.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.analysis.filter_bounds import bound_model, filter_pcrb, filter_pcrbs
from wsnloc.estimators.epochs import sorted_codes
from wsnloc.estimators.run_data import RunData
from wsnloc.metrics.consistency import consistency_test, normalized_squared
from wsnloc.metrics.tracking import cell_rows

NEES_DOF = 2   # position NEES
QUALITY_COLUMNS = ["t", "error_m", "pcrb_m2", "nees", "nis", "n_meas"]


def epoch_quality(scored: pd.DataFrame, bound: pd.DataFrame) -> pd.DataFrame:
    """QUALITY_COLUMNS of the finite estimates of one run: scored filter output (t, x, y,
    true_x, true_y, error_m, p_xx, p_xy, p_yy, nis, n_meas) beside its bound (filter_bounds)."""
    rows = np.flatnonzero(_finite(scored))
    return pd.DataFrame(_quality(scored, rows, np.zeros(len(rows), dtype=np.intp), [bound]),
                        index=scored.index[rows])


def _finite(scored: pd.DataFrame) -> np.ndarray:
    return np.isfinite(scored["x"].to_numpy(float)) & np.isfinite(scored["y"].to_numpy(float))


def _quality(scored: pd.DataFrame, rows: np.ndarray, group: np.ndarray, bounds: list[pd.DataFrame]) -> dict:
    """QUALITY_COLUMNS (arrays) of the estimates at positions `rows` of scored, the one at
    rows[i] beside the bound bounds[group[i]] (matched on t: same epoch grid):
    pcrb_m2 = pcrb_xx + pcrb_yy (m^2), NaN off the bound's grid; nees = e^T P^-1 e."""
    column = lambda name: scored[name].to_numpy(float)[rows]        # noqa: E731
    t, trace = column("t"), np.full(len(rows), np.nan)
    for g, bound in enumerate(bounds):
        mine, bound_t = np.flatnonzero(group == g), bound["t"].to_numpy(float)
        at = np.searchsorted(bound_t, t[mine])       # the bound at the estimate's epoch end
        found = at < len(bound_t)
        found[found] = bound_t[at[found]] == t[mine][found]
        trace[mine[found]] = (bound["pcrb_xx"].to_numpy(float) + bound["pcrb_yy"].to_numpy(float))[at[found]]
    error = np.column_stack([column("x") - column("true_x"), column("y") - column("true_y")])
    covariance = np.stack([column("p_xx"), column("p_xy"), column("p_xy"), column("p_yy")], axis=-1).reshape(-1, 2, 2)
    return {"t": t, "error_m": column("error_m"), "pcrb_m2": trace, "nees": normalized_squared(error, covariance),
            "nis": column("nis"), "n_meas": column("n_meas")}


def run_efficiency(quality: pd.DataFrame) -> dict[str, float]:
    """sqrt_pcrb (m) and efficiency = RMSE / sqrt_pcrb of one run's epoch_quality rows."""
    usable = quality[np.isfinite(quality["error_m"]) & np.isfinite(quality["pcrb_m2"])]
    if usable.empty:
        return {"sqrt_pcrb": np.nan, "efficiency": np.nan}
    bound = float(np.sqrt(usable["pcrb_m2"].mean()))
    return {"sqrt_pcrb": bound, "efficiency": float(np.sqrt((usable["error_m"] ** 2).mean())) / bound}


def run_quality(data: RunData, p: dict, scored: pd.DataFrame) -> tuple[pd.DataFrame, dict[str, float]]:
    """epoch_quality of one run of a Bayesian filter (resolved registry parameters p, its
    scored output) and the run's run_efficiency."""
    quality = epoch_quality(scored, filter_pcrb(data, p))
    return quality, run_efficiency(quality)


def consistency_rows(tests: dict[str, tuple], runs: int, **keys) -> list[dict]:
    """results.csv rows of consistency(...): metric `anees` / `anis`, value the time average,
    band_low / band_high its 95% chi-square band (with the time-correlation inflation), runs
    the number of Monte Carlo runs; keys: experiment, table, row, scenario (column = the statistic)."""
    out = []
    for name, (_, test) in tests.items():
        row = results.single_row(test.time_average, column=name.lower(), metric=name.lower(), **keys)
        row.update(band_low=test.time_low, band_high=test.time_high, runs=runs)
        out.append(row)
    return out


def _epoch_index(t: pd.Series, period: float) -> np.ndarray:
    return np.round(t.to_numpy(float) / period).astype(np.int64)


def over_time(quality: pd.DataFrame, period: float) -> pd.DataFrame:
    """Per epoch index over runs (rows with a `run` column): t (mean time, s), rmse (m),
    sqrt_pcrb (m) and the number of runs, over the estimates scored against the truth."""
    quality = quality[np.isfinite(quality["error_m"])]
    frame = quality.assign(k=_epoch_index(quality["t"], period), sq=quality["error_m"] ** 2)
    grouped = frame.groupby("k", sort=True)
    return pd.DataFrame({"t": grouped["t"].mean(), "rmse": np.sqrt(grouped["sq"].mean()),
                         "sqrt_pcrb": np.sqrt(grouped["pcrb_m2"].mean()), "runs": grouped["run"].nunique()}
                        ).reset_index(drop=True)


def _runs_by_epoch(quality: pd.DataFrame, column: str, period: float) -> tuple[np.ndarray, np.ndarray]:
    """(runs, epochs) matrix of a column and the epochs' mean times: rows the runs in sorted
    order, columns the epoch indices k = round(t / period) in sorted order, entry (r, k) the
    first value that is not NaN (inf counts: a singular covariance) of run r at epoch k in
    row order (NaN where it has none)."""
    k = _epoch_index(quality["t"], period)
    runs, run_code = sorted_codes(quality["run"])
    epochs, epoch_code = np.unique(k, return_inverse=True)
    values = quality[column].to_numpy(float)
    present = np.flatnonzero(~np.isnan(values))
    cell = run_code[present] * len(epochs) + epoch_code[present]
    cells, first = np.unique(cell, return_index=True)     # first: the earliest row of each cell
    table = np.full(len(runs) * len(epochs), np.nan)
    table[cells] = values[present[first]]
    times = quality["t"].groupby(k).mean()     # index: the sorted epochs
    return table.reshape(len(runs), len(epochs)), times.to_numpy(float)


def consistency(quality: pd.DataFrame, period: float, epoch_updates: bool) -> dict[str, tuple]:
    """{'ANEES': (t, ConsistencyTest), 'ANIS': (t, ConsistencyTest)} over the runs of a cell
    (ANIS only with epoch updates, see the module docstring)."""
    out = {}
    nees, t = _runs_by_epoch(quality, "nees", period)
    if np.isfinite(nees).any():
        out["ANEES"] = (t, consistency_test(nees, NEES_DOF))
    if epoch_updates:
        with_update = quality[np.isfinite(quality["nis"]) & (quality["n_meas"] > 0)]
        if len(with_update):
            nis, t = _runs_by_epoch(with_update, "nis", period)
            dof, _ = _runs_by_epoch(with_update, "n_meas", period)
            out["ANIS"] = (t, consistency_test(nis, np.nan_to_num(dof)))
    return out


def grouped_quality(runs: list[tuple[RunData, pd.DataFrame]], keys: list[str],
                    params_of) -> list[tuple[pd.DataFrame, pd.DataFrame]]:
    """run_quality of every Bayesian filter in each run's scored estimates ((run data, scored)
    pairs), grouped by keys (e.g. a paper's table and row); params_of(*key values) gives that
    filter's resolved registry parameters. The bounds of all runs and groups are computed in
    one batch (filter_pcrbs). Per run: (quality rows with the keys, group after group in order
    of first appearance, per group sqrt_pcrb and efficiency)."""
    split = [(data, scored, *_groups(scored, keys)) for data, scored in runs]
    bounds = iter(filter_pcrbs([(data, params_of(*key)) for data, _, _, names in split for key in names]))
    return [_run_groups(scored, keys, code, names, [next(bounds) for _ in names])
            for _, scored, code, names in split]


def _groups(scored: pd.DataFrame, keys: list[str]) -> tuple[np.ndarray, list[tuple]]:
    """Group number of every row of scored (-1: a missing key) in order of first appearance,
    and each group's key values."""
    names, rows = cell_rows(scored, keys)
    code = np.full(len(scored), -1, dtype=np.intp)
    for g, members in enumerate(rows):
        code[members] = g
    return code, names


def _run_groups(scored: pd.DataFrame, keys: list[str], code: np.ndarray, names: list[tuple],
                bounds: list[pd.DataFrame]) -> tuple[pd.DataFrame, pd.DataFrame]:
    """epoch_quality of every group of one run (stacked, with the keys) and run_efficiency per group,
    as sums over each group's usable rows: sqrt_pcrb = sqrt(sum pcrb / n), RMSE = sqrt(sum e^2 / n)."""
    order = np.argsort(code, kind="stable")
    rows = order[(code[order] >= 0) & _finite(scored)[order]]
    group = code[rows]
    quality = pd.DataFrame(_quality(scored, rows, group, bounds))
    for j, name in enumerate(keys):
        quality[name] = pd.Series([key[j] for key in names]).to_numpy()[group]
    usable = np.isfinite(quality["error_m"].to_numpy()) & np.isfinite(quality["pcrb_m2"].to_numpy())
    count = np.bincount(group[usable], minlength=len(names))
    with np.errstate(invalid="ignore", divide="ignore"):
        bound = np.sqrt(np.bincount(group[usable], quality["pcrb_m2"].to_numpy()[usable], len(names)) / count)
        rmse = np.sqrt(np.bincount(group[usable], quality["error_m"].to_numpy()[usable] ** 2, len(names)) / count)
    efficiencies = [{**dict(zip(keys, key)), "sqrt_pcrb": float(b), "efficiency": float(r / b)} if n else
                    {**dict(zip(keys, key)), "sqrt_pcrb": np.nan, "efficiency": np.nan}
                    for key, n, b, r in zip(names, count, bound, rmse)]
    return quality, pd.DataFrame(efficiencies)


def cell_outputs(quality: pd.DataFrame, p: dict, label: str, title: str, **keys) -> tuple[list, tuple, list]:
    """Report outputs of one Bayesian filter cell over its runs (quality rows with `run`,
    resolved parameters p): results rows of ANEES / ANIS (consistency_rows with keys
    experiment, table, row, scenario), the panel of sqrt(PCRB) beside the RMSE (labelled
    label; bound_figures.pcrb_panels) and the ANEES / ANIS panels (consistency_panels)."""
    runs = quality["run"].nunique()
    tests = consistency(quality, p["epoch_s"], p["update"] == "epoch")
    series = over_time(quality, p["epoch_s"])
    title = f"{title}, {runs} runs"
    bound = (series["t"], {label: series["rmse"]}, series["sqrt_pcrb"], bound_model(p), title)
    return consistency_rows(tests, runs, **keys), bound, [(t, test, name, title) for name, (t, test) in tests.items()]
