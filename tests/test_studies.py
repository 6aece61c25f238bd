"""Studies: parameter resolution and overrides, validation before jobs, loud failure."""

import numpy as np
import pytest

from synthetic import SQUARE, bursts, tables_for
from wsnloc.errors import ConfigError, WsnlocError
from wsnloc.estimators import registry
from wsnloc.studies import cell_params, run_cell, study_cells, validate_studies

SPEC = {"scenarios": ["site/walk", "site/run"], "estimators": {"tracker": {}, "slow": {"estimator": "ekf",
                                                                                          "accel_sigma_mps2": 0.2}},
        "overrides": {"site": {"max_range_m": 60.0, "accel_sigma_mps2": 0.9},
                      "site/run": {"slow": {"epoch_s": 1.0}}}}


def test_parameters_resolve_from_defaults_entries_and_overrides():
    walk = cell_params(SPEC, "slow", "site", "walk", "studies.s")
    run = cell_params(SPEC, "slow", "site", "run", "studies.s")
    tracker = cell_params(SPEC, "tracker", "site", "walk", "studies.s")
    assert walk["max_range_m"] == 60.0 and walk["epoch_s"] == 0.5 and run["epoch_s"] == 1.0
    assert walk["accel_sigma_mps2"] == 0.9 and tracker["accel_sigma_mps2"] == 0.9    # dataset layer wins
    assert tracker["update"] == "sequential" and walk["update"] == "auto"        # ekf: from the data
    assert study_cells({"studies": {"s": SPEC}})["s"][0] == ("site", "walk", "tracker")


@pytest.mark.parametrize("change, message", [
    (lambda s: s["estimators"].update(bad={"estimator": "ekff"}), "unknown estimator 'ekff'"),
    (lambda s: s["estimators"]["tracker"].update(acel=1), "'studies.s.estimators.tracker.acel': unknown parameter"),
    (lambda s: s["overrides"].update(site={"nope": 1}), "'studies.s.overrides.site.nope': neither"),
    (lambda s: s["overrides"].update(elsewhere={}), "'studies.s.overrides.elsewhere': not a declared"),
    (lambda s: s.update(scenarios=["site/sprint"]), "'studies.s.scenarios': 'site/sprint' is not a declared"),
    (lambda s: s.update(subsets=["UWB=99"]), "'UWB=99' is not a subset"),
])
def test_validation_names_the_key_before_any_job(change, message):
    import copy

    from conftest import NEWCOM

    spec = copy.deepcopy(SPEC)
    change(spec)
    config = {"datasets": {"site": {"campaign": str(NEWCOM), "scenarios": ["walk", "run"]}}, "studies": {"s": spec}}
    with pytest.raises(ConfigError, match=message):
        validate_studies(config)


def test_a_cell_without_estimates_fails_naming_the_cell_and_the_reason():
    times, ids = bursts(20.0, 0.5, {"A1": SQUARE["A1"]})
    runs = {"run-01": tables_for(times, ids, np.array([10.0, 10.0]), SQUARE)}
    p = registry.get("multilateration").resolve({})
    with pytest.raises(WsnlocError, match=r"cell ml \(multilateration\) on site/walk, run-01, subset 'all': no "
                                          r"estimates; 40 usable ranges from 1 anchors"):
        run_cell("site/walk", "ml", "multilateration", p, ["all"], runs, None)


def test_cells_of_a_scenario_share_the_self_fit_passes_and_give_the_estimates_they_give_alone(monkeypatch):
    """run_cells (one job per scenario): the self-fitted EKF, its smoother, the UKF and the
    particle filter fit on the same EKF passes, computed once per run; each cell's estimates
    are exactly those it gives alone."""
    from synthetic import walk

    from wsnloc.estimators import bayes
    from wsnloc.studies import run_cells

    rng = np.random.default_rng(5)
    times = np.sort(rng.uniform(0.0, 60.0, 240))
    ids = rng.choice(np.array(list(SQUARE), dtype=object), len(times))
    runs = {"run-01": tables_for(times, ids, walk, SQUARE, noise_m=0.1, rng=rng)}
    cells = [{"cell": name, "estimator": name, "parameters": registry.get(name).resolve({})}
             for name in ("ekf", "ekf_rts", "ukf", "pf")]
    passes = []
    original = bayes.run_filters
    monkeypatch.setattr(bayes, "run_filters", lambda *a, **k: passes.append(1) or original(*a, **k))
    estimates, _, _ = run_cells("site/walk", cells, ["all"], runs, None)
    shared = len(passes)
    for cell in cells:
        alone, _ = run_cell("site/walk", cell["cell"], cell["estimator"], cell["parameters"], ["all"], runs, None)
        together = estimates[estimates["cell"] == cell["cell"]].reset_index(drop=True)
        np.testing.assert_array_equal(together[["x", "y"]].to_numpy(), alone[["x", "y"]].to_numpy())
    assert shared < 0.5 * (len(passes) - shared), (shared, len(passes) - shared)
