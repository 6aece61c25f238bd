"""Posterior CRB of a registry Bayesian filter along a run's true trajectory.

The bound is for the filter's own model (its motion model, measurement models, noise
sigmas and update schedule) with the measurement availability of the run: the anchors that
gave a measurement in each epoch (epoch updates: one per anchor and epoch, as the filter
averages them) or in each group of records sharing a time stamp (sequential updates), read
from the same `MeasurementSource` the filter uses. Steps are the filter's update times
(and, sequentially, the output epoch ends, where the information is zero):

    J_0 = P0^-1 + H_0^T R^-1 H_0,   J_j = (Q(dt_j) + F(dt_j) J_{j-1}^-1 F(dt_j)^T)^-1 + H_j^T R^-1 H_j

(metrics.bounds.pcrb), dt_j = s_j - s_{j-1}; F = I, Q = 0 where motion detection declares
the step's epoch static (the filter skips its predict step there). The first step is the
initiator's: the filter starts there from a fix of that step's measurements with covariance P0
(without an update), so the bound's prior is J_0 = P0^-1 plus that step's information (a bound
ignoring it would be above the filter's error when P0 is wider than the fix's error). H_j is evaluated at the true position (truth
interpolated at s_j); range and RSS models observe the position only, so the true velocity
is not needed (the per-anchor Fisher terms of metrics.bounds: 3-D ranges with the anchors'
height offsets as RangeModel, RSS by the log-distance model as RssModel; TDOA by the
filter's own TdoaModel of each update, H^T R^-1 H with the correlated noise of pairs sharing
an anchor, metrics.bounds.model_information).
A coasting-limit reset of the filter does not restart the bound (it keeps its information).
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc.estimators import bayes
from wsnloc.estimators.epochs import sorted_codes
from wsnloc.estimators.motion import MotionModel
from wsnloc.estimators.run_data import RunData
from wsnloc.metrics.bounds import (available_information, model_information, pcrb, rss_information_terms,
                                   to_matrices, toa_information_terms)
from wsnloc.metrics.ranging import truth_at

BOUND_COLUMNS = ["t", "pcrb_xx", "pcrb_xy", "pcrb_yy"]
MEASUREMENT_TEXT = {"toa": "ranges", "rss": "RSS", "hybrid": "ranges + RSS", "tdoa": "range differences"}


def is_bayesian(function) -> bool:
    """Whether a registry estimator's function is the Bayesian filter loop (it has a PCRB)."""
    return function is bayes.run_filter


def _counts(step_of: np.ndarray, anchors: np.ndarray, n_steps: int) -> tuple[list[str], np.ndarray]:
    """(the distinct anchors, sorted; (steps, anchors) number of measurements of each at each step)."""
    ids, column = sorted_codes(np.asarray(anchors, dtype=object))
    counts = np.bincount(np.asarray(step_of, dtype=np.intp) * len(ids) + column, minlength=n_steps * len(ids))
    return ids.tolist(), counts.reshape(n_steps, len(ids)).astype(float)


def _measurement_steps(source, times: np.ndarray, p: dict):
    """(step times, step index of each range, its anchor, same for RSS, output index of times);
    epoch updates: one step per epoch and each anchor's epoch mean (MeasurementSource.epoch_means)."""
    if p["update"] == "epoch":
        ranges, rss = source.epoch_means(times, p["epoch_s"])
        return (times, ranges.epoch, source.anchor_ids(0)[ranges.code], rss.epoch, source.anchor_ids(1)[rss.code],
                np.arange(len(times)))
    records = source.records()
    steps = np.union1d(records.t, times)
    record_step = np.searchsorted(steps, records.t)
    ranges, rss = records.kind == 0, records.kind == 1
    return (steps, record_step[ranges], records.anchor[ranges], record_step[rss], records.anchor[rss],
            np.searchsorted(steps, times))


def _transitions(motion: MotionModel, steps: np.ndarray, static_of_step: np.ndarray):
    """F, Q (len(steps) - 1, n, n) of the steps s_{j-1} -> s_j; identity and zero where static.
    The matrices are built once per distinct step length."""
    lengths, which = np.unique(np.diff(steps), return_inverse=True)
    built = [motion.matrices(float(dt))[:2] for dt in lengths]
    F = np.array([f for f, _ in built]).reshape(-1, motion.dim, motion.dim)[which]
    Q = np.array([q for _, q in built]).reshape(-1, motion.dim, motion.dim)[which]
    static = static_of_step[1:]
    F[static], Q[static] = np.eye(motion.dim), 0.0
    return F, Q


def _pcrb_inputs(data: RunData, p: dict):
    """(epoch end times, output step index of each, P0, F, Q, information (steps, n, n)) of the
    bound of a filter with resolved parameters p on one run; None without epochs."""
    p = bayes.resolve_update(data, p)
    source = bayes.measurement_source(data, p)
    times = data.grid(p["epoch_s"], p["preliminary_filter"], p["max_range_m"])
    if len(times) == 0:
        return None
    if p["measurements"] == "tdoa":
        steps, information, outputs = _tdoa_information(data, source, times, p)
        return _with_motion(data, p, times, outputs, steps, information)
    steps, range_step, range_ids, rss_step, rss_ids, outputs = _measurement_steps(source, times, p)
    position = _truth_at(data, steps)
    information = np.zeros((len(steps), 3))
    (toa_ids, toa_counts), (rss_members, rss_counts) = (_counts(range_step, range_ids, len(steps)),
                                                        _counts(rss_step, rss_ids, len(steps)))
    if toa_ids:
        dz = data.height_offsets(toa_ids) if data.three_d else None
        terms = toa_information_terms(position, data.positions(toa_ids), p["range_sigma_m"], dz)
        information += available_information(terms, toa_counts)
    if rss_members:
        rss = source.rss_params
        terms = rss_information_terms(position, data.positions(rss_members), rss.path_loss_exponent, rss.sigma_db)
        information += available_information(terms, rss_counts)
    information[~np.isfinite(position).all(axis=1)] = 0.0  # outside the truth span: unknown geometry
    return _with_motion(data, p, times, outputs, steps, information)


def _tdoa_information(data: RunData, source, times: np.ndarray, p: dict):
    """(steps, position information (steps, 3), output index of times) of a TDOA filter: the
    TdoaModel of each update (epoch means or record groups) evaluated at the true position."""
    if p["update"] == "epoch":
        steps, outputs = times, np.arange(len(times))
        models, step_of = source.epoch_models(times, p["epoch_s"]), np.arange(len(times))
    else:
        records = source.records()
        bounds = records.groups()
        steps = np.union1d(records.t, times)
        outputs = np.searchsorted(steps, times)
        models = source.group_models            # the filters' own models of the record groups (built once per source)
        step_of = np.searchsorted(steps, records.t[bounds[:-1]])
    position = _truth_at(data, steps)
    information = np.zeros((len(steps), 3))
    for k, model in zip(step_of, models):
        if model is not None and np.all(np.isfinite(position[k])):
            J = model_information(model, position[k][None])[0]
            information[k] += (J[0, 0], J[0, 1], J[1, 1])
    return steps, information, outputs


def _truth_at(data: RunData, steps: np.ndarray) -> np.ndarray:
    """The run's true position at the bound's steps (metrics.ranging.truth_at), once per run and
    steps (the cells of a run on one epoch grid share it)."""
    return data.cached(("truth_at", steps.tobytes()), lambda: truth_at(data.require("truth", "the PCRB"), steps))


def _with_motion(data: RunData, p: dict, times, outputs, steps, information):
    """The bound's inputs (see _pcrb_inputs) from its steps and their position information."""
    motion = bayes.motion_model(p)
    static = bayes.static_flags(data, p, times)[np.minimum(np.searchsorted(times, steps), len(times) - 1)]
    F, Q = _transitions(motion, steps, static)
    return times, outputs, motion.initial_covariance(), F, Q, to_matrices(information, motion.dim)


def filter_pcrbs(cells: list[tuple[RunData, dict]]) -> list[pd.DataFrame]:
    """filter_pcrb of every (run, resolved parameters) cell; cells with the same state
    dimension run through one batched recursion (metrics.bounds.pcrb over a leading cell
    axis), their step sequences padded at the end with F = I, Q = 0 and no information
    (padded steps come after a cell's last output and do not change it)."""
    inputs = [_pcrb_inputs(data, p) for data, p in cells]
    out = [pd.DataFrame(columns=BOUND_COLUMNS, dtype=float)] * len(cells)
    by_dim: dict[int, list[int]] = {}
    for i, item in enumerate(inputs):
        if item is not None:
            by_dim.setdefault(item[2].shape[0], []).append(i)
    for n, members in by_dim.items():
        K = max(len(inputs[i][5]) for i in members)
        F = np.broadcast_to(np.eye(n), (len(members), max(K - 1, 0), n, n)).copy()
        Q = np.zeros_like(F)
        information = np.zeros((len(members), K, n, n))
        P0 = np.empty((len(members), n, n))
        for j, i in enumerate(members):
            _, _, P0[j], F_i, Q_i, info_i = inputs[i]
            F[j, :len(F_i)], Q[j, :len(Q_i)], information[j, :len(info_i)] = F_i, Q_i, info_i
        bounds = pcrb(P0, F, Q, information)
        for j, i in enumerate(members):
            times, outputs = inputs[i][:2]
            bound = bounds[j, outputs]
            out[i] = pd.DataFrame({"t": times, "pcrb_xx": bound[:, 0, 0], "pcrb_xy": bound[:, 0, 1],
                                   "pcrb_yy": bound[:, 1, 1]})
    return out


def filter_pcrb(data: RunData, p: dict) -> pd.DataFrame:
    """PCRB position block (m^2) of a Bayesian filter with resolved registry parameters p
    (bayes.run_filter's) at every epoch end of the run's grid: columns BOUND_COLUMNS."""
    return filter_pcrbs([(data, p)])[0]


def bound_model(p: dict) -> str:
    """The model a filter's PCRB assumes, in words (printed beside the bound)."""
    motion = {"p": f"P random walk {p['p_sigma_m']:g} m per {p['epoch_s']:g} s",
              "pv": f"PV, white acceleration {p['accel_sigma_mps2']:g} m/s^2",
              "pva": f"PVA, acceleration input noise {p['accel_sigma_mps2']:g} m/s^2, "
                     f"bias walk {p['bias_walk_sigma']:g} m/s^2/sqrt(s)"}[p["motion"]]
    noise = []
    if p["measurements"] in ("toa", "hybrid"):
        noise.append(f"Gaussian ranges sigma {p['range_sigma_m']:g} m")
    if p["measurements"] in ("rss", "hybrid"):
        noise.append("log-normal RSS (the filter's path-loss model)")
    if p["measurements"] == "tdoa":
        noise.append(f"range differences, arrival noise sigma {p['range_sigma_m']:g} m per anchor")
    update = {"epoch": "epoch updates", "sequential": "sequential updates"}.get(
        p["update"], "updates by epoch or sequential as the data call for (auto)")
    detection = ", static epochs frozen" if p["motion_detection"] else ""
    return f"{motion}; {', '.join(noise)}; anchors {p['anchors']}; {update} every {p['epoch_s']:g} s{detection}"
