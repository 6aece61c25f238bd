"""Choices resolved from the run's data when the user left them at their default.

`measurements_for`: an estimator reads ranges by default (`measurements: toa`, `fixes: toa`);
a run without usable ranges is estimated on what it has instead of giving no estimate: its
range differences (`measurements: tdoa`, a TDOA run) where the estimator accepts them, else
its RSS (e.g. a BLE RSSI campaign). Runs that have ranges keep them (RSS needs a path-loss
model that ranges do not; TDOA gives less of the geometry than the ranges it may be made of).
Applied by `wsnloc estimate` to parameters not given with --set.
`motion_for`: a filter with the default constant-velocity model (`motion: pv`, 2-D) on a run
with an odometry table uses it (`motion: odometry`, the unicycle model it drives).
`dimensions_for`: an estimator with a `dimensions` parameter left at 2 tracks in 3-D where the
run's campaign declares a height profile of the tag's path (a 3-D scenario: Campaign.for_scenario)
that varies by VARYING_HEIGHT_M or more.

`update_mode`: the Bayesian filters' `update: auto` (their default, bayes.run_filters) is
`epoch` on synchronous rounds and `sequential` on asynchronous measurements.
`fix_window_epochs`: per-epoch fixes (estimators.fixes) read the latest value of each anchor
over the last FIX_WINDOW_S seconds when most epochs hear fewer than 3 anchors.
"""

from __future__ import annotations

import numpy as np

from wsnloc.errors import ConfigError
from wsnloc.estimators.run_data import RunData

CHOICE_KEYS = ("measurements", "fixes")      # parameters naming the measurement kind an estimator reads


def measurements_for(data: RunData, p: dict, explicit: set[str], choices: dict | None = None) -> dict:
    """The parameters with the measurement kind switched where the run has no usable range and
    the key was not set explicitly: to 'tdoa' where the run has range differences and the key
    accepts it (`choices`: the estimator's {parameter: its choices}), else to 'rss' where the
    run has RSS and the key accepts it; the others unchanged. ConfigError where the run has
    only RSS and no free key accepts it (an estimator that reads ranges only, e.g. sliding_window)."""
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
    accepting = [k for k in free if choices is None or "rss" in (choices.get(k) or ())]
    if free and not accepting:
        reads = ", ".join(k + " " + " / ".join(choices[k]) for k in free)
        raise ConfigError(f"the run has RSS and no usable range or range difference; this estimator reads {reads} "
                          "only (`wsnloc estimators` lists the ones that read RSS)")
    return dict(p, **{k: "rss" for k in accepting})


SYNCHRONOUS_SHARE = 0.5     # bursts in at least this share of the epochs with measurements: synchronous


def update_mode(t: np.ndarray, anchor: np.ndarray, times: np.ndarray, period: float) -> tuple[str, str]:
    """The update mode the ranges at times t (s, sorted) to `anchor` call for, and why.
    RSS does not decide it (bayes.resolve_update passes the ranges only; a filter on RSS alone
    keeps `epoch`): the RSS samples of one receiver within a period are mostly fast fading,
    correlated from sample to sample, so each is not an independent measurement; their mean in
    dB per epoch is the ML estimate of the local mean power (estimators.epochs) and one
    update with it does not let a burst of fading samples drag the filter along the steep
    log-distance curve near a receiver.

    An epoch (t_k - period, t_k] of the grid `times` is a **burst** when its measurements share
    one time stamp and come from at least two anchors: a synchronous round, which the epoch
    update (one update with the per-anchor means, output at t_k) uses as the sequential one
    would. When bursts make up at least SYNCHRONOUS_SHARE of the epochs that hold measurements
    the data are synchronous: `epoch` (the papers' filters; the array EKF steps many runs at
    once). Otherwise (ranges one anchor at a time, or each anchor at its own time stamp) an
    epoch update would treat measurements up to one period old as taken at t_k and average
    away all but one per anchor: `sequential` (each measurement at its own time)."""
    if len(t) == 0 or len(times) == 0:
        return "epoch", "no ranges"
    epoch = np.searchsorted(times, t, side="left")
    inside = epoch < len(times)
    epoch, t, anchor = epoch[inside], t[inside], np.asarray(anchor, dtype=object)[inside]
    starts = np.flatnonzero(np.r_[True, epoch[1:] != epoch[:-1]])
    ends = np.r_[starts[1:], len(epoch)]
    one_stamp = np.array([t[a] == t[b - 1] for a, b in zip(starts, ends)])
    anchors = np.array([len(set(anchor[a:b])) for a, b in zip(starts, ends)])
    bursts = float(np.mean(one_stamp & (anchors >= 2))) if len(starts) else 0.0
    if bursts >= SYNCHRONOUS_SHARE:
        return "epoch", f"synchronous: {bursts:.0%} of the epochs are single-time-stamp rounds of >= 2 anchors"
    single = float(np.mean(anchors == 1))
    return "sequential", (f"asynchronous: {bursts:.0%} of the epochs are single-time-stamp rounds "
                          f"({single:.0%} hold a single anchor)")


FIX_WINDOW_S = 4.0          # s: as the tracker's initiator (multilateration over the last 4 s)
FIX_ANCHORS = 3             # a 2-D fix needs three anchors


def fix_window_epochs(anchors_per_epoch: np.ndarray, period: float) -> int:
    """Epochs a per-epoch fix reads: 1 when at least half of the epochs with measurements hear
    FIX_ANCHORS anchors or more (synchronous rounds: the papers' solvers, unchanged), else the
    epochs of FIX_WINDOW_S (ranges one anchor at a time: a fix from the latest range of each
    anchor over the window, up to FIX_WINDOW_S old, instead of none in most epochs)."""
    heard = anchors_per_epoch[anchors_per_epoch > 0]
    if len(heard) == 0 or np.mean(heard >= FIX_ANCHORS) >= 0.5:
        return 1
    return max(1, int(np.ceil(FIX_WINDOW_S / period - 1e-9)))


def motion_for(run_tables: dict, p: dict, explicit: set[str]) -> dict:
    """The parameters with `motion: odometry` where the run has odometry rows, the estimator's
    motion is the default pv in 2-D and neither key was set explicitly; else p unchanged."""
    odometry = run_tables.get("odometry")
    if odometry is None or not len(odometry) or p.get("motion") != "pv" or p.get("dimensions", 2) != 2 \
            or explicit & {"motion", "dimensions"}:
        return p
    return dict(p, motion="odometry")


VARYING_HEIGHT_M = 0.5      # m: a declared tag height that varies by less is a plane (the fixed-height 2-D model)


def dimensions_for(campaign, p: dict, explicit: set[str]) -> dict:
    """The parameters with `dimensions: 3` where the estimator has the key at 2, it was not set
    explicitly, its motion model has a 3-D state (motion.THREE_D; e.g. not pva or odometry) and the
    campaign's path declares tag heights varying by VARYING_HEIGHT_M or more (the set-up, never the
    truth); else p unchanged."""
    from wsnloc.estimators.motion import THREE_D

    heights = getattr(getattr(campaign, "path", None), "heights", None)
    if p.get("dimensions") != 2 or "dimensions" in explicit or p.get("motion", "pv") not in THREE_D \
            or heights is None or np.ptp(heights[:, 1]) < VARYING_HEIGHT_M:
        return p
    return dict(p, dimensions=3)
