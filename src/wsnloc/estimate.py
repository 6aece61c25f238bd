"""One estimator on one raw run, without Snakemake (`wsnloc estimate`).

raw run -> canonical tables (OUT/tables, with quarantine) -> 5 Hz IMU when the estimator
reads it -> estimates (OUT/estimates.parquet) -> metrics against the run's truth
(OUT/metrics.json: rmse_m, mean_m, median_m, p75_m, p90_m, p95_m, max_m, n, availability, and rmse_3d_m
with a 3-D state and truth with z; the gated share
and the range calibration applied, with its fitted values; see studies.calibration_metrics; the
diagnosis values diag_*, see wsnloc.diagnosis; the self-fit's values and verdicts self_fit_*, see
estimators.self_fit; without truth only the estimator, the diagnosis and the self-fit).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.campaign import Campaign, generic_site
from wsnloc.errors import WsnlocError
from wsnloc.diagnosis import diagnose_run, metrics_of as diagnosis_metrics, report as diagnosis_report
from wsnloc.estimators import registry
from wsnloc.estimators.auto import CHOICE_KEYS, dimensions_for, measurements_for, motion_for
from wsnloc.estimators.run_data import RunData, preliminary_filter_reasons
from wsnloc.experiments.calibration import calibrate_ranges, calibrate_tdoa, donor_model_for
from wsnloc.io import tables
from wsnloc.io.convert import QUARANTINE_FILE
from wsnloc.io.ingest import file_notes, ingest_one
from wsnloc.io.limits import QuarantineLimits, check_quarantine_limits
from wsnloc.metrics.tracking import run_metrics, score
from wsnloc.signal.resample import resample_imu
from wsnloc.studies import calibration_metrics, diagnose, reads_rss

RESAMPLE = {"rate_hz": 5.0, "grid_rate_hz": 500.0, "max_gap_s": 0.1, "kaiser_beta": 8.0}   # config/schema.yaml defaults
METRIC_KEYS = {"rmse": "rmse_m", "mean": "mean_m", "median": "median_m", "p75": "p75_m", "p90": "p90_m",
               "p95": "p95_m", "max": "max_m", "n": "n", "availability": "availability", "rmse_3d": "rmse_3d_m"}


def load_run(fmt: str, run_dir: Path, campaign: Campaign | None, out_dir: Path,
             limits: QuarantineLimits = QuarantineLimits()) -> tuple[dict[str, pd.DataFrame], list[str]]:
    """Ingest a raw run into out_dir (Parquet + quarantine), stop above the quarantine limits:
    (the tables, the quarantine table under the key 'quarantine'; the files' inventory notes,
    e.g. 'ranges.csv: 12 row(s) out of time order (sorted)', as `wsnloc ingest` prints them)."""
    inventory = ingest_one(fmt, run_dir, campaign, out_dir)
    quarantine = tables.read(out_dir / "quarantine.parquet")
    check_quarantine_limits(run_dir, inventory, quarantine, limits, out_dir / "quarantine.parquet")
    loaded = {name: tables.read(out_dir / f"{name}.parquet") for name in tables.RAW_TABLES}
    loaded["quarantine"] = quarantine
    notes = {name: file_notes(info) for name, info in inventory.items()}
    return loaded, [f"{name}: {text}" for name, text in notes.items() if text]


def quarantine_summary(quarantine: pd.DataFrame, where: Path) -> str | None:
    """'N row(s) quarantined (count reason per file ...); table: where', or None when none was."""
    if not len(quarantine):
        return None
    from wsnloc.metrics.data_quality import quarantine_by_reason

    listed = "; ".join(f"{count} {file}: {reason}" for file, reason, count in quarantine_by_reason(quarantine))
    return f"{len(quarantine)} row(s) quarantined ({listed}); table: {where}"


def converted_quarantine(run_dir: Path) -> str | None:
    """The source lines `wsnloc convert` could not convert for this run (io.convert), or None."""
    path = run_dir / QUARANTINE_FILE
    if not path.is_file():
        return None
    rows = pd.read_csv(path)
    if not len(rows):
        return None
    from wsnloc.metrics.data_quality import quarantine_by_reason

    listed = "; ".join(f"{count} {file}: {reason}" for file, reason, count in quarantine_by_reason(rows))
    return (f"{len(rows)} source line(s) were not converted ({listed}); "
            f"table: {path}")


def donor_models(fmt: str, donor_dir: Path, campaign: Campaign | None, out_dir: Path, name: str, p: dict,
                 reads_rss: bool, limits: QuarantineLimits = QuarantineLimits()) -> tuple[dict | None, dict | None]:
    """(RSS model, range calibration) fitted on a donor run with truth (same site): the RSS
    model when the estimator reads RSS (experiments.calibration.donor_model_for: by default
    per-receiver P0s, sigma, and the exponent, the donor's or the configured one, whichever
    makes estimator `name` track the donor better); the range scale and per-anchor offsets
    when it asks for `range_calibration=other_run` (fitted on the donor's ranges, or on its
    range differences when it has none: offsets relative to its main reference anchor)."""
    wants_ranges = p.get("range_calibration") == "other_run"
    if not (reads_rss or wants_ranges):
        raise WsnlocError(f"--calibration {donor_dir}: {name} calibrates nothing on a donor (it reads no RSS, and "
                          + ("has no range calibration: the Bayesian filters and smoothers have one, see "
                             "`wsnloc estimators`)" if "range_calibration" not in p
                             else f"range_calibration is {p['range_calibration']!r}; other_run reads the donor)"))
    donor, _ = load_run(fmt, donor_dir, campaign, out_dir, limits)
    if len(donor["truth"]) == 0:
        raise WsnlocError(f"{donor_dir}: a calibration donor needs truth")
    for table, wanted in (("rss", reads_rss), ("ranges", wants_ranges and not len(donor["tdoa"]))):
        if wanted and len(donor[table]) == 0:
            raise WsnlocError(f"{donor_dir}: a calibration donor needs the {table} it calibrates, and has none")
    site = campaign or generic_site()
    source = f"fitted on {donor_dir}"
    rss = dict(donor_model_for(p, donor["rss"], donor["truth"], site,
                               lambda model: registry.run(name, RunData(donor, campaign, model, str(donor_dir)), p),
                               donor["anchors"]), source=source) if reads_rss else None
    fit_ranges = calibrate_ranges if len(donor["ranges"]) else calibrate_tdoa
    ranges = dict(fit_ranges(donor["ranges" if len(donor["ranges"]) else "tdoa"], donor["truth"], site,
                             donor["anchors"]), source=source) if wants_ranges else None
    return rss, ranges


def unused_tdoa_notes(data: RunData, p: dict, explicit: set[str], choices: dict) -> list[str]:
    """A note per measurement key left on the ranges of a run that also has range differences
    (tdoa.csv) the estimator could read: ranges stay the default there (a two-way range fixes
    one distance; a range difference is the difference of two, each with its own noise, and
    N anchors give N ranges but N - 1 independent differences), and the note says how to pick them."""
    if not len(data.usable_tdoa()):
        return []
    return [f"the run has range differences (tdoa.csv), not used: {k}={p[k]} reads the two-way ranges, which "
            f"carry more information; --set {k}=tdoa reads the range differences instead"
            for k in CHOICE_KEYS if p.get(k) == "toa" and k not in explicit and "tdoa" in (choices.get(k) or ())]


def filtered_ranges_note(data: RunData, p: dict) -> str | None:
    """How many of the run's ranges to known anchors the preliminary filter leaves out
    (run_data.preliminary_filter: a device status other than 0, not positive, longer than
    max_range_m), by reason; None when none is or the estimator reads no ranges."""
    if not p.get("preliminary_filter") or p.get("measurements", "toa") in ("rss", "tdoa") or p.get("fixes") == "rss":
        return None
    ranges = data.usable_ranges(False, np.inf)          # finite, to a known anchor
    counts = {reason: int(rows.sum()) for reason, rows in preliminary_filter_reasons(ranges, p["max_range_m"]).items()
              if rows.any()}
    if not counts:
        return None
    detail = {"longer than max_range_m": f" ({p['max_range_m']:g} m; raise it to keep them)"}
    return (f"the preliminary filter left out {sum(counts.values())} of {len(ranges)} ranges: "
            + ", ".join(f"{n} {reason}{detail.get(reason, '')}" for reason, n in counts.items()))


def estimate_run(fmt: str, run_dir: Path, campaign: Campaign | None, out: Path, name: str, overrides: dict,
                 calibration_dir: Path | None = None, limits: QuarantineLimits = QuarantineLimits()) -> dict:
    """Run `name` on the raw run; writes estimates.parquet (and metrics.json with truth); returns the
    metrics, with 'n_estimates', 'notes' (quarantine, choices made from the data) and 'diagnosis'
    (the text of diagnosis.report). A donor (`calibration_dir`) alone turns on the range
    calibration from it (range_calibration=other_run) on a run with ranges unless overrides set
    range_calibration, and the RSS model when the estimator reads RSS;
    measurements / fixes, motion and dimensions not in overrides follow the data and the set-up
    (estimators.auto: measurements_for, motion_for, dimensions_for).
    The run and the donor stop above the quarantine `limits` (IngestError)."""
    estimator = registry.get(name, "--estimator")
    p = estimator.resolve(overrides, "--set")
    run_tables, inventory_notes = load_run(fmt, run_dir, campaign, out / "tables", limits)
    notes = [q for q in [quarantine_summary(run_tables.pop("quarantine"), out / "tables" / "quarantine.parquet"),
                         converted_quarantine(run_dir)] if q] + inventory_notes
    if "imu_5hz" in estimator.tables(p):
        run_tables["imu_5hz"] = resample_imu(run_tables["imu"], **RESAMPLE)
    measured = RunData(run_tables, campaign, None, str(run_dir))      # what the run holds (no calibration yet)
    choices = {param.name: param.choices for param in estimator.params}
    chosen = measurements_for(measured, p, set(overrides), choices)
    notes += [f"{k}={v}: the run has {'range differences' if v == 'tdoa' else 'RSS'} and no usable range"
              for k, v in chosen.items() if p[k] != v]
    notes += unused_tdoa_notes(measured, chosen, set(overrides), choices)
    p, chosen = chosen, motion_for(run_tables, chosen, set(overrides))
    notes += [f"{k}={v}: the run has odometry" for k, v in chosen.items() if p[k] != v]
    p, chosen = chosen, dimensions_for(campaign, chosen, set(overrides))
    notes += [f"{k}={v}: the campaign's path varies the tag height" for k, v in chosen.items() if p[k] != v]
    p = chosen
    if reads_rss(name, p) and p.get("measurements") != "rss" and p.get("fixes") != "rss" \
            and not len(measured.usable_rss()) and len(run_tables["ranges"]):
        mixes = name in ("pmix", "fmix") or p.get("fixes") in ("pmix", "fmix")
        notes.append(f"the run has no RSS: {name} reads the ranges alone"
                     + (" (no RSS fix to mix in: the range fixes)" if mixes else ""))
    if calibration_dir is not None and "range_calibration" in p and "range_calibration" not in overrides \
            and (len(run_tables["ranges"]) or len(run_tables["tdoa"])) and p.get("measurements", "toa") != "rss":
        p = dict(p, range_calibration="other_run")       # the donor calibrates the ranges (or differences) too
    rss_model, range_model = donor_models(fmt, calibration_dir, campaign, out / "calibration", name, p,
                                          reads_rss(name, p) and p.get("rss_calibration") != "configured", limits) \
        if calibration_dir else (None, None)
    if rss_model and "exponent_choice" in rss_model:
        notes.append(f"RSS model from the donor: per-receiver P0 offsets, exponent {rss_model['exponent_choice']}")
    data = RunData(run_tables, campaign, rss_model, str(run_dir), range_model)
    if data.three_d and (campaign is None or campaign.tag_height_m is None) and p.get("dimensions", 2) == 2:
        notes.append("anchors have heights (z) but the run gives no tag height: the tag is taken at z = 0 m "
                     "(give tag_height_m in the run's meta.yaml, or --set dimensions=3)")
    notes += [note for note in [filtered_ranges_note(data, p)] if note]
    estimates = registry.run(name, data, p)
    if not np.isfinite(estimates["x"]).any():
        raise WsnlocError(f"{name} on {run_dir}: no estimates; {diagnose(data, p)}")
    diagnosis = diagnose_run(data, estimates, p)
    truth = run_tables["truth"]
    scored = score(estimates, truth).assign(run=run_dir.name, subset=p.get("anchors", "all"))
    tables.write("estimates", scored, out / "estimates.parquet")
    metrics = {"n_estimates": int(np.isfinite(estimates["x"]).sum()), "notes": notes,
               "diagnosis": diagnosis_report(diagnosis, p)}
    summary = {"estimator": name, **{k: v for k, v in diagnosis_metrics(diagnosis).items()
                                     if isinstance(v, str) or np.isfinite(v)},
               **{k: v for k, v in estimates.attrs.items() if k.startswith("self_fit_")}}
    if len(truth):
        values = run_metrics(scored, truth)
        summary.update({METRIC_KEYS[k]: float(v) for k, v in values.items()})
        summary.update(resets=int(estimates.attrs.get("resets", 0)),
                       rss_model=(rss_model or {}).get("source", "configured"),
                       **({"rss_exponent_choice": rss_model["exponent_source"],
                           "rss_path_loss_exponent": rss_model["path_loss_exponent"]}
                          if rss_model and "exponent_choice" in rss_model else {}),
                       **{k: v for k, v in calibration_metrics(estimates).items() if pd.notna(v)})
        metrics.update({METRIC_KEYS[k]: float(v) for k, v in values.items()})
        metrics["gated"] = float(summary["gated"])
    (out / "metrics.json").write_text(json.dumps(summary, indent=1, default=float))
    return metrics
