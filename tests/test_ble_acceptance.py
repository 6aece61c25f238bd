"""Issue 28's BLE acceptance on the shared philotuxo tracks: `wsnloc estimate --calibration <donor>`
(the donor being the next track, as benchmarks/realdata.py and the real-data study choose it)
has a lower 2-D RMSE than both references (wsnloc.references) on every track; and the donor
RSS model's pieces on hand-made data."""

from pathlib import Path

import numpy as np
import pytest

from wsnloc.estimate import estimate_run
from wsnloc.experiments.realdata import reference_scores
from wsnloc.io.convert import convert_philotuxo
from wsnloc.io.generic import ingest_run, run_campaign
from wsnloc.metrics.ranging import fit_path_loss, fit_path_loss_per_anchor

ROOT = Path(__file__).resolve().parents[1]
BLE = ROOT.parent / "shared" / "realdata" / "philotuxo-ble-rssi"
EKF_REF, CENTROID_REF = "gated EKF, path loss fitted on donor", "weighted centroid (3 strongest, 1 s)"


def test_per_receiver_fit_recovers_offsets_and_exponent_a_common_p0_fit_does_not():
    """Receivers with different gains, the far ones the weak ones: one P0 for all confounds the
    gains with distance and bends n; a P0 per receiver recovers n and the offsets exactly."""
    rng = np.random.default_rng(1)
    gains = {"a": 6.0, "b": 0.0, "c": -6.0}
    near = {"a": (1.0, 5.0), "b": (3.0, 10.0), "c": (8.0, 20.0)}        # each receiver's distance range (m)
    ids = np.repeat(list(gains), 200)
    d = np.concatenate([rng.uniform(*near[a], 200) for a in gains])
    rss = np.array([-60.0 + gains[a] for a in ids]) - 20.0 * np.log10(d)
    fit = fit_path_loss_per_anchor(rss, d, ids)
    assert fit["n"] == pytest.approx(2.0, abs=1e-9) and fit["sigma_dB"] == pytest.approx(0.0, abs=1e-9)
    assert fit["P0_dBm"] == pytest.approx(-60.0) and fit["offsets_dB"]["c"] == pytest.approx(-6.0)
    assert abs(fit_path_loss(rss, d)["n"] - 2.0) > 0.3
    fixed = fit_path_loss_per_anchor(rss, d, ids, exponent=2.5)
    assert fixed["n"] == 2.5 and fixed["sigma_dB"] > 0.5


@pytest.fixture(scope="module")
def ble_runs(tmp_path_factory):
    if not BLE.is_dir():
        pytest.skip(f"{BLE} (the shared BLE tracks) is absent")
    return [run.run_dir for run in convert_philotuxo(BLE, tmp_path_factory.mktemp("philotuxo"))]


def test_calibrated_tracker_beats_both_references_on_every_ble_track(ble_runs, tmp_path):
    failures = []
    for i, run_dir in enumerate(ble_runs):
        donor = ble_runs[(i + 1) % len(ble_runs)]
        ours = estimate_run("generic", run_dir, run_campaign(run_dir), tmp_path / run_dir.name, "tracker", {}, donor)
        refs = reference_scores(run_dir, ingest_run(run_dir)[0], ingest_run(donor)[0], run_campaign(run_dir))
        if not ours["rmse_m"] < min(refs[EKF_REF], refs[CENTROID_REF]):
            failures.append(f"{run_dir.name} (donor {donor.name}): ours {ours['rmse_m']:.3f}, "
                            f"EKF {refs[EKF_REF]:.3f}, centroid {refs[CENTROID_REF]:.3f}")
    assert not failures, failures
