"""TDOA made from two-way ranges: `wsnloc convert tdoa SRC OUT`.

Range differences d(anchor) - d(ref) to a reference anchor, from the ranges of a generic
run. Ranges of different anchors are asynchronous (a round of two-way ranging visits the
anchors one after the other, and an anchor may be missed), so they are paired in time: at
each range of the reference anchor (time t_ref) every other anchor's range is interpolated
linearly between its two samples bracketing t_ref, when both lie within the window of t_ref
(an anchor sampled exactly at t_ref is used as is); otherwise that pair is left out of the
group. The window is `window_s` or 1.5 ranging round periods, whichever is longer (the
round period: the median over anchors of each anchor's median spacing; with anchors ranged
one at a time a round lasts several tenths of a second). The pairs of one reference range
share its time and its noise, as TDOA pairs of one transmission share the reference's
arrival (the TDOA model's correlated noise). The reference is chosen per time group: the
anchor with the most ranges (ties: the first id in sorted order; or the one given) wherever
it can be paired (it has a sample at t or two bracketing ones within the window); where it
cannot (out of range, a gap), the next anchor by number of ranges at its own range times,
and so on, so a missing reference anchor does not drop the other anchors' ranges. Ranges
with a non-zero status or not finite are not used.

Before pairing, each anchor's isolated outliers are left out (a Hampel identifier): a range
further than HAMPEL_SIGMAS normalised MADs (metrics.stats.robust_sigma: 1.4826 x the median absolute
residual over that anchor's ranges, at least 1 cm) from the robust (repeated-median) line through its HAMPEL_NEIGHBOURS
neighbours on each side within two windows of it (`outliers`). An NLOS or multipath excess of one two-way range would
otherwise reach every difference it is paired into: the interpolations on both sides of it and,
for the reference, every pair of its group; the tracker on the ranges meets it once and
gates it. A lasting excess (a blocked path for seconds) moves the neighbours' median with it
and is kept. The ranges left out are listed in the run's convert_quarantine.csv.

A converted run is the source run with `tdoa.csv` (t, anchor_id, ref_anchor_id, tdoa_m) in
place of `ranges.csv` and without `rss.csv`; every other file (anchors, truth, meta.yaml,
reference tables) is copied unchanged; ranges the generic reader quarantines are added to
the run's convert_quarantine.csv. SRC is a generic run directory or a folder of them
(every directory holding ranges.csv or ranges.parquet below it; OUT mirrors their paths).
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd

from wsnloc.errors import IngestError
from wsnloc.metrics.stats import robust_sigma
from wsnloc.io import generic
from wsnloc.io.convert import QUARANTINE_FILE, Converted

WINDOW_S = 0.25      # pairing window: a bracketing sample at most this far from t_ref (s); ~2.5 rounds at 10 Hz
ROUND_WINDOWS = 1.5  # ... and at least 1.5 ranging round periods (anchors ranged one after the other, jitter)
HAMPEL_NEIGHBOURS = 2   # outlier test: the line through up to 2 ranges of the same anchor on each side ...
HAMPEL_SIGMAS = 3.0     # ... a range further than 3 normalised MADs from it is left out (Hampel identifier)
HAMPEL_FLOOR_M = 0.01   # smallest spread of the test (m): ranges quantised or noise-free


def reference_order(ranges: pd.DataFrame) -> list[str]:
    """Anchor ids by number of ranges, most first (ties: sorted id order)."""
    counts = ranges["anchor_id"].value_counts()
    return sorted(counts.index, key=lambda a: (-counts[a], a))


def round_period(ranges: pd.DataFrame) -> float:
    """The ranging round period P (s): the median over anchors of each anchor's median spacing
    between its ranges (NaN with no anchor ranged twice). Gaps and missed rounds are outliers of
    an anchor's spacings and leave its median alone."""
    spacings = [np.median(np.diff(np.sort(rows.to_numpy(float)))) for _, rows in ranges.groupby("anchor_id")["t"]
                if len(rows) > 1]
    return float(np.median(spacings)) if spacings else float("nan")


def _at(t_query: np.ndarray, t: np.ndarray, r: np.ndarray, window_s: float) -> tuple[np.ndarray, np.ndarray]:
    """One anchor's range at the times t_query (s) from its samples (t sorted, r): the sample at
    exactly t_query, else the linear interpolation between the two samples bracketing t_query
    when both lie within window_s of it; (values, usable) with values undefined where not usable."""
    after = np.searchsorted(t, t_query, side="left")              # first sample at or after t_query
    before = np.clip(after - 1, 0, len(t) - 1)
    after_c = np.clip(after, 0, len(t) - 1)
    exact = (after < len(t)) & (t[after_c] == t_query)
    bracketed = ((after > 0) & (after < len(t)) & (t_query - t[before] <= window_s)
                 & (t[after_c] - t_query <= window_s))
    with np.errstate(invalid="ignore", divide="ignore"):
        share = np.where(t[after_c] > t[before], (t_query - t[before]) / (t[after_c] - t[before]), 0.0)
    return np.where(exact, r[after_c], r[before] + share * (r[after_c] - r[before])), exact | bracketed


def outliers(t: np.ndarray, r: np.ndarray, span_s: float) -> np.ndarray:
    """bool: the isolated outliers among one anchor's ranges r (m) at sorted times t (s) (module
    docstring). The reference of range i is the repeated-median line through its neighbours (up
    to HAMPEL_NEIGHBOURS on each side within span_s, i itself left out) at t_i: the slope s is
    the median over neighbours j of the median of j's slopes to the others (Siegel), the value
    the median of r_j - s (t_j - t_i), so the target's motion does not count as an outlier and
    one outlier among the neighbours does not move it. Flagged: a
    residual beyond HAMPEL_SIGMAS normalised MADs of the anchor's residuals (at least
    HAMPEL_FLOOR_M); a range with fewer than two neighbours is not tested. At the onset and end
    of a lasting excess one or two ranges may be flagged too."""
    n = len(t)
    steps = [k for k in range(-HAMPEL_NEIGHBOURS, HAMPEL_NEIGHBOURS + 1) if k]
    dt = np.full((n, len(steps)), np.nan)
    value = np.full((n, len(steps)), np.nan)
    for j, k in enumerate(steps):
        index = np.arange(n) + k
        inside = (index >= 0) & (index < n)
        index = np.clip(index, 0, n - 1)
        near = inside & (np.abs(t[index] - t) <= span_s)
        dt[near, j], value[near, j] = (t[index] - t)[near], r[index][near]
    tested = np.sum(np.isfinite(value), axis=1) >= 2
    if not tested.any():
        return np.zeros(n, dtype=bool)
    dt, value = dt[tested], value[tested]
    with np.errstate(invalid="ignore", divide="ignore"):
        slopes = (value[:, None, :] - value[:, :, None]) / (dt[:, None, :] - dt[:, :, None])   # (rows, j, k)
    slopes[~np.isfinite(slopes)] = np.nan
    each = np.column_stack([_nanmedian(slopes[:, j]) for j in range(len(steps))])
    slope = np.nan_to_num(_nanmedian(each))
    residual = r[tested] - _nanmedian(value - slope[:, None] * dt)
    spread = max(robust_sigma(residual), HAMPEL_FLOOR_M)
    flagged = np.zeros(n, dtype=bool)
    flagged[tested] = np.abs(residual) > HAMPEL_SIGMAS * spread
    return flagged


def _nanmedian(values: np.ndarray) -> np.ndarray:
    """Row medians ignoring NaN; NaN for a row without a value (without numpy's warning)."""
    out = np.full(len(values), np.nan)
    some = np.isfinite(values).any(axis=1)
    out[some] = np.nanmedian(values[some], axis=1)
    return out


def ranges_to_tdoa(ranges: pd.DataFrame, reference: str | None = None, window_s: float = WINDOW_S) -> pd.DataFrame:
    """Range differences (t, anchor_id, ref_anchor_id, tdoa_m) from ranges (t, anchor_id, range_m
    [, status]) (module docstring), sorted by t then anchor; attrs["outliers"]: the ranges left
    out as isolated outliers (rows of `ranges`)."""
    columns = ["t", "anchor_id", "ref_anchor_id", "tdoa_m"]
    ok = np.isfinite(ranges["range_m"]) & np.isfinite(ranges["t"])
    if "status" in ranges:
        ok &= ranges["status"].fillna(0) == 0
    ranges = ranges[ok].sort_values("t", kind="stable")
    if not len(ranges):
        return pd.DataFrame(columns=columns)
    period = round_period(ranges)
    window_s = max(window_s, ROUND_WINDOWS * period) if np.isfinite(period) else window_s
    flagged = np.zeros(len(ranges), dtype=bool)
    for _, rows in ranges.groupby("anchor_id", sort=False).indices.items():
        flagged[rows] = outliers(ranges["t"].to_numpy(float)[rows], ranges["range_m"].to_numpy(float)[rows],
                                 2.0 * window_s)
    dropped, ranges = ranges[flagged], ranges[~flagged]
    samples = {anchor: (rows["t"].to_numpy(float), rows["range_m"].to_numpy(float))
               for anchor, rows in ranges.sort_values("t", kind="stable").groupby("anchor_id", sort=True)}
    order = reference_order(ranges)
    if reference is not None:
        order = [reference] + [a for a in order if a != reference]
    out, earlier = [], []
    for ref in order:                                            # each reference at the times no earlier one serves
        t_ref, r_ref = samples[ref]
        free = np.ones(len(t_ref), dtype=bool)
        for other in earlier:
            free &= ~_at(t_ref, *samples[other], window_s)[1]
        earlier.append(ref)
        t_ref, r_ref = t_ref[free], r_ref[free]
        for anchor in sorted(samples):
            if anchor == ref or not len(t_ref):
                continue
            value, use = _at(t_ref, *samples[anchor], window_s)
            out.append(pd.DataFrame({"t": t_ref[use], "anchor_id": anchor, "ref_anchor_id": ref,
                                     "tdoa_m": value[use] - r_ref[use]}))
    frame = pd.concat(out, ignore_index=True) if out else pd.DataFrame(columns=columns)
    frame = frame.sort_values(["t", "anchor_id"], kind="stable").reset_index(drop=True)
    frame.attrs["outliers"] = dropped
    return frame


def _run_dirs(src: Path) -> list[Path]:
    if generic.find(src, "ranges") is not None:
        return [src]
    runs = sorted({p.parent for suffix in ("csv", "parquet") for p in src.rglob(f"ranges.{suffix}")})
    if not runs:
        raise IngestError(f"{src}: no generic run (a directory with ranges.csv or ranges.parquet) below it")
    return runs


def outlier_rows(dropped: pd.DataFrame | None, file: str) -> pd.DataFrame:
    """Quarantine rows (file, line, text, reason) of the ranges left out as outliers."""
    if dropped is None or not len(dropped):
        return pd.DataFrame(columns=["file", "line", "text", "reason"])
    return pd.DataFrame({"file": file, "line": dropped["line"].to_numpy() if "line" in dropped else -1,
                         "text": [f"{t:.6f},{a},{r:.4f}" for t, a, r in dropped[["t", "anchor_id", "range_m"]]
                                  .itertuples(index=False)],
                         "reason": f"isolated outlier: beyond {HAMPEL_SIGMAS:g} normalised MADs of the median of its "
                                   "neighbours (not converted to TDOA)"})


def convert_tdoa(src: str | Path, out: str | Path, reference: str | None = None,
                 window_s: float = WINDOW_S) -> list[Converted]:
    """Every generic run below `src` as a TDOA run below `out` (module docstring)."""
    src, out = Path(src), Path(out)
    converted = []
    for run in _run_dirs(src):
        tables, _ = generic.ingest_run(run)            # the generic reader's quarantine rules apply to the ranges
        target = out / run.relative_to(src) if run != src else out
        target.mkdir(parents=True, exist_ok=True)
        for path in run.iterdir():
            if path.is_file() and path.stem not in ("ranges", "rss", "tdoa"):
                shutil.copy2(path, target / path.name)
        tdoa = ranges_to_tdoa(tables["ranges"], reference, window_s)
        if not len(tdoa):
            raise IngestError(f"{run}: no range pairs within {window_s} s to make TDOA from")
        tdoa.to_csv(target / "tdoa.csv", index=False, float_format="%.9f")
        quarantine = pd.concat([tables["quarantine"][["file", "line", "text", "reason"]],
                                outlier_rows(tdoa.attrs.get("outliers"), generic.find(run, "ranges").name)],
                               ignore_index=True)
        if len(quarantine):                            # source rows not converted, beside the source's own
            kept = target / QUARANTINE_FILE
            earlier = pd.read_csv(kept) if kept.is_file() else None
            pd.concat([earlier, quarantine], ignore_index=True).to_csv(kept, index=False)
        converted.append(Converted(target, [tuple(row) for row in quarantine.itertuples(index=False)]))
    return converted
