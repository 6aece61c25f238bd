"""UWB link budget of the campaign simulator and the ranging validation built on it."""

import numpy as np
import pandas as pd
import pytest
from conftest import ROOT

from wsnloc.io.newcom import ingest_run
from wsnloc.metrics import ranging_validation as rv
from wsnloc.metrics.ranging import range_errors
from wsnloc.sim import link_budget, uwb_channel

C = 299792458.0


@pytest.fixture(scope="module")
def uwb(campaign):
    return campaign.section("radio", "uwb")


def test_noise_floor_and_accumulation_gain_from_first_principles(uwb):
    assert link_budget.thermal_noise_dbm(1.0, 0.0) == pytest.approx(-173.98, abs=0.01)      # kT0 per Hz
    assert link_budget.thermal_noise_dbm(499.2e6, 6.0) == pytest.approx(-173.98 + 86.98 + 6.0, abs=0.01)
    assert link_budget.accumulation_gain_db(499.2e6, 993.6, 1024) == pytest.approx(
        10 * np.log10(499.2e6 * 993.6e-9 * 1024), abs=1e-9)
    expected = -173.98 + 10 * np.log10(499.2e6) + uwb["noise_figure_db"] \
        - 10 * np.log10(499.2e6 * 993.6e-9 * uwb["preamble_symbols"]) + uwb["noise_threshold_db"]
    assert link_budget.first_path_threshold_dbm(uwb) == pytest.approx(expected, abs=0.01)


def test_path_loss_and_received_power_follow_the_channel_models(uwb):
    d = np.array([1.0, 10.0, 10.0])
    nlos = np.array([False, False, True])
    power = link_budget.received_power_dbm(uwb, d, nlos, np.array([0.0, 0.0, 1.0]))
    cm3, cm4 = uwb["channel_models"]["CM3"], uwb["channel_models"]["CM4"]
    base = uwb["tx_power_dbm"] - uwb["antenna_loss_db"]
    assert power[0] == pytest.approx(base - cm3["path_loss_db_at_1m"])
    assert power[1] == pytest.approx(base - cm3["path_loss_db_at_1m"] - 10 * cm3["path_loss_exponent"])
    assert power[2] == pytest.approx(base - cm4["path_loss_db_at_1m"] - 10 * cm4["path_loss_exponent"]
                                     + cm4["shadowing_sigma_db"])
    assert link_budget.path_loss_db(np.array([0.2]), cm3)[0] == cm3["path_loss_db_at_1m"]   # floored at d0


def test_received_power_scales_the_realisation_and_walls_remove_the_direct_path(uwb):
    model = uwb["channel_models"]["CM4"]
    n = 50
    target = np.linspace(1e-9, 1e-7, n)
    link, delays, amplitudes = uwb_channel.impulse_responses(model, np.random.default_rng(4), n, target)
    assert np.bincount(link, np.abs(amplitudes) ** 2, minlength=n) == pytest.approx(target, rel=1e-9)
    plain = uwb_channel.impulse_responses(model, np.random.default_rng(4), n)
    assert np.array_equal(plain[1], delays)                       # the same draws, only scaled
    link, delays, amplitudes = uwb_channel.impulse_responses(model, np.random.default_rng(4), n, target, np.zeros(n))
    first_heard = pd.Series(delays[np.abs(amplitudes) > 0]).groupby(link[np.abs(amplitudes) > 0]).min()
    assert (first_heard > 0).all()                                # the ray at the direct-path delay is gone


def test_detector_needs_the_noise_referenced_threshold():
    powers = np.array([[1.0, 5.0, 100.0, 20.0],
                       [1.0, 5.0, 8.0, 2.0]])
    assert uwb_channel.detect_delay_ns(powers, 1.0, "first_path", 15.0).tolist() == [1.0, 0.0]
    found = uwb_channel.detect_delay_ns(powers, 1.0, "first_path", 15.0, noise_threshold=10.0)
    assert found[0] == 2.0 and np.isnan(found[1])                 # row 2: nothing above the noise threshold
    strongest = uwb_channel.detect_delay_ns(powers, 1.0, "strongest_path", 15.0, noise_threshold=10.0)
    assert strongest[0] == 2.0 and np.isnan(strongest[1])


def _mean_nlos_error(uwb, distance_m, rng, noise=True, n=600):
    power = link_budget.received_power_dbm(uwb, np.full(n, distance_m), np.ones(n, bool), np.zeros(n))
    delay = uwb_channel.detected_delays_ns(
        uwb["channel_models"]["CM4"], rng, n, uwb["cir_tap_ns"], "first_path", uwb["leading_edge_threshold_db"],
        10 ** (power / 10), np.full(n, 10 ** (-uwb["direct_path_wall_loss_db"] / 10)),
        10 ** (link_budget.first_path_threshold_dbm(uwb) / 10) if noise else None)
    return np.nanmean(delay) * C * 1e-9


def test_nlos_first_path_error_grows_with_distance_through_the_noise_threshold(uwb):
    rng = np.random.default_rng(11)
    with_noise = [_mean_nlos_error(uwb, d, rng) for d in (3.0, 6.0, 10.0, 15.0)]
    assert np.all(np.diff(with_noise) > 0) and with_noise[-1] > with_noise[0] + 0.5
    without = [_mean_nlos_error(uwb, d, rng, noise=False) for d in (3.0, 15.0)]
    assert abs(without[1] - without[0]) < 0.2                     # peak-relative only: no distance dependence


def test_simulated_nlos_error_grows_with_distance(campaign, simulated_run):
    tables = ingest_run(simulated_run, campaign)[0]
    errors = rv.link_of_walls(range_errors(tables["ranges"], tables["truth"], campaign)).assign(run="r1")
    stats = rv.per_run(errors).set_index(["link", "from_m"])
    nlos = stats.loc["NLOS", "median_m"]
    assert nlos.loc[2.0] < nlos.loc[5.0] < nlos.loc[10.0]
    assert nlos.loc[10.0] > 1.0                                   # walls cost metres at 10-20 m
    assert stats.loc["LOS", "median_m"].abs().max() < 0.1         # LOS stays unbiased at every distance


def test_links_exist_by_the_budget_not_by_a_fixed_range(campaign, uwb, simulated_run):
    tables = ingest_run(simulated_run, campaign)[0]
    errors = range_errors(tables["ranges"], tables["truth"], campaign)
    nlos = errors[errors["walls"] > 0]
    assert nlos["true_distance_m"].max() > 10.0                   # beyond the old 10 m NLOS rule
    sigma = uwb["channel_models"]["CM4"]["shadowing_sigma_db"]
    d = np.linspace(1, 40, 400)
    mean = link_budget.received_power_dbm(uwb, d, np.ones(len(d), bool), np.zeros(len(d)))
    farthest = d[mean + 4.5 * sigma >= uwb["sensitivity_dbm"]].max()
    assert nlos["true_distance_m"].max() <= farthest              # none closes beyond 4.5 sigma of shadowing


def test_channel_model_reference_and_rows(campaign):
    errors = rv.channel_model_errors(campaign, 300, np.random.default_rng(2))
    stats = rv.per_run(errors).set_index(["link", "from_m"])["median_m"]
    assert stats.loc["NLOS"].iloc[-1] > stats.loc["NLOS"].iloc[0] + 0.3     # 10-20 m against 0-2 m
    assert stats.loc["LOS"].abs().max() < 0.1
    rows = pd.DataFrame(rv.single_rows(errors, rv.EXPERIMENT, "IEEE 802.15.4a model"))
    assert set(rows["column"]) == {*rv.STATS.values(), rv.COUNT_COLUMN} and rows["row"].str.match(r"^(LOS|NLOS) \d").all()
    counts = rows[rows["column"] == rv.COUNT_COLUMN]
    assert counts["value"].sum() == rv.per_run(errors)["n"].sum() and (counts["metric"] == "count").all()
    figure = rv.curves(rows.assign(table=rv.TABLE))
    assert set(figure) == set(rv.STATS.values())
    assert list(figure["median error"]) == ["IEEE 802.15.4a model LOS", "IEEE 802.15.4a model NLOS"]


def test_rows_are_means_over_runs_by_bin():
    errors = pd.DataFrame({"run": ["a"] * 10 + ["b"] * 10, "link": "NLOS",
                           "true_distance_m": [3.0] * 20, "error_m": [1.0] * 10 + [3.0] * 10})
    rows = pd.DataFrame(rv.rows(errors, "data", "x/y"))
    median = rows[rows["column"] == "median error"].iloc[0]
    assert median["row"] == "NLOS 2-5 m" and median["value"] == pytest.approx(2.0) and median["runs"] == 2
    assert rows[rows["column"] == rv.COUNT_COLUMN]["value"].tolist() == [20]     # the ranges of both runs
    few = errors.iloc[:3]
    assert rv.rows(few, "data", "x/y") == []                      # fewer than MIN_SAMPLES ranges


REAL = ROOT.parent / "shared" / "realdata" / "cucudasluv-uwb"


@pytest.mark.skipif(not REAL.is_dir(), reason=f"real dataset not present at {REAL} (../shared missing)")
def test_real_runs_give_rows_per_case_class_and_bin():
    errors = rv.real_errors(str(REAL), str(ROOT / "config" / "campaigns" / "cucudasluv.yaml"))
    assert set(errors["link"]) == {"LOS", "NLOS"} and errors["run"].nunique() == 6
    assert errors["error_m"].abs().median() < 0.3             # RTK truth, 3-D distances: a real UWB's centimetres
    rows = pd.DataFrame(rv.rows(errors[errors["link"] == "LOS"], rv.EXPERIMENT, "cucudasluv/los"))
    assert rows["runs"].max() == 3 and (rows["row"].str.startswith("LOS ")).all()


def test_a_resting_cart_keeps_each_links_impulse_response(campaign, uwb, simulated_run):
    """Spatial consistency: while the cart rests (first 5 s) every anchor's range error changes by
    the timing noise only (its leading edge, NLOS bias included, is the same), not by the metres a
    new impulse response per ranging would give an NLOS link."""
    tables = ingest_run(simulated_run, campaign)[0]
    errors = range_errors(tables["ranges"], tables["truth"], campaign)
    rest = errors[errors["t"] < errors["t"].min() + 4.0]
    spread = rest.groupby("anchor_id")["error_m"].std()
    assert len(spread) >= 8 and spread.max() < 4 * uwb["timing_noise_ns"] * 1e-9 * C
    assert (rest.groupby("anchor_id")["error_m"].mean() > 0.5).any()      # a constant NLOS bias among them


def test_pl0_sensitivity_counts_rounds_links_and_anchors_from_the_logs(campaign, simulated_run):
    """round_links has one row per (ranging round, UWB anchor); its valid links are the log's
    status-0 ranges; a higher CM4 path loss at 1 m closes fewer NLOS links and no fewer LOS ones,
    and nothing changes where no PL0 is replaced."""
    from wsnloc.analysis import pl0_sensitivity as pl0
    from wsnloc.analysis.simulated_runs import simulate_tables
    from wsnloc.sim import newcom

    tables, _ = ingest_run(simulated_run, campaign)
    links = pl0.round_links(tables, campaign)
    n_anchors = len(campaign.anchors_of("uwb"))
    assert len(links) == links["round"].nunique() * n_anchors
    duration = tables["truth"]["t"].iloc[-1] - tables["truth"]["t"].iloc[0]
    assert links["round"].nunique() == len(newcom.ranging_rounds_ms(campaign.section("radio", "uwb"), n_anchors,
                                                                     duration))      # the simulator's rounds
    assert links["valid"].sum() == (tables["ranges"]["status"] == 0).sum()
    assert links["linked"].sum() == len(tables["ranges"]) and (links["linked"] >= links["valid"]).all()
    summary = pl0.run_summary(tables, campaign)
    assert summary["anchors_per_epoch"] == pytest.approx(links["valid"].sum() / links["round"].nunique())
    assert pl0.variant_campaign(campaign, None, None).spec == campaign.spec
    harsh = pl0.variant_campaign(campaign, None, 57.9)
    assert harsh.section("radio", "uwb", "channel_models", "CM4", "path_loss_db_at_1m") == 57.9
    assert harsh.section("radio", "uwb", "channel_models", "CM3") == campaign.section("radio", "uwb", "channel_models", "CM3")
    base, alt = (pl0.run_summary(simulate_tables(c, "constant", 1, 7)["run-01"], c) for c in (campaign, harsh))
    assert alt["link_share_nlos"] < base["link_share_nlos"] and alt["link_share_los"] == base["link_share_los"]
    bins = pl0.nlos_bins({"r": tables}, campaign)
    assert bins["link_share"].between(0, 1).all() and (bins["median_m"].dropna() > 0).all()   # NLOS: late, not early
