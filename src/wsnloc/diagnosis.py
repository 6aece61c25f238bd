"""Diagnosis of one run: what says the estimator's model does not fit the data, with the
likely cause and a remedy. No truth is used: only the estimates, their attrs and the run's
measurements, so that it works on any user run.

Values (`diagnose_run`, all optional, NaN where the estimator or run has none):
  gated_share       measurements rejected by the innovation gate / offered (attrs)
  restarts          track dropped and restarted (attrs `resets`)
  gaps              the stretches longer than max_coast_s without measurements of two anchors (the
                    usable measurements the estimator reads, of its subset): none at all, or one anchor
                    (TDOA: one pair) alone, which gives a distance, not a position; as (start, end,
                    the anchor heard alone or None) in s after the first measurement: where a
                    sequential track is dropped whatever the model (restarts; core.Support)
  withheld          estimates not output because their position sigma passed max_position_sigma_m (a
                    track coasting through a gap) or they lie beyond max_range_m of every anchor
                    (attrs `withheld`, core.withhold_uncertain), or, by the sliding window, because
                    its window held no measurement
  withheld_share    withheld / the run's output times (its epoch grid); beyond WITHHELD_SHARE_LIMIT a
                    finding says the scores cover the rest only
  widenings         the gate rejected most recent measurements and the covariance was widened
                    (attrs `gate_widenings`, filter_options.ConfiguredFilter.widen)
  refixes           restarts at once because a fix on the recent ranges explained them better
                    than the track (attrs `gate_refixes`, ConfiguredFilter.fix_explains_better)
  nis_mean          mean normalised innovation squared per measurement dof over the updates,
  nis_low/high      with its two-sided 95% chi-square band (metrics.consistency.chi2_band;
                    sequential updates: 1 dof per update, the last update of each output
                    step; epoch updates: n_meas dof). Above the band: the innovations are
                    larger than the filter's R + HPH' says (noise, bias or a scale error
                    not modelled); below: R is larger than needed.
  range_scale       r = s d + b_a fitted robustly (metrics.ranging.fit_range_bias) on the
  range_offsets_m   measured ranges against the distances from the *estimated* track
                    (interpolated at the range times, 3-D where the anchor has z): residual
                    structure the filter did not absorb. A common scale error leaves s != 1,
                    per-anchor biases leave offsets b_a.
  self_scale, self_offset_m   the filter's own self-calibration states, where it has them
  calibrated_scale  the range calibration applied (donor or self-fitted), where one was, and
  calibrated_offsets_m  its per-anchor offsets
  self_fit_run_sigma_m, self_fit_range_sigma_m, self_fit_accel_sigma_mps2 (P model:
  self_fit_p_sigma_m), self_fit_range_correction
                    the tracker's self-fit (estimators.self_fit): the range sigma the output pass ran
                    with, the sigma of the innovations' Gaussian core and the process noise with
                    it (maximum likelihood; the P model's is p_sigma_m), and whether the fitted range scale and offsets were applied. The run sigma is deliberately wider than the core
                    (the gate keeps NLOS-long ranges), so the NIS of a self-fitted run sits below its
                    band by about (core / run sigma)^2: the stated covariance is pessimistic, not
                    the noise mis-set.
  regularised, skipped, reinitialised   numerical guards (filters.numerics): covariances made
                    positive definite, updates skipped (singular or non-finite), particle-filter
                    restarts from a fix after its likelihood collapsed (attrs, where counted)
  update            the update mode used (`auto` resolved from the data: estimators.auto), not a metric
Sentences (`findings`): one per value outside its tolerance, each "what: likely cause; remedy";
where the self-fit already corrected the range scale or offsets the sentence says so instead
(the fit above reads the ranges as measured), and where it kept the scale alone, why the offsets
were left out. Read against a track whose gate rejected more than POOR_TRACK_GATED_SHARE of the
ranges, the scale and offsets carry a caveat: that track trades them against its own error (a
walk with ranges 7% long read "13% short" with 42% gated and self_fit=none).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.campaign import generic_site
from wsnloc.estimators import range_calibration
from wsnloc.estimators.measurements import KINDS
from wsnloc.estimators.run_data import RunData
from wsnloc.estimators.self_fit import FITTED_NOISE_KEYS, PROCESS_NOISE
from wsnloc.metrics.consistency import chi2_band
from wsnloc.metrics.ranging import fit_range_bias, positions_and_distances

GATED_SHARE_LIMIT = 0.05        # more rejected than this: the model is wrong more often than an outlier rate
POOR_TRACK_GATED_SHARE = 0.2    # more rejected than this: the scale / offsets read against the track are unreliable
SCALE_TOLERANCE = 0.03          # |s - 1| above this: a common range scale error (UWB clock/antenna delay ~1%)
OFFSET_TOLERANCE_M = 0.15       # |b_a| above this: a per-anchor bias (antenna delay, cable; UWB sigma ~0.1 m)
MIN_RANGES = 50                 # fewer ranges along the track: no scale / offset fit
WITHHELD_SHARE_LIMIT = 0.2     # withheld outputs beyond this share of the output times: said, with what it means
MAX_GAPS_LISTED = 3             # measurement gaps named in the restart sentence
GUARDS = {"regularised": "covariances made positive definite", "skipped": "updates or windows skipped",
          "reinitialised": "particle filter restarted from a fix"}
SELF_FIT = ("self_fit_run_sigma_m", "self_fit_range_sigma_m", "self_fit_range_correction") \
    + tuple(fitted for _, fitted in FITTED_NOISE_KEYS.values())


def _nis(estimates: pd.DataFrame, p: dict) -> dict:
    nis = estimates["nis"].to_numpy(float) if "nis" in estimates else np.array([])
    used = np.isfinite(nis)
    if not used.any():
        return {}
    if estimates.attrs.get("update", p.get("update")) == "sequential":       # attrs: the mode `auto` chose
        dof = np.ones(used.sum())
    else:
        dof = np.maximum(estimates["n_meas"].to_numpy(float)[used], 1.0)
    mean_per_dof = float(nis[used].sum() / dof.sum())
    low, high = chi2_band(dof.sum(), dof.sum())
    return {"nis_mean": mean_per_dof, "nis_low": float(low), "nis_high": float(high)}


def track_distances(data: RunData, estimates: pd.DataFrame, p: dict) -> pd.DataFrame | None:
    """The run's usable ranges (t, anchor_id, range_m; status 0) with the estimated track's position
    interpolated at their times (true_x, true_y, m) and its distance to the anchor (true_distance_m,
    3-D where the anchor has z; metrics.ranging.positions_and_distances); None when too few.
    Arrays, not frame operations: the self-fit reads it twice a run (about 0.5 ms, not 2.5 ms)."""
    ranges = data.usable_ranges(p.get("preliminary_filter", True), p.get("max_range_m", np.inf))
    ranges = ranges[ranges["status"].to_numpy() == 0]
    if "range_calibration" in p:                        # as the filter read them: a donor's or the campaign's
        ranges = range_calibration.correction(data, p).apply(ranges)
    x, y = estimates["x"].to_numpy(float), estimates["y"].to_numpy(float)
    finite = np.isfinite(x) & np.isfinite(y)
    if len(ranges) < MIN_RANGES or finite.sum() < 2:
        return None
    track = pd.DataFrame({"t": estimates["t"].to_numpy(float)[finite], "x": x[finite], "y": y[finite]})
    site = data.campaign or generic_site()
    anchors = data.table("anchors") if len(data.table("anchors")) else site.anchors
    inside, position, _, distance = positions_and_distances(ranges["t"].to_numpy(float), ranges["anchor_id"], track,
                                                            site, anchors)
    if len(inside) < MIN_RANGES:
        return None
    return pd.DataFrame({"t": ranges["t"].to_numpy(float)[inside],
                         "anchor_id": ranges["anchor_id"].to_numpy(dtype=object)[inside],
                         "range_m": ranges["range_m"].to_numpy(float)[inside], "true_x": position[:, 0],
                         "true_y": position[:, 1], "true_distance_m": distance})


def range_fit(data: RunData, estimates: pd.DataFrame, p: dict) -> dict:
    """{range_scale, range_offsets_m} of the run's ranges, as the filter read them, against the
    estimated track ({} when too few, and for an estimator that cannot take a range calibration:
    the tracks of Min-Max, multilateration and the trackers over their fixes lag or scatter more
    than the errors sought, and told a reviewer "ranges look 4-13% long" on exact ranges)."""
    if "range_calibration" not in p:
        return {}
    samples = track_distances(data, estimates, p)
    if samples is None:
        return {}
    try:
        fit = fit_range_bias(samples["range_m"], samples["true_distance_m"], samples["anchor_id"])
    except ValueError:
        return {}
    return {"range_scale": float(fit["scale"]), "range_offsets_m": {k: float(v) for k, v in fit["offsets_m"].items()}}


def measurement_gaps(data: RunData, p: dict) -> list[tuple[float, float, str | None]]:
    """(start, end, anchor) (s after the first usable measurement) of every stretch longer than
    max_coast_s without measurements of two anchors (module docstring, gaps), in time order:
    anchor None where none came at all (start, end: the measurements around it), else the one
    anchor (or TDOA pair) heard alone (start, end: the last and next measurement of another, or
    the run's last measurement); [] for an estimator without a coasting limit. The sequential
    filters' and the sliding window's deleter counts both as coasting (core.Support). A stretch of
    one anchor that holds a gap is listed as that gap only."""
    if "max_coast_s" not in p:
        return []
    t, ids = _timeline(data, p)
    if len(t) < 2:
        return []
    limit = p["max_coast_s"]
    step = np.diff(t)
    out = [(t[i], t[i + 1], None) for i in np.flatnonzero(step > limit)]
    starts = np.flatnonzero(ids[1:] != ids[:-1]) + 1                 # runs of one anchor, but the first
    ends = np.r_[starts[1:] + 1, len(t)]                             # the next other anchor's index + 1
    long = t[ends - 1] - t[starts - 1] > limit
    for s, e in zip(starts[long], ends[long]):
        if step[s - 1:e - 1].max() <= limit:                         # not a gap's
            out.append((t[s - 1], t[e - 1], str(ids[s])))
    return sorted((float(a - t[0]), float(b - t[0]), anchor) for a, b, anchor in out)


def _timeline(data: RunData, p: dict) -> tuple[np.ndarray, np.ndarray]:
    """(t, id) in time order of the usable measurements the estimator reads (its `measurements`:
    ranges, RSS or both by anchor, range differences by pair; all where it names none) of its
    anchor subset: what its deleter's support (core.Support) sees."""
    kinds = KINDS.get(p.get("measurements"), ("ranges", "rss", "tdoa"))
    members = data.members(p.get("anchors", "all"))
    frames = {"ranges": data.usable_ranges(p.get("preliminary_filter", True), p.get("max_range_m", np.inf)),
              "rss": data.usable_rss(), "tdoa": data.usable_tdoa()}
    t, ids = [], []
    for kind in kinds:
        frame = frames[kind]
        inside = frame["anchor_id"].isin(members) & (frame["ref_anchor_id"].isin(members) if kind == "tdoa" else True)
        frame = frame[inside]
        t.append(frame["t"].to_numpy(float))
        pair = "/" + frame["ref_anchor_id"].astype(str) if kind == "tdoa" else ""
        ids.append((frame["anchor_id"].astype(str) + pair).to_numpy(object))
    t, ids = np.concatenate(t), np.concatenate(ids)
    order = np.argsort(t, kind="stable")
    return t[order], ids[order]


def _withheld_share(data: RunData, withheld: int, output: int, p: dict) -> float:
    """withheld / the run's output times (the epoch grid), or / (withheld + output) for an
    estimator without one."""
    if "epoch_s" in p:
        times = len(data.grid(p["epoch_s"], p.get("preliminary_filter", True), p.get("max_range_m", np.inf)))
        return withheld / max(times, 1)
    return withheld / max(withheld + output, 1)


def diagnose_run(data: RunData, estimates: pd.DataFrame, p: dict) -> dict:
    """The diagnosis values of one run (module docstring)."""
    a = estimates.attrs
    gaps = measurement_gaps(data, p)
    if a.get("update", p.get("update")) != "sequential" and "window_s" not in p:    # epoch updates coast on
        gaps = [gap for gap in gaps if gap[2] is None]                              # any update
    out = {"gated_share": float(a["gated_share"]) if "gated_share" in a else np.nan,
           "restarts": int(a.get("resets", 0)), "widenings": int(a.get("gate_widenings", 0)),
           "refixes": int(a.get("gate_refixes", 0)), "withheld": int(a.get("withheld", 0)),
           "withheld_share": _withheld_share(data, int(a.get("withheld", 0)), len(estimates), p),
           "gaps": gaps, **_nis(estimates, p), **range_fit(data, estimates, p)}
    if "range_scale" in a:
        out["self_scale"] = float(a["range_scale"])
    if "range_offset_m" in a:
        out["self_offset_m"] = float(a["range_offset_m"])
    out.update({k: int(a[k]) for k in GUARDS if k in a})
    if "update" in a:
        out["update"] = str(a["update"])
    if a.get("range_calibration", "none") != "none" and "calibrated_scale" in a:
        out["calibrated_scale"] = float(a["calibrated_scale"])
        out["calibrated_offsets_m"] = dict(a.get("calibrated_offsets_m") or {})
    out.update({k: a[k] for k in SELF_FIT if k in a})
    return out


def findings(d: dict, p: dict) -> list[str]:
    """Likely cause and remedy, one sentence per symptom (module docstring); [] when all fit."""
    out = []
    if d.get("withheld_share", 0.0) > WITHHELD_SHARE_LIMIT:
        why, compare = (("position sigma above max_position_sigma_m: where the measurements do not fix the position "
                         "(anchors clustered far from the track, range differences along their hyperbolae, one anchor) "
                         "or a gap", " (max_position_sigma_m=0 outputs every one)")
                        if "max_position_sigma_m" in p else ("windows without a measurement", ""))
        out.append(f"{d['withheld_share']:.0%} of the output times have no estimate ({d['withheld']} withheld: {why}); "
                   f"the scores cover the rest only: compare estimators at the same availability{compare}")
    if np.isfinite(d.get("gated_share", np.nan)) and d["gated_share"] > GATED_SHARE_LIMIT:
        if p.get("measurements") == "rss":
            remedy = (f"the RSS model (P0, path-loss exponent, sigma_db) does not fit the site; fit it on a donor "
                      f"run with truth (--calibration DONOR_RUN) or raise sigma_db (now {p.get('sigma_db', '?')})")
        else:
            sigma = d.get("self_fit_run_sigma_m") or p.get("range_sigma_m")      # the one the run used
            now = f" (the run's {float(sigma):.2g} m)" if sigma is not None else ""
            calibrate = "" if str(d.get("self_fit_range_correction", "")).startswith("applied") \
                else "calibrate the ranges (--calibration DONOR_RUN)"
            options = _options(p, robust_loss="robust_loss=cauchy", range_sigma_m=f"a larger range_sigma_m{now}")
            remedy = "noise too small, ranges biased or scaled" + (f"; try {options}" if options else "") \
                + (", or " if options and calibrate else "; " if calibrate else "") + calibrate
        out.append(f"the gate rejected {d['gated_share']:.0%} of the measurements: the model is wrong more often "
                   f"than outliers explain ({remedy})")
    if d.get("widenings", 0) > 0:
        out.append(f"the gate rejected most measurements {d['widenings']} time(s) and the position covariance "
                   f"was widened to take them back: turns livelier than the process noise, a bias or a gap; "
                   f"raise accel_sigma_mps2 or range_sigma_m if it recurs")
    refixes = d.get("refixes", 0)
    if d.get("restarts", 0) > refixes:
        out.append(_restarts(d["restarts"] - refixes, d.get("gaps") or [], p))
    if refixes > 0:
        out.append(f"the track was restarted from a fix {refixes} time(s): the gate rejected most recent ranges and a "
                   f"fix on them fitted them far better than the track; often a wrong branch (ranged one anchor at a "
                   f"time past an anchor, the mirror side of two anchors); more anchors in range or a higher ranging "
                   f"rate avoid it (gate_refix=false widens the covariance instead, as the smoothers do)")
    if "nis_mean" in d:
        out += _nis_findings(d, p)
    guarded = {k: d[k] for k in GUARDS if d.get(k, 0) > 0}
    if guarded:
        listed = ", ".join(f"{k} {n}: {GUARDS[k]}" for k, n in guarded.items())
        out.append(f"numerical guards acted ({listed}): the measurements disagree with the model or the geometry is "
                   f"degenerate (few or collinear anchors); check the anchors, raise range_sigma_m or use `tracker`")
    corrected = str(d.get("self_fit_range_correction", ""))
    gated = d.get("gated_share", np.nan)
    caveat = (f" (read against a track whose gate rejected {gated:.0%} of the ranges: a poor track trades "
              f"scale and offsets against its own error, so these may be off, even in sign)"
              if np.isfinite(gated) and gated > POOR_TRACK_GATED_SHARE else "")
    scale = d.get("range_scale", np.nan)
    calibrated = p.get("range_calibration", "none") != "none"       # a donor's or the campaign's: read after it
    after = (" (the ranges after the range calibration applied: what it leaves; a donor of another set-up, or "
             "errors that change along the path)" if calibrated else "")
    if np.isfinite(scale) and abs(scale - 1.0) > SCALE_TOLERANCE:
        fitted_scale = d.get("calibrated_scale", np.nan) if corrected.startswith("applied") else np.nan
        cause = "a common range scale error"
        if abs(fitted_scale - scale) <= SCALE_TOLERANCE:
            remedy = f"the self-fit corrected it (scale {fitted_scale:.3f} applied)"
        elif np.isfinite(fitted_scale):     # the self-fit read the scale apart from the track's own error
            cause = "more likely the track's own error (a wrong branch, a low ranging rate) than the ranges'"
            remedy = f"the self-fit, which fits the scale with the track's error, found and applied {fitted_scale:.3f}"
        elif calibrated:
            remedy = "try range_self_calibration=scale" + after
        else:
            options = (_options(p, range_self_calibration="range_self_calibration=scale"), "--calibration DONOR_RUN")
            remedy = "try " + ", or ".join(t for t in options if t)
        out.append(f"ranges look {abs(scale - 1.0):.0%} {'long' if scale > 1 else 'short'} against the track"
                   f"{caveat}: {cause}; {remedy}")
        caveat = " (the same caveat)" if caveat else ""
    biased = {k: v for k, v in (d.get("range_offsets_m") or {}).items() if abs(v) > OFFSET_TOLERANCE_M}
    if biased:
        listed = ", ".join(f"{k} {v:+.2f} m" for k, v in sorted(biased.items(), key=lambda kv: -abs(kv[1])))
        if corrected == "applied":
            applied = d.get("calibrated_offsets_m") or {}
            largest = sorted(applied.items(), key=lambda kv: -abs(kv[1]))[:4]
            listed_fit = ", ".join(f"{k} {v:+.2f} m" for k, v in largest)
            remedy = ("the self-fit applied its own correction, fitted with the track's error and the outliers "
                      f"left out (calibrated_offsets_m: {listed_fit}); offsets beyond it here are what the track "
                      "and those outliers still carry (NLOS-long ranges, robust_loss=cauchy)"
                      if applied and any(abs(applied.get(k, 0.0) - v) > OFFSET_TOLERANCE_M for k, v in biased.items())
                      else "the self-fit corrected them (calibrated_offsets_m in the run's metrics)")
        elif calibrated:
            remedy = f"robust_loss=cauchy takes NLOS-long ranges as outliers{after}"
        else:
            left = ("the self-fit left them out: offsets fitted on part of the run beat constant ones "
                    "(self_fit_range_local_gain), so they change along the path; "
                    if corrected.startswith("applied, scale only") else "")
            remedy = (f"{left}try --calibration DONOR_RUN (a run of the same site with truth) or the campaign's "
                      f"range_calibration.offsets_m")
        out.append(f"per-anchor range offsets against the track ({listed}){caveat}: antenna delays or NLOS biases; "
                   f"{remedy}")
    return out


def _restarts(n: int, gaps: list[tuple[float, float, str | None]], p: dict) -> str:
    """The sentence of n restarts (re-fixes apart): those the stretches longer than max_coast_s
    without two anchors explain (measurement_gaps; named, MAX_GAPS_LISTED of them), and the
    others, which a gate lost."""
    coast = f"max_coast_s ({p.get('max_coast_s', '?')} s)"
    parts = []
    if gaps:
        alone = any(anchor is not None for _, _, anchor in gaps)
        listed = ", ".join(f"{a:.0f}-{b:.0f} s" + ("" if anchor is None else f" ({anchor} alone)")
                           for a, b, anchor in gaps[:MAX_GAPS_LISTED]) \
            + (f" and {len(gaps) - MAX_GAPS_LISTED} more" if len(gaps) > MAX_GAPS_LISTED else "")
        what = ("the measurements stop, or come from one anchor alone (a distance, not a position),"
                if alone else "the measurements stop")
        parts.append(f"{what} for longer than {coast} {len(gaps)} time(s) ({listed} after the first "
                     f"measurement): no estimate there is expected (raise max_coast_s to coast through shorter ones)")
    lost = n - min(len(gaps), n)
    if lost:
        why = []
        if p.get("gate_probability", 0.0) > 0:
            raise_ = _options(p, gate_loss_share="gate_loss_share", range_sigma_m="range_sigma_m")
            why.append(f"the gate lost the track (most recent measurements rejected)"
                       f"{f'; raise {raise_} if that recurs' if raise_ else ''}")
        if "window_s" in p:             # the sliding window: a window it could not solve
            why.append("a window's solution was dropped (it did not converge or left the anchors' reach: skipped)")
        elif not why:
            why.append("its anchor subset's measurements stopped or came from one anchor for longer than "
                       "max_coast_s")
        parts.append(f"{'the other ' if gaps else ''}{lost} time(s) " + ", or ".join(why))
    return f"the track was dropped and restarted {n} time(s): " + "; ".join(parts)


def _options(p: dict, **phrases: str) -> str:
    """The phrases (keyed by parameter name) of the parameters the estimator has (p: its resolved
    parameters), joined by " or ": advice names only settings the estimator accepts."""
    return " or ".join(phrase for name, phrase in phrases.items() if name in p)


def _nis_findings(d: dict, p: dict) -> list[str]:
    """The NIS outside its band: what it means. A self-fitted run states its own sigma (run) and the
    innovations' core (fit): below the band by about (fit / run)^2 is the self-fit's choice. The
    NIS is that of the measurements the gate kept (estimators.robust.robust_update): where the core
    is not narrower than the run's sigma, a NIS below the band is the gate's truncation."""
    band = f"NIS {d['nis_mean']:.2f} per dof is {{}} its 95% band [{d['nis_low']:.2f}, {d['nis_high']:.2f}]"
    noise = PROCESS_NOISE[p.get("motion") == "p"]          # accel_sigma_mps2, or p_sigma_m for the P model
    run, core, process = (d.get(k) for k in ("self_fit_run_sigma_m", "self_fit_range_sigma_m",
                                             FITTED_NOISE_KEYS[noise][1]))
    sigma = run or p.get("range_sigma_m")
    if d["nis_mean"] > d["nis_high"] and p.get("filter") == "pf":
        return [band.format("above") + ": the particle filter updates with every measurement (no gate: its "
                "likelihood's uniform outlier part weighs NLOS-long ranges down instead), so those ranges' "
                "innovations raise the NIS; not a noise setting to change: read the restarts and the range "
                "offsets instead"]
    if d["nis_mean"] > d["nis_high"]:
        hint = f" (range_sigma_m about {sigma * np.sqrt(d['nis_mean']):.2g} would match)" \
            if sigma and p.get("measurements", "toa") == "toa" else ""
        return [band.format("above") + ": the innovations are larger than the filter expects; raise the "
                f"measurement noise{hint} or the process noise ({noise})"]
    if d["nis_mean"] >= d["nis_low"]:
        return []
    if run and core and process and core >= run:
        gated = d.get("gated_share", np.nan)
        share = f" ({gated:.0%} gated)" if np.isfinite(gated) else ""
        return [band.format("below") + f", yet the innovations' Gaussian core (about {core:.2g} m) is not narrower "
                f"than the run's range sigma ({run:.2g} m): the NIS counts only the measurements the gate kept"
                f"{share}, the smaller innovations; read the gated share and the range offsets above, not this NIS"]
    if run and core and process:
        return [band.format("below") + f": the self-fit ran with range sigma {run:.2g} m, the candidate whose "
                f"gain fits the innovations best, while their Gaussian core is about {core:.2g} m; the stated "
                f"covariance is pessimistic by about {1 / np.sqrt(d['nis_mean']):.1f}x in sigma (the wider noise "
                f"keeps NLOS-long ranges inside the gate). By design, not a setting to change: the core's sigma "
                f"({core:.2g} m, {noise} {process:.2g}) as the run's noise with self_fit=none gates those ranges "
                f"out and can lose the track (docs/realdata.md, self-fit)"]
    return [band.format("below") + ": the measurement noise is set larger than the data need; a smaller one "
            "would follow the track more closely"]


def metrics_of(d: dict) -> dict:
    """Flat scalar columns of a diagnosis for metrics files (offsets as 'A=b;...', findings counted)."""
    out = {f"diag_{k}": v for k, v in d.items()
           if k not in ("range_offsets_m", "calibrated_offsets_m", "update", "self_fit_range_correction", "gaps")}
    out["diag_gaps"] = len(d.get("gaps") or [])
    if "self_fit_range_correction" in d:
        out["diag_self_fit_range_corrected"] = float(d["self_fit_range_correction"].startswith("applied"))
    offsets = d.get("range_offsets_m") or {}
    out["diag_max_abs_offset_m"] = max((abs(v) for v in offsets.values()), default=np.nan)
    out["diag_range_offsets_m"] = ";".join(f"{k}={v:.3f}" for k, v in offsets.items())
    return out


def report(d: dict, p: dict) -> str:
    """Lines for `wsnloc estimate`: the values, then each finding (or that the model fits)."""
    values = [f"{d['update']} updates" if "update" in d else None,
              f"gated {d['gated_share']:.1%}" if np.isfinite(d.get("gated_share", np.nan)) else None,
              f"restarts {d.get('restarts', 0)}" + (f" ({d['refixes']} re-fixed)" if d.get("refixes") else ""),
              f"widened {d.get('widenings', 0)}",
              f"withheld {d['withheld']} estimates ("
              + (f"position sigma above max_position_sigma_m {p['max_position_sigma_m']} m, or beyond max_range_m of "
                 f"every anchor)" if "max_position_sigma_m" in p
                 else "windows without a measurement)") if d.get("withheld") else None,
              f"NIS {d['nis_mean']:.2f} per dof (95% band {d['nis_low']:.2f}-{d['nis_high']:.2f})"
              if "nis_mean" in d else None,
              f"range scale vs track {d['range_scale']:.3f}" if "range_scale" in d else None,
              f"self-calibrated scale {d['self_scale']:.3f}" if "self_scale" in d else None,
              f"self-fit range sigma {d['self_fit_run_sigma_m']:.2g} m (innovations' core "
              f"{d['self_fit_range_sigma_m']:.2g} m), range correction {d['self_fit_range_correction']}"
              if "self_fit_run_sigma_m" in d and "self_fit_range_correction" in d else None]
    lines = ["diagnosis: " + ", ".join(v for v in values if v)]
    found = findings(d, p)
    lines += [f"  - {f}" for f in found] or ["  - no sign that the model does not fit"]
    return "\n".join(lines)
