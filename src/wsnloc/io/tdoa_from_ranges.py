"""TDOA made from two-way ranges: `wsnloc convert tdoa SRC OUT`.

Range differences to one reference anchor, d(anchor) - d(ref), from the ranges of a generic
run. Ranges of different anchors are asynchronous (a round of two-way ranging visits the
anchors one after the other, and an anchor may be missed), so they are paired in time: at
each range of the reference anchor (time t_ref) every other anchor's range is interpolated
linearly between its two samples bracketing t_ref, when both lie within `window_s` of t_ref
(an anchor sampled exactly at t_ref is used as is); otherwise that pair is left out of the
group. The pairs of one reference range share its time and its noise, as TDOA pairs of one
transmission share the reference's arrival (the TDOA model's correlated noise). The
reference anchor is the one with the most ranges (ties: the first id in sorted order) unless
one is given. Ranges with a non-zero status or not finite are not used.

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
from wsnloc.io import generic
from wsnloc.io.convert import QUARANTINE_FILE, Converted

WINDOW_S = 0.25      # pairing window: a bracketing sample at most this far from t_ref (s); ~2.5 rounds at 10 Hz


def reference_anchor(ranges: pd.DataFrame) -> str:
    """The anchor with the most ranges (ties: the first id in sorted order)."""
    counts = ranges["anchor_id"].value_counts()
    return sorted(counts.index[counts == counts.max()])[0]


def ranges_to_tdoa(ranges: pd.DataFrame, reference: str | None = None, window_s: float = WINDOW_S) -> pd.DataFrame:
    """Range differences (t, anchor_id, ref_anchor_id, tdoa_m) from ranges (t, anchor_id, range_m
    [, status]) (module docstring), sorted by t then anchor."""
    ok = np.isfinite(ranges["range_m"]) & np.isfinite(ranges["t"])
    if "status" in ranges:
        ok &= ranges["status"].fillna(0) == 0
    ranges = ranges[ok]
    if not len(ranges):
        return pd.DataFrame(columns=["t", "anchor_id", "ref_anchor_id", "tdoa_m"])
    reference = reference or reference_anchor(ranges)
    ref = ranges[ranges["anchor_id"] == reference].sort_values("t", kind="stable")
    t_ref, r_ref = ref["t"].to_numpy(float), ref["range_m"].to_numpy(float)
    out = []
    for anchor, rows in ranges[ranges["anchor_id"] != reference].groupby("anchor_id", sort=True):
        rows = rows.sort_values("t", kind="stable")
        t, r = rows["t"].to_numpy(float), rows["range_m"].to_numpy(float)
        after = np.searchsorted(t, t_ref, side="left")            # first sample at or after t_ref
        before = np.clip(after - 1, 0, len(t) - 1)
        after_c = np.clip(after, 0, len(t) - 1)
        exact = (after < len(t)) & (t[after_c] == t_ref)
        bracketed = (after > 0) & (after < len(t)) & (t_ref - t[before] <= window_s) & (t[after_c] - t_ref <= window_s)
        with np.errstate(invalid="ignore", divide="ignore"):
            share = np.where(t[after_c] > t[before], (t_ref - t[before]) / (t[after_c] - t[before]), 0.0)
        value = np.where(exact, r[after_c], r[before] + share * (r[after_c] - r[before]))
        use = exact | bracketed
        out.append(pd.DataFrame({"t": t_ref[use], "anchor_id": anchor, "ref_anchor_id": reference,
                                 "tdoa_m": value[use] - r_ref[use]}))
    frame = pd.concat(out, ignore_index=True) if out else pd.DataFrame(columns=["t", "anchor_id", "ref_anchor_id",
                                                                              "tdoa_m"])
    return frame.sort_values(["t", "anchor_id"], kind="stable").reset_index(drop=True)


def _run_dirs(src: Path) -> list[Path]:
    if generic.find(src, "ranges") is not None:
        return [src]
    runs = sorted({p.parent for suffix in ("csv", "parquet") for p in src.rglob(f"ranges.{suffix}")})
    if not runs:
        raise IngestError(f"{src}: no generic run (a directory with ranges.csv or ranges.parquet) below it")
    return runs


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
        quarantine = tables["quarantine"][["file", "line", "text", "reason"]]
        if len(quarantine):                            # source rows not converted, beside the source's own
            kept = target / QUARANTINE_FILE
            earlier = pd.read_csv(kept) if kept.is_file() else None
            pd.concat([earlier, quarantine], ignore_index=True).to_csv(kept, index=False)
        converted.append(Converted(target, [tuple(row) for row in quarantine.itertuples(index=False)]))
    return converted
