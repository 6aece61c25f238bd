"""Per-scenario data summary: inventory, quarantine, Range error (overall, per anchor, against
distance, with the robust scale / per-anchor offset fit a range calibration would use), RSS
path-loss fit.

Reads the processed tables of every run of one scenario; returns a JSON-ready summary for
the report, results rows for results.csv, and the pooled samples the figures need.
"""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.campaign import Campaign
from wsnloc.io import tables
from wsnloc.metrics import ranging_validation
from wsnloc.metrics.ranging import anchor_slots, fit_path_loss, fit_range_bias, range_errors, rss_with_distance
from wsnloc.metrics.ranging_validation import DISTANCE_BINS_M
from wsnloc.metrics.stats import error_summary

EXPERIMENT = "data"


def reason_category(reason: str) -> str:
    """Group quarantine reasons: quoted values and numbers become placeholders."""
    text = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", reason)
    return re.sub(r"-?\d+(\.\d+)?(e-?\d+)?", "N", text)


VALUE_WIDTH = 24          # characters of an offending value shown in a note (longer ones end with '…')
VALUES_SHOWN = 3


def _shown(value: str) -> str:
    return repr(value if len(value) <= VALUE_WIDTH else value[:VALUE_WIDTH - 1] + "…")


def reasons_with_values(reasons: pd.Series) -> pd.Series:
    """{reason category (reason_category): text} with the offending values put back: the
    reason itself when all of its rows say the same (values cut to VALUE_WIDTH characters), else
    the most frequent reason (quoted values as '…', numbers as written) followed by its most frequent values
    ('e.g. ...', at most VALUES_SHOWN, each cut to VALUE_WIDTH characters, '+N more'), or, when
    only numbers differ, the most frequent reason as written ('and N more with other numbers')."""
    out = {}
    for category, group in reasons.groupby(reasons.map(reason_category), sort=False):
        values = pd.Series([v for reason in group for v in re.findall(r"'([^']*)'", reason)], dtype=object).value_counts()
        if group.nunique() == 1:
            out[category] = re.sub(r"'([^']*)'", lambda m: _shown(m.group(1)), group.iloc[0])
        elif len(values):
            more = f", +{len(values) - VALUES_SHOWN} more" if len(values) > VALUES_SHOWN else ""
            written = re.sub(r"'[^']*'|\"[^\"]*\"", "'…'", group.value_counts().index[0])   # its numbers kept
            out[category] = f"{written} (e.g. {', '.join(map(_shown, values.index[:VALUES_SHOWN]))}{more})"
        else:       # the numbers differ: the most frequent reason as written, not its N placeholders
            variants = group.value_counts()
            more = f" (and {len(variants) - 1} more with other numbers)" if len(variants) > 1 else ""
            out[category] = f"{variants.index[0]}{more}"
    return pd.Series(out, dtype=object)


def quarantine_by_reason(quarantine: pd.DataFrame) -> list[tuple[str, str, int]]:
    """(file, reason with its values (reasons_with_values), rows) per file and reason category."""
    rows = []
    for file, group in quarantine.groupby("file", sort=True):
        texts = reasons_with_values(group["reason"])
        counts = group["reason"].map(reason_category).value_counts()
        rows += [(file, texts[category], int(n)) for category, n in counts.items()]
    return rows


def load_runs(tables_dirs, names=tables.RAW_TABLES, imu_dirs=None, first: int | None = None
              ) -> dict[str, dict[str, pd.DataFrame]]:
    """{run: {table: DataFrame}} for every run directory under the (shard) folder(s), in run order.

    names: the tables to read (default all; an estimator without IMU input skips the large
    500 Hz table); "imu_5hz" is read from `imu_dirs` (the resample stage's folders);
    first: only the first N runs.
    """
    imu = imu_files(imu_dirs) if "imu_5hz" in names else {}
    return {run: {name: tables.read(imu[run] if name == "imu_5hz" else folder / f"{name}.parquet")
                  for name in names} for run, folder in list(run_folders(tables_dirs).items())[:first]}


def run_folders(tables_dirs) -> dict[str, Path]:
    """{run: its table folder} over the (shard) folder(s), in run order."""
    dirs = [tables_dirs] if isinstance(tables_dirs, (str, Path)) else list(tables_dirs)
    return {p.name: p for p in sorted((p for d in dirs for p in Path(d).iterdir() if p.is_dir()), key=lambda p: p.name)}


def load_inventory(tables_dirs) -> dict:
    """Raw-file inventory (checksums, lines, quarantine) of every run, merged over shards."""
    dirs = [tables_dirs] if isinstance(tables_dirs, (str, Path)) else list(tables_dirs)
    merged = {}
    for d in dirs:
        merged.update(json.loads((Path(d) / "inventory.json").read_text()))
    return dict(sorted(merged.items()))


def imu_files(imu_dirs) -> dict[str, Path]:
    """{run: resampled IMU Parquet} over the (shard) folder(s)."""
    dirs = [imu_dirs] if isinstance(imu_dirs, (str, Path)) else list(imu_dirs)
    return dict(sorted((p.stem, p) for d in dirs for p in Path(d).glob("*.parquet")))


SUMMARY_TABLES = tuple(name for name in tables.RAW_TABLES if name != "imu")   # the 500 Hz IMU is only counted


def summarize(runs: dict[str, dict[str, pd.DataFrame]], imu_5hz: dict[str, pd.DataFrame],
              campaign: Campaign, label: str, imu_rows: dict[str, int] | None = None
              ) -> tuple[dict, list[dict], dict[str, pd.DataFrame]]:
    """Summary dict, results rows and pooled samples (range errors, RSS vs distance).

    runs: {run: tables} with at least SUMMARY_TABLES; imu_rows: {run: raw IMU samples}, counted
    from the runs' "imu" tables when not given."""
    if imu_rows is None:
        imu_rows = {run: len(data["imu"]) for run, data in runs.items()}
    per_run, errors, rss_samples, quarantine = [], [], [], []
    for run, data in runs.items():
        err = range_errors(data["ranges"], data["truth"], campaign, data["anchors"]).assign(run=run)
        rss = rss_with_distance(data["rss"], data["truth"], campaign, data["anchors"]).assign(run=run)
        errors.append(err)
        rss_samples.append(rss)
        quarantine.append(data["quarantine"].assign(run=run))
        d0 = campaign.spec.get("radio", {}).get("zigbee", {}).get("d0_m", 1.0)
        fit_all = fit_path_loss(rss["rss_dbm"], rss["true_distance_m"], d0)
        los = rss[rss["los"]]
        fit_los = fit_path_loss(los["rss_dbm"], los["true_distance_m"], d0)
        truth = data["truth"]
        resampled = imu_5hz.get(run, pd.DataFrame())
        per_run.append({
            "run": run,
            "duration_s": float(truth["t"].max() - truth["t"].min()) if len(truth) else float("nan"),
            "uwb_valid": int((data["ranges"]["status"] == 0).sum()),
            "uwb_flagged": int((data["ranges"]["status"] != 0).sum()),
            "rss": len(data["rss"]),
            "imu": imu_rows[run],
            "imu_5hz": len(resampled),
            "imu_5hz_in_gap": int(resampled["in_gap"].sum()) if len(resampled) else 0,
            "truth": len(truth),
            "quarantined": len(data["quarantine"]),
            **_range_error_stats(err, "los", err["los"]),
            **_range_error_stats(err, "nlos", ~err["los"]),
            **{f"fit_all_{k}": v for k, v in fit_all.items()},
            **{f"fit_los_{k}": v for k, v in fit_los.items()},
        })
    per_run = pd.DataFrame(per_run)
    errors = pd.concat(errors, ignore_index=True) if errors else pd.DataFrame()
    rss_samples = pd.concat(rss_samples, ignore_index=True) if rss_samples else pd.DataFrame()
    quarantine = pd.concat(quarantine, ignore_index=True) if quarantine else tables.empty("quarantine")

    rows = []
    common = {"experiment": EXPERIMENT, "scenario": label}
    for link in ("los", "nlos"):
        for stat, column in (("bias", "median error"), ("p95", "p95 |error|")):
            rows.append(results.row_over_runs(per_run[f"{link}_{stat}"], table="Range error",
                                              row=link.upper(), column=column, metric="range_error_m", **common))
    for subset in ("all", "los"):
        for key in ("P0_dBm", "n", "sigma_dB"):
            rows.append(results.row_over_runs(per_run[f"fit_{subset}_{key}"], table="RSS path-loss fit",
                                              row="all links" if subset == "all" else "LOS links",
                                              column=key, metric=key, **common))
    rows.append(results.row_over_runs(per_run["quarantined"], table="Inventory", row="all files",
                                      column="quarantined lines per run", metric="lines", **common))
    if len(errors):
        rows += ranging_validation.rows(ranging_validation.link_of_walls(errors), EXPERIMENT, label)

    per_anchor = _per_anchor_counts(runs)
    by_reason = (pd.DataFrame(quarantine_by_reason(quarantine), columns=["file", "reason", "lines"])
                 .sort_values(["file", "lines"], ascending=[True, False]))
    pooled_errors = {
        link.upper(): {k.removeprefix(f"{link}_"): v for k, v in
                       _range_error_stats(errors, link, errors["los"] == (link == "los")).items()}
        for link in ("los", "nlos")
    } if len(errors) else {}
    summary = {
        "label": label,
        "runs": len(runs),
        "per_run": per_run.to_dict(orient="records"),
        "totals": per_run.drop(columns="run").sum(numeric_only=True).to_dict(),
        "per_anchor": per_anchor.to_dict(orient="records"),
        "quarantine_by_reason": by_reason.to_dict(orient="records"),
        "quarantine_examples": quarantine.head(20).to_dict(orient="records"),
        "range_error_pooled": pooled_errors,
        "range_per_anchor": per_anchor_range_quality(errors).to_dict(orient="records"),
        "range_by_distance": range_error_by_distance(errors).to_dict(orient="records"),
        "range_bias_fit": range_bias_fit(errors),
        "configured_path_loss": {k: campaign.spec.get("radio", {}).get("zigbee", {}).get(k)
                                 for k in ("p0_dbm", "path_loss_exponent", "shadowing_sigma_db",
                                           "fast_fading_sigma_db", "wall_loss_db")},
    }
    return summary, rows, {"range_errors": errors, "rss": rss_samples}


def _range_error_stats(errors: pd.DataFrame, prefix: str, mask) -> dict[str, float]:
    """Signed median (bias) and the distribution of |error| for the selected range errors."""
    selected = errors.loc[mask, "error_m"] if len(errors) else pd.Series(dtype=float)
    stats = error_summary(selected)
    stats["bias"] = float(selected.median()) if len(selected) else float("nan")
    return {f"{prefix}_{k}": v for k, v in stats.items()}


def _per_anchor_counts(runs: dict[str, dict[str, pd.DataFrame]]) -> pd.DataFrame:
    """Mean number of measurements per run for each anchor (valid and flagged ranges, RSS),
    over the runs whose anchor table lists it (0 in a run without its measurements)."""
    frames = []
    for data in runs.values():
        r, anchors = data["ranges"], data["anchors"]
        valid = (r["status"] == 0).to_numpy()
        frames.append(pd.DataFrame({
            "anchor_id": anchors["anchor_id"], "tech": anchors["tech"],
            "ranges_valid": _count_per_anchor(r["anchor_id"][valid], anchors["anchor_id"]),
            "ranges_flagged": _count_per_anchor(r["anchor_id"][~valid], anchors["anchor_id"]),
            "rss": _count_per_anchor(data["rss"]["anchor_id"], anchors["anchor_id"]),
        }))
    if not frames:
        return pd.DataFrame(columns=["anchor_id", "tech", "ranges_valid", "ranges_flagged", "rss"])
    all_runs = pd.concat(frames)
    mean = all_runs.groupby(["anchor_id", "tech"], sort=False)[["ranges_valid", "ranges_flagged", "rss"]].mean()
    return mean.round(1).reset_index()


def _count_per_anchor(anchor_of_rows: pd.Series, anchor_ids: pd.Series) -> np.ndarray:
    """Number of rows (float) of each of anchor_ids; rows of anchors not listed are not counted."""
    slot = anchor_slots(anchor_of_rows, anchor_ids)
    return np.bincount(slot[slot >= 0], minlength=len(anchor_ids)).astype(float)


def per_anchor_range_quality(errors: pd.DataFrame) -> pd.DataFrame:
    """Per anchor, pooled over runs: ranges n, bias = median signed error (m), RMSE (m), p95 |error|
    (m) and NLOS share (share of ranges whose straight link crosses a campaign wall)."""
    columns = ["anchor_id", "n", "bias_m", "rmse_m", "p95_abs_m", "nlos_share"]
    if len(errors) == 0:
        return pd.DataFrame(columns=columns)
    e = errors.assign(abs_error=errors["error_m"].abs(), sq=errors["error_m"] ** 2, nlos=~errors["los"])
    g = e.groupby("anchor_id", sort=True)
    out = pd.DataFrame({"n": g.size(), "bias_m": g["error_m"].median(), "rmse_m": g["sq"].mean() ** 0.5,
                        "p95_abs_m": g["abs_error"].quantile(0.95), "nlos_share": g["nlos"].mean()})
    return out.reset_index()[columns]


def range_error_by_distance(errors: pd.DataFrame) -> pd.DataFrame:
    """Range error against true distance (DISTANCE_BINS_M, m): n, median signed error (m), p95 |error|
    (m) and NLOS share per bin; a bias that grows with distance is a scale error."""
    columns = ["from_m", "to_m", "n", "median_m", "p95_abs_m", "nlos_share"]
    if len(errors) == 0:
        return pd.DataFrame(columns=columns)
    edges = list(DISTANCE_BINS_M)
    bins = pd.cut(errors["true_distance_m"], edges, right=False)
    e = errors.assign(abs_error=errors["error_m"].abs(), nlos=~errors["los"], bin=bins)
    g = e.groupby("bin", observed=True)
    out = pd.DataFrame({"n": g.size(), "median_m": g["error_m"].median(), "p95_abs_m": g["abs_error"].quantile(0.95),
                        "nlos_share": g["nlos"].mean()})
    out["from_m"] = [b.left for b in out.index]
    out["to_m"] = [b.right for b in out.index]
    return out.reset_index(drop=True)[columns]


def range_bias_fit(errors: pd.DataFrame) -> dict:
    """The robust fit r = s d + b_a over all runs (metrics.ranging.fit_range_bias): what
    `range_calibration: other_run` would fit; {} when there are too few ranges."""
    try:
        return fit_range_bias(errors["range_m"], errors["true_distance_m"], errors["anchor_id"]) if len(errors) else {}
    except ValueError:
        return {}
