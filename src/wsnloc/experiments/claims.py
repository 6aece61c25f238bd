"""The papers' claims decided on per-run metrics, as claims.json records and results rows.

Every comparison of two cells is decided by `wsnloc.metrics.verdicts` on the per-run
values (e.g. RMSE in m) the per-scenario jobs write (`.../paper_x/metrics.csv`):
  paired    cells of the same scenario share their runs (same seeds): the mean of the
            per-run differences a_r - b_r and its 95% Student-t interval;
  unpaired  cells of different scenarios (independent seeds): Welch's interval
            (a_bar - b_bar) +- t_{0.975, nu} sqrt(s_a^2/n_a + s_b^2/n_b), with the
            Welch-Satterthwaite degrees of freedom
            nu = (s_a^2/n_a + s_b^2/n_b)^2 / ((s_a^2/n_a)^2/(n_a-1) + (s_b^2/n_b)^2/(n_b-1)).
A claim holds when every comparison holds, does not hold when one does not, and is
inconclusive otherwise (`verdicts.combine`).

In results.csv a claim is one row (table "Claims", column = the verdict, metric "verdict",
value = VERDICT_CODE: +1 holds, 0 inconclusive, -1 does not hold) and each comparison one
row (table "Claim parts", metric "difference", value = mean difference with its interval).
"""

from __future__ import annotations

import json
import weakref
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.metrics import verdicts
from wsnloc.metrics.stats import student_t_quantile
from wsnloc.metrics.verdicts import Claim, Comparison

VERDICT_CODE = {verdicts.HOLDS: 1, verdicts.INCONCLUSIVE: 0, verdicts.DOES_NOT_HOLD: -1}
CLAIMS_TABLE = "Claims"
PARTS_TABLE = "Claim parts"


def runs_of(metrics: pd.DataFrame, metric: str = "rmse", **keys) -> pd.Series:
    """Per-run values of one cell: `metric` of the rows matching every key (column == value),
    indexed by run, in the frame's row order. The rows of every cell and the columns' arrays
    are found once per frame (cell_rows, column_values): a paper's claims look up the same cells
    many times."""
    rows = cell_rows(metrics, tuple(keys)).get(tuple(keys.values()), _NO_ROWS)
    values, runs = column_values(metrics, metric, float), column_values(metrics, "run")
    return pd.Series(values[rows], index=runs[rows], name=metric)


_NO_ROWS = np.array([], dtype=np.intp)
_FRAME_MEMO: dict[int, tuple[weakref.ref, dict]] = {}   # id(frame) -> (frame, {what: derived from the frame})


def _memo(frame: pd.DataFrame) -> dict:
    """A dict of values derived from `frame`, kept while the frame lives (its entry is dropped
    when the frame is garbage-collected); the frame must not be modified after its first use."""
    key = id(frame)
    held = _FRAME_MEMO.get(key)
    if held is None or held[0]() is not frame:
        held = (weakref.ref(frame, lambda _ref, key=key: _FRAME_MEMO.pop(key, None)), {})
        _FRAME_MEMO[key] = held
    return held[1]


def column_values(frame: pd.DataFrame, name: str, dtype=None) -> np.ndarray:
    """frame[name].to_numpy(dtype), converted once per frame (_memo; string columns convert slowly)."""
    memo = _memo(frame)
    if ("column", name, dtype) not in memo:
        memo["column", name, dtype] = frame[name].to_numpy(dtype)
    return memo["column", name, dtype]


def cell_rows(frame: pd.DataFrame, columns: tuple[str, ...]) -> dict[tuple, np.ndarray]:
    """Row positions (ascending) of each cell of `frame`, by its values of `columns`: the rows
    where every column equals the value (rows with a missing value in one of them are in no
    cell, as NaN == NaN is false). Computed once per frame and columns (_memo)."""
    memo = _memo(frame)
    if ("cells", columns) not in memo:
        memo["cells", columns] = _group_rows(frame, columns)
    return memo["cells", columns]


def _group_rows(frame: pd.DataFrame, columns: tuple[str, ...]) -> dict[tuple, np.ndarray]:
    """{values of `columns`: ascending row positions} of the frame (all rows for no columns)."""
    if not columns:
        return {(): np.arange(len(frame))}
    groups = frame.groupby(list(columns), sort=False, dropna=True).indices
    return {(k if isinstance(k, tuple) else (k,)): np.asarray(v, dtype=np.intp) for k, v in groups.items()}


def paired(a: pd.Series, b: pd.Series, side: str, label: str) -> Comparison:
    """"A <side> B" on runs present in both (aligned by run name)."""
    a, b = a.align(b, join="inner")
    return verdicts.compare_paired(a.to_numpy(), b.to_numpy(), side, label)


def unpaired(a, b, side: str, label: str) -> Comparison:
    """"A <side> B" on independent samples (Welch interval, see the module docstring).

    `runs` of the result is the smaller sample size; inconclusive below 2 runs per side.
    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    a, b = a[np.isfinite(a)], b[np.isfinite(b)]
    n = min(len(a), len(b))
    if n < 2:
        mean = float(a.mean() - b.mean()) if n else float("nan")
        return Comparison(label, side, verdicts.INCONCLUSIVE, mean, float("nan"), float("nan"), n)
    va, vb = a.var(ddof=1) / len(a), b.var(ddof=1) / len(b)
    mean = float(a.mean() - b.mean())
    se = float(np.sqrt(va + vb))
    if se == 0.0:
        low = high = mean
    else:
        dof = (va + vb) ** 2 / (va ** 2 / (len(a) - 1) + vb ** 2 / (len(b) - 1))
        half = student_t_quantile(0.975, dof) * se
        low, high = mean - half, mean + half
    return Comparison(label, side, verdicts.interval_verdict(low, high, side), mean, low, high, n)


def describe(part: Comparison, unit: str = "m") -> str:
    """One comparison's deciding numbers, e.g. "hybrid - TOA: -0.031 m [-0.040, -0.022], 20 runs: holds"."""
    if not np.isfinite(part.ci95_low):
        return f"{part.label} {part.side} 0? {part.runs} run(s): {part.verdict}"
    return (f"{part.label} {part.side} 0? {part.mean_diff:+.3f} {unit} [{part.ci95_low:+.3f}, "
            f"{part.ci95_high:+.3f}], {part.runs} runs: {part.verdict}")


def record(text: str, decided: Claim, unit: str = "m", note: str = "") -> dict:
    """claims.json entry: the claim, its verdict, the deciding numbers (text and parts)."""
    evidence = "; ".join(describe(part, unit) for part in decided.parts)
    return {"claim": text, "verdict": decided.verdict, "evidence": f"{note}{evidence}",
            "parts": [part.as_dict() for part in decided.parts]}


def decided_record(text: str, holds: bool, evidence: str) -> dict:
    """claims.json entry of a claim decided without sampling error (e.g. an operation count)."""
    return {"claim": text, "verdict": verdicts.HOLDS if holds else verdicts.DOES_NOT_HOLD,
            "evidence": evidence, "parts": []}


def write_outputs(experiment: str, rows: list[dict], decided: list[dict], results_path, claims_path) -> None:
    """A paper's results.csv (its table rows, then one row per claim and per comparison:
    results_rows) and claims.json (the decided claims, as the report reads them)."""
    results.write(rows + results_rows(experiment, decided), results_path)
    Path(claims_path).write_text(json.dumps({"claims": decided}, indent=1))


def results_rows(experiment: str, records: list[dict], unit: str = "m") -> list[dict]:
    """results.csv rows of a paper's claims: one per claim, one per comparison."""
    rows = []
    for rec in records:
        parts = rec["parts"]
        rows.append({"experiment": experiment, "table": CLAIMS_TABLE, "row": rec["claim"], "column": rec["verdict"],
                     "scenario": "all", "metric": "verdict", "value": VERDICT_CODE[rec["verdict"]],
                     "ci95_low": None, "ci95_high": None,
                     "runs": min((p["runs"] for p in parts), default=None), "paper_value": None})
        for part in parts:
            rows.append({"experiment": experiment, "table": PARTS_TABLE, "row": rec["claim"], "column": part["label"],
                         "scenario": "all", "metric": f"difference_{unit} ({part['side']} 0 claimed)",
                         "value": part["mean_diff"], "ci95_low": part["ci95_low"], "ci95_high": part["ci95_high"],
                         "runs": part["runs"], "paper_value": None})
    return rows
