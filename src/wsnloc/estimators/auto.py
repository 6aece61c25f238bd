"""Choices resolved from the run's data when the user left them at their default.

`measurements_for`: an estimator reads ranges by default (`measurements: toa`, `fixes: toa`);
a run without usable ranges is estimated on what it has instead of giving no estimate: its
range differences (`measurements: tdoa`, a TDOA run) where the estimator accepts them, else
its RSS (e.g. a BLE RSSI campaign). Runs that have ranges keep them (RSS needs a path-loss
model that ranges do not; TDOA gives less of the geometry than the ranges it may be made of).
Applied by `wsnloc estimate` to parameters not given with --set.
`motion_for`: a filter with the default constant-velocity model (`motion: pv`, 2-D) on a run
with an odometry table uses it (`motion: odometry`, the unicycle model it drives).
"""

from __future__ import annotations

from wsnloc.estimators.run_data import RunData

CHOICE_KEYS = ("measurements", "fixes")      # parameters naming the measurement kind an estimator reads


def measurements_for(data: RunData, p: dict, explicit: set[str], choices: dict | None = None) -> dict:
    """The parameters with the measurement kind switched where the run has no usable range and
    the key was not set explicitly: to 'tdoa' where the run has range differences and the key
    accepts it (`choices`: the estimator's {parameter: its choices}), else to 'rss' where the
    run has RSS; the others unchanged."""
    ranges = data.usable_ranges(p.get("preliminary_filter", True), p.get("max_range_m", float("inf")))
    if len(ranges):
        return p
    free = [k for k in CHOICE_KEYS if p.get(k) == "toa" and k not in explicit]
    if len(data.usable_tdoa()):
        accepting = [k for k in free if "tdoa" in ((choices or {}).get(k) or ())]
        if accepting:
            return dict(p, **{k: "tdoa" for k in accepting})
    if not len(data.usable_rss()):
        return p
    return dict(p, **{k: "rss" for k in free})


def motion_for(run_tables: dict, p: dict, explicit: set[str]) -> dict:
    """The parameters with `motion: odometry` where the run has odometry rows, the estimator's
    motion is the default pv in 2-D and neither key was set explicitly; else p unchanged."""
    odometry = run_tables.get("odometry")
    if odometry is None or not len(odometry) or p.get("motion") != "pv" or p.get("dimensions", 2) != 2 \
            or explicit & {"motion", "dimensions"}:
        return p
    return dict(p, motion="odometry")
