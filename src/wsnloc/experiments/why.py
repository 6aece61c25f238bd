"""Why a paper's claim does not hold (or is inconclusive): the mechanism, with numbers computed
from the same per-run metrics that decided it (claims.json `why`).

Each paper's `explain_*` takes the decided records (experiments.claims.record) and the per-run
metrics of its scenarios (metrics[label], as the claims were decided on) and adds `why` to every
record whose verdict is not "holds". A mechanism names the cause and the numbers that show it
(means over runs of the per-run RMSE, in m, unless stated); where the build has one, a
counterfactual cell or scenario that removes the cause is quoted beside it.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from wsnloc.experiments import claims as claims_of
from wsnloc.metrics import verdicts


def _mean(per_run: pd.DataFrame, metric: str = "rmse", **keys) -> float:
    """Mean over runs of one cell's per-run `metric` (NaN without runs)."""
    values = claims_of.runs_of(per_run, metric, **keys).to_numpy(float)
    values = values[np.isfinite(values)]
    return float(values.mean()) if len(values) else float("nan")


def _attach(records: list[dict], whys: dict[str, str]) -> list[dict]:
    """Set record["why"] from whys[claim] on the records that do not hold; a claim that does not
    hold without a computed mechanism raises (every such claim must carry one)."""
    for rec in records:
        if rec["verdict"] == verdicts.HOLDS:
            continue
        if rec["claim"] not in whys:
            raise KeyError(f"no computed mechanism for the claim {rec['claim']!r} ({rec['verdict']})")
        rec["why"] = whys[rec["claim"]]
    return records


def independent_combination(a: float, b: float) -> float:
    """RMSE of the inverse-variance combination of two independent unbiased estimates with RMSEs
    a and b: (a^-2 + b^-2)^-1/2 = a b / sqrt(a^2 + b^2) -- the best a fusion of the two can do."""
    return a * b / math.hypot(a, b)


def barycentre(a: float, b: float, w: float = 0.5) -> float:
    """RMSE of the weighted barycentre w p_a + (1 - w) p_b of two independent unbiased position
    estimates with RMSEs a and b: sqrt(w^2 a^2 + (1 - w)^2 b^2)."""
    return math.hypot(w * a, (1.0 - w) * b)


# ---- paper A -----------------------------------------------------------------------------------
def explain_a(records: list[dict], metrics: dict[str, pd.DataFrame], rows: list[str], peak_accel: dict[str, float],
              accel_sigma_mps2: dict[str, float]) -> list[dict]:
    """rows: the paper's row labels in order (TOA, TOA, RSS, RSS, hybrid, hybrid); peak_accel: the
    largest acceleration of each scenario's motion (m/s^2, campaign: sim.trajectory.peak_acceleration);
    accel_sigma_mps2: each scenario's PV white-acceleration sigma (m/s^2; per-scenario overrides differ)."""
    toa, rss, hybrid = rows[0], rows[2], rows[4]
    labels = list(metrics)
    whys = {}
    parts = []
    for label in labels:
        t, r, h = (_mean(metrics[label], table="Table I", row=row) for row in (toa, rss, hybrid))
        bound = independent_combination(t, r)
        parts.append(f"{label}: TOA-only {t:.3f}, RSS-only {r:.3f} (TOA {'better' if t < r else 'worse'}); independent "
                     f"unbiased errors combined would give {bound:.3f}, the hybrid measures {h:.3f} "
                     f"({h - bound:+.3f} from that bound)")
    whys["Hybrid beats TOA-only, which beats RSS-only"] = (
        "Each part of the ordering is set by the two sources' errors and by how far the stacked filter gets from "
        "combining them optimally: " + "; ".join(parts) + ". Where the TOA rows are worse than the RSS rows, the UWB "
        "ranges' NLOS errors (positive biases the filter's range noise does not model) exceed the RSS spread; a hybrid "
        "well above the independent-combination bound shows biased, not random, errors in at least one source.")
    moving = []
    for table in ("Table I", "Table II"):
        for row in (toa, rss, hybrid):
            values = [_mean(metrics[label], "rmse_moving", table=table, row=row) for label in labels]
            moving.append(f"{table} {row}: " + " / ".join(f"{v:.3f}" for v in values))
    within = {label: a <= accel_sigma_mps2[label] for label, a in peak_accel.items()}
    whys["Constant speed is tracked better than variable speed"] = (
        f"On the moving epochs ({' / '.join(labels)}) the RMSE is ranging-limited and nearly the same for both "
        f"speed profiles: {'; '.join(moving)}. The profiles' peak accelerations against the PV model's "
        "white-acceleration sigma of each scenario: "
        + ", ".join(f"{label} {a:.2g} {'<=' if within[label] else '>'} {accel_sigma_mps2[label]:.2g} m/s^2"
                    for label, a in peak_accel.items())
        + (" (campaign), so the filter models both profiles." if all(within.values()) else
           " (campaign): where the peak exceeds the sigma, the filter lags on the steepest ramps."))
    detection = []
    for label in labels:
        overall = [_mean(metrics[label], table="Table II", row=row) - _mean(metrics[label], table="Table I", row=row)
                   for row in rows]
        on_moving = [_mean(metrics[label], "rmse_moving", table="Table II", row=row)
                     - _mean(metrics[label], "rmse_moving", table="Table I", row=row) for row in rows]
        detection.append(f"{label}: with - without detection {np.mean(overall):+.3f} overall, "
                         f"{np.mean(on_moving):+.3f} on moving epochs (mean over rows)")
    whys["Motion detection improves every row"] = (
        "Motion detection only skips the prediction at epochs found static; the runs stand still only before the "
        "start and after the end (no stop in between), so the gain is confined to those epochs: "
        + "; ".join(detection) + ". Rows whose error at rest is already small gain nothing measurable.")
    whys["More anchors give a lower RMSE"] = _anchors_a(metrics, rows)
    return _attach(records, whys)


def _anchors_a(metrics: dict[str, pd.DataFrame], rows: list[str]) -> str:
    pairs = []
    for label, per_run in metrics.items():
        for more, fewer in zip(rows[::2], rows[1::2]):
            pairs.append(f"{label} {more} {_mean(per_run, table='Table I', row=more):.3f} vs {fewer} "
                         f"{_mean(per_run, table='Table I', row=fewer):.3f}")
    return ("Dropping anchors matters only where the dropped ones are heard and add geometry: " + "; ".join(pairs) + ".")


# ---- paper B -----------------------------------------------------------------------------------
def explain_b(records: list[dict], metrics: dict[str, pd.DataFrame], bias_calibration_s: dict[str, float],
              accel_bias_sigma_mps2: dict[str, float], imu_rate_hz: float = 5.0) -> list[dict]:
    """bias_calibration_s[label]: the rest (s) the sensor bias was measured over (0: none);
    accel_bias_sigma_mps2[label]: the simulated accelerometer's per-run bias sigma per axis
    (sim.imu.bias_sigma; 0: none, NaN: unknown)."""
    fusion, gains = [], []
    for label, per_run in metrics.items():
        uwb, imu, sskf, kf = (_mean(per_run, method=m) for m in ("uwb", "imu", "sskf", "kf"))
        duration = _mean(per_run, "n", method="imu") / imu_rate_hz
        calibrated, bias = bias_calibration_s.get(label, 0.0), accel_bias_sigma_mps2.get(label, np.nan)
        fusion.append(f"{label}: UWB only {uwb:.2f}, IMU only {imu:.2f} (max {_mean(per_run, 'max', method='imu'):.1f}), "
                      f"fused {sskf:.2f}; bias measured at rest over {calibrated:g} s"
                      + ("" if calibrated or not bias > 0 else
                         f" (none: a {bias:g} m/s^2 turn-on bias (1 sigma per axis, campaign) alone integrates to "
                         f"b T^2 / 2 = {0.5 * bias * duration**2:.0f} m over the {duration:.0f} s run)"))
        gains.append(f"{label}: classical - steady-state {kf - sskf:+.3f}")
    why_fusion = ("Fusion is only as good as the dead reckoning between fixes: where the accelerometer and gyro "
                  "biases are not removed the dead reckoning drifts by tens of metres and the filter, trusting it "
                  "with 5 cm per step, follows the drift away from the Min-Max fixes. " + "; ".join(fusion)
                  + ". Counterfactual: the simulation set-up (additive noise only, no bias) is the same fusion "
                    "without the drift (its rows above).")
    why_classical = ("The classical KF starts from P0 = 0 (the start pose is known), so its gain rises from 0 to the "
                     "steady-state gain over the first fixes: in those steps it trusts the dead reckoning more. "
                     "Where the dead reckoning is good this helps, where it drifts it hurts: " + "; ".join(gains) + ".")
    return _attach(records, {"Fusion beats both UWB only and IMU only": why_fusion,
                             "The classical KF is somewhat better than the steady-state KF": why_classical})


# ---- paper C -----------------------------------------------------------------------------------
def explain_c(records: list[dict], metrics: dict[str, pd.DataFrame], speeds: dict[str, str], subset: str,
              subsets: list[str], table_2: str, corner_radius_m: float, pv_accel_sigma: float) -> list[dict]:
    order, speed_lines = [], []
    for label, per_run in metrics.items():
        values = {m: _mean(per_run, subset=subset, model=m) for m in ("P", "PV", "PVA")}
        v = float(speeds[label].split()[0]) / 100.0
        order.append(f"{speeds[label]}: P {values['P']:.3f}, PV {values['PV']:.3f}, PVA {values['PVA']:.3f}; "
                     f"corner acceleration v^2/r = {v * v / corner_radius_m:.2f} m/s^2")
        moving = {m: _mean(per_run, "rmse_moving", subset=subset, model=m) for m in ("P", "PV", "PVA")}
        speed_lines.append(f"{speeds[label]}: " + ", ".join(f"{m} {x:.3f}" for m, x in moving.items()))
    why_order = (f"The measured acceleration carries the turns that the PV model treats as white noise of "
                 f"{pv_accel_sigma:g} m/s^2: " + "; ".join(order) + ". The PVA input's errors (gravity leaking through "
                 "the tilt, no rest calibration, heading from the first fixes) are absorbed by its bias states and "
                 "stay below the corner accelerations, so with centimetre ranges the input helps instead of hurting.")
    why_speed = ("On moving epochs the error grows from 20 to 40 cm/s but not beyond: with a range every 0.67-1.33 s "
                 "per beacon the cart moves v x 1 s between updates, while the centimetre ranges pin the position "
                 "at each update; RMSE over moving epochs: " + "; ".join(speed_lines) + ".")
    per_run = metrics.get(table_2)
    beacons = []
    if per_run is not None:
        for m in ("P", "PV", "PVA"):
            beacons.append(f"{m}: " + ", ".join(f"{s.split(':')[0]} beacons {_mean(per_run, subset=s, model=m):.3f}"
                                                   for s in subsets))
    why_beacons = ("A beacon adds information only where it is in range and not nearly collinear with the others; "
                   "the gains from 4 to 6 beacons are centimetres, within the runs' spread: " + "; ".join(beacons) + ".")
    return _attach(records, {"P < PV < PVA (Table I, every speed)": why_order,
                             "The error grows with speed (every model)": why_speed,
                             "More beacons give a lower RMSE (Table II, every model)": why_beacons})


# ---- paper D -----------------------------------------------------------------------------------
def explain_d(records: list[dict], metrics: dict[str, pd.DataFrame], pmix_weight: float, k_smallest: int) -> list[dict]:
    fusion, fmix, minmax, kalman, tracked, speed = [], [], [], [], [], []
    for label, per_run in metrics.items():
        for loc, name in (("minmax", "Min-Max"), ("multilateration", "Multilateration")):
            u, n, p, f = (_mean(per_run, localizer=loc, technique=t, stage="raw")
                          for t in ("uwb", "narrowband", "pmix", "fmix"))
            fusion.append(f"{label} {name}: UWB {u:.2f}, narrowband {n:.2f} (ratio {n / u:.1f}), P-mix {p:.2f} "
                          f"(an equal-weight barycentre of independent fixes: {barycentre(u, n, pmix_weight):.2f})")
            fmix.append(f"{label} {name}: F-mix {f:.2f} vs UWB {u:.2f}")
        mm, ml = (_mean(per_run, localizer=loc, technique="uwb", stage="raw") for loc in ("minmax", "multilateration"))
        minmax.append(f"{label} UWB: Min-Max {mm:.2f}, multilateration {ml:.2f}")
        kf, vel = (_mean(per_run, localizer="minmax", technique="fmix", stage=s) for s in ("kalman", "velocity"))
        kalman.append(f"{label}: KF {kf:.3f}, velocity tracker {vel:.3f}")
        if "speed_input_mps" in per_run:          # the KF fed the velocity algorithm's speed
            v_hat, v, bias, spread, without = (
                _mean(per_run, metric, localizer="minmax", technique="fmix", stage="kalman")
                for metric in ("speed_input_mps", "true_speed_mps", "speed_bias_mps", "speed_rmse_mps",
                               "rmse_without_speed_m"))
            speed.append(f"{label}: speed fed {v_hat:.2f} m/s against a true {v:.2f} m/s (bias {bias:+.2f}, RMS error "
                         f"{spread:.2f} m/s); KF {kf:.3f} with it, {without:.3f} without it")
        tracked.append(f"{label}: " + ", ".join(
            f"{loc} {t} {_mean(per_run, localizer=loc, technique=t, stage='velocity'):.2f}"
            for loc in ("minmax", "multilateration") for t in ("uwb", "fmix")))
    why_fusion = ("A barycentre of independent fixes beats the better one only when the two are of similar quality "
                  "(sqrt(w^2 a^2 + (1-w)^2 b^2) < a); the measured P-mix against that figure and the single sources: "
                  + "; ".join(fusion) + ".")
    why_fmix = (f"F-mix keeps the {k_smallest} smallest of all distances, whichever source they come from: an RSS "
                "distance that comes out short (shadowing, a fitted exponent) displaces a UWB range from the selection, "
                "so F-mix inherits the narrowband errors where they are short: " + "; ".join(fmix) + ".")
    why_fmix_tracked = ("The velocity tracker bounds each step but keeps the source's error; with UWB better than "
                        "F-mix the tracked UWB cells stay ahead: " + "; ".join(tracked) + ".")
    why_minmax = ("Min-Max returns the centre of the boxes' intersection, which is biased toward the anchors' "
                  "arrangement (exact only for symmetric geometry); least squares on the circles has no such bias "
                  "with accurate ranges: " + "; ".join(minmax) + ".")
    why_kalman = ("The KF (PV model, fixes as measurements) smooths the Min-Max F-mix fixes over several epochs while "
                  "the velocity tracker only clips outliers to the speed bound; the ranking of the two depends on how "
                  "large and how correlated the fix errors are: " + "; ".join(kalman) + ".")
    if speed:
        why_kalman += (" The KF is also fed the velocity algorithm's speed (seed 004 4.2). That speed (eq. 1) is the "
                       "path length of the last raw fixes over its duration: each step's length adds the fixes' "
                       "noise, so it is biased high whenever the fix errors per epoch exceed the distance moved, "
                       "and the KF, told that speed within speed_sigma_mps, carries it in its velocity state: its "
                       "predictions run ahead of the slower target and each fix pulls them back: " + "; ".join(speed) + " (Min-Max F-mix, mean over runs).")
    return _attach(records, {
        "Fusion beats a single source": why_fusion,
        "F-mix is the best fusion and technique": why_fmix,
        "Velocity tracking lowers the RMSE in every cell": (
            "The speed bound clips a fix only where the fix jumps farther than the window speed allows: "
            + "; ".join(tracked) + "."),
        "F-mix followed by velocity tracking gives the lowest RMSE": why_fmix_tracked,
        "Min-Max is more accurate than multilateration": why_minmax,
        "The Kalman filter is slightly more accurate than the velocity tracker (within 25%)": why_kalman,
        "The Kalman filter is several times costlier per step than the velocity tracker": (
            "The operation counts of one step decide it (see the evidence)."),
    })
