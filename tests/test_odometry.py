"""Odometry: the generic odometry table (ingest, quarantine), the unicycle motion model it drives,
`wsnloc estimate` choosing it, and the acceptance check: odometry lowers the error of a
one-range-at-a-time run with 20 s gaps."""

from __future__ import annotations

import json

import numpy as np
import pandas as pd
import pytest

from synthetic import SQUARE, one_at_a_time, run_data
from wsnloc.cli import main
from wsnloc.estimators import registry
from wsnloc.filters.motion_models import unicycle
from wsnloc.io import tables as canonical
from wsnloc.io.generic import ingest_run
from wsnloc.metrics.tracking import run_metrics, score

SPEED_MPS, TURN_RPS = 0.8, 0.2        # a figure eight of 4 m loops in the middle of SQUARE
GAPS = ((40.0, 60.0), (100.0, 120.0), (160.0, 180.0))     # 20 s without any range
DURATION_S = 200.0


def yaw_rate(t: np.ndarray) -> np.ndarray:
    """Left loops, then right loops, alternating every full circle (2 pi / TURN_RPS s)."""
    loop = 2 * np.pi / TURN_RPS
    return np.where(np.floor(np.asarray(t) / loop) % 2 == 0, TURN_RPS, -TURN_RPS)


def drive(step_s: float = 0.01) -> pd.DataFrame:
    """The true unicycle path (t, x, y, heading) from (10, 6) heading east, integrated finely."""
    t = np.arange(0.0, DURATION_S + step_s, step_s)
    heading = np.concatenate([[0.0], np.cumsum(yaw_rate(t[:-1]) * step_s)])
    x = 10.0 + np.concatenate([[0.0], np.cumsum(SPEED_MPS * np.cos(heading[:-1]) * step_s)])
    y = 6.0 + np.concatenate([[0.0], np.cumsum(SPEED_MPS * np.sin(heading[:-1]) * step_s)])
    return pd.DataFrame({"t": t, "x": x, "y": y, "heading": heading})


def gap_run(seed: int = 4, with_odometry: bool = True):
    """Ranges one anchor at a time (2 Hz Poisson, N(0, 0.1^2) m) with the 20 s GAPS, truth at 20 Hz
    and 10 Hz odometry with a 3 % speed scale error and noise (0.05 m/s, 0.02 rad/s)."""
    rng = np.random.default_rng(seed)
    path = drive()
    times, ids = one_at_a_time(DURATION_S, 2.0, rng, SQUARE)
    for a, b in GAPS:
        keep = (times < a) | (times > b)
        times, ids = times[keep], ids[keep]
    position = np.column_stack([np.interp(times, path["t"], path[c]) for c in ("x", "y")])
    anchors = np.array([SQUARE[a] for a in ids])
    ranges = pd.DataFrame({"t": times, "anchor_id": ids,
                           "range_m": np.hypot(*(position - anchors).T) + rng.normal(0, 0.1, len(times)),
                           "status": np.int32(0), "line": np.arange(1, len(times) + 1, dtype=np.int32)})
    truth = path.iloc[::5][["t", "x", "y"]].assign(s=0.0, line=np.int32(1)).reset_index(drop=True)
    t_odo = np.arange(0.05, DURATION_S, 0.1)
    odometry = pd.DataFrame({"t": t_odo, "v_mps": SPEED_MPS * 1.03 + rng.normal(0, 0.05, len(t_odo)),
                             "yaw_rate_rps": yaw_rate(t_odo) + rng.normal(0, 0.02, len(t_odo)),
                             "line": np.arange(2, len(t_odo) + 2, dtype=np.int32)})
    tables = {"ranges": ranges, "rss": canonical.empty("rss"),
              "truth": truth, "anchors": pd.DataFrame({"anchor_id": list(SQUARE), "tech": "uwb",
                                                       "x": [v[0] for v in SQUARE.values()],
                                                       "y": [v[1] for v in SQUARE.values()], "z": np.nan})}
    if with_odometry:
        tables["odometry"] = odometry
    return tables


# ---- the model -----------------------------------------------------------------------------------
def test_unicycle_transition_matches_the_integrated_path():
    """F(v, w, dt) [x, y, cos, sin] equals a fine Euler integration of the unicycle, and tends to
    the straight step as w -> 0."""
    x0 = np.array([1.0, 2.0, np.cos(0.7), np.sin(0.7)])
    for w in (0.3, -1.1, 0.0, 1e-12):
        F, Q = unicycle(2.0, 0.9, w, 0.1, 0.05)
        steps, p, heading = 200000, x0[:2].copy(), 0.7
        for _ in range(steps):
            p += 0.9 * np.array([np.cos(heading), np.sin(heading)]) * 2.0 / steps
            heading += w * 2.0 / steps
        np.testing.assert_allclose(F @ x0, [*p, np.cos(heading), np.sin(heading)], atol=1e-5)
        np.testing.assert_allclose(np.diag(Q), [0.04, 0.04, 0.01, 0.01])


# ---- ingest ------------------------------------------------------------------------------------
def test_generic_odometry_and_3d_truth_are_ingested_with_quarantine(tmp_path):
    (tmp_path / "anchors.csv").write_text("anchor_id,tech,x,y,z\nA1,uwb,0,0,1\nA2,uwb,9,0,2\nA3,uwb,0,9,3\n")
    (tmp_path / "ranges.csv").write_text("t,anchor_id,range_m\n0.0,A1,5.0\n")
    (tmp_path / "truth.csv").write_text("t,x,y,z\n0,3,4,1.5\n1,6,8,\n2,6,8,inf\n")
    (tmp_path / "odometry.csv").write_text("t,v_mps,yaw_rate_rps\n0.1,0.5,0.01\n0.0,-0.2,0\n0.2,abc,0\n0.3,0.4\n")
    result, inventory = ingest_run(tmp_path)
    odometry = result["odometry"]
    assert odometry[["t", "v_mps", "line"]].values.tolist() == [[0.0, -0.2, 3], [0.1, 0.5, 2]]
    reasons = result["quarantine"].set_index(["file", "line"])["reason"].to_dict()
    assert reasons[("odometry.csv", 4)] == "v_mps 'abc' is not a finite number"
    assert ("odometry.csv", 5) in reasons and reasons[("truth.csv", 4)] == "z 'inf' is not a finite number"
    assert inventory["odometry.csv"]["quarantined"] == 2 and inventory["odometry.csv"]["reordered"] == 1
    assert result["truth"]["z"].tolist()[0] == 1.5 and np.isnan(result["truth"]["z"].iloc[1])


# ---- acceptance ----------------------------------------------------------------------------------
@pytest.mark.parametrize("name", ["tracker", "ekf"])
def test_odometry_lowers_the_error_of_a_one_range_at_a_time_run_with_20_s_gaps(name):
    """Acceptance (issue 31): the recommended tracker (sequential PV EKF; and the epoch-mode EKF)
    and the same filter with the odometry motion model on one run, both coasting through the gaps
    (max_coast_s 30, every estimate output: max_position_sigma_m 0): the odometry track's RMSE over the whole run and inside the gaps is lower by
    a computed margin (printed)."""
    tables = gap_run()
    truth = tables["truth"]
    results = {}
    for motion in ("pv", "odometry"):
        est = registry.run(name, run_data(tables), {"motion": motion, "max_coast_s": 30.0, "max_position_sigma_m": 0.0})
        scored = score(est, truth)
        inside = np.any([(scored["t"] > a) & (scored["t"] <= b) for a, b in GAPS], axis=0)
        results[motion] = (run_metrics(scored, truth), float(np.sqrt(np.mean(scored["error_m"][inside] ** 2))))
    (pv, pv_gaps), (odo, odo_gaps) = results["pv"], results["odometry"]
    print(f"{name}, one range at a time, 20 s gaps: RMSE {pv['rmse']:.2f} m (PV) -> {odo['rmse']:.2f} m (odometry), "
          f"inside the gaps {pv_gaps:.2f} m -> {odo_gaps:.2f} m")
    assert odo["availability"] >= max(pv["availability"], 0.9)
    assert odo["rmse"] <= 0.5 * pv["rmse"]
    assert odo_gaps <= 0.5 * pv_gaps


def test_without_odometry_table_the_odometry_model_is_refused_clearly():
    with pytest.raises(Exception, match="odometry"):
        registry.run("tracker", run_data(gap_run(with_odometry=False)), {"motion": "odometry"})


def test_estimate_uses_the_runs_odometry(tmp_path):
    tables = gap_run()
    run = tmp_path / "run"
    run.mkdir()
    tables["ranges"][["t", "anchor_id", "range_m"]].to_csv(run / "ranges.csv", index=False, float_format="%.6f")
    tables["truth"][["t", "x", "y"]].to_csv(run / "truth.csv", index=False, float_format="%.6f")
    tables["anchors"][["anchor_id", "tech", "x", "y"]].to_csv(run / "anchors.csv", index=False)
    tables["odometry"][["t", "v_mps", "yaw_rate_rps"]].to_csv(run / "odometry.csv", index=False, float_format="%.6f")
    metrics = {}
    for name, extra in (("odometry", []), ("pv", ["--set", "motion=pv"])):
        out = tmp_path / name
        assert main(["estimate", "--format", "generic", str(run), "--out", str(out), "--set", "max_coast_s=30"]
                    + extra) == 0
        metrics[name] = json.loads((out / "metrics.json").read_text())
    assert metrics["odometry"]["rmse_m"] < 0.5 * metrics["pv"]["rmse_m"]
