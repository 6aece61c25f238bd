"""Static bounds of the configured anchor subsets (analysis.static_bounds): subset expressions,
the maps, the path rows and the subset search on the default campaigns."""

import numpy as np
import pytest
import yaml

from wsnloc.analysis.static_bounds import (NoiseModel, check_config, configured_subsets, crlb, distinct, floor_maps,
                                           members, path_points, picked_subsets, subset_rows, subset_search,
                                           with_subsets)
from wsnloc.errors import ConfigError
from wsnloc.metrics.bounds import toa_crlb

NEWCOM = NoiseModel(0.3, 3.0, 5.5)


@pytest.fixture(scope="module")
def config():
    return yaml.safe_load(open("config/config.yaml"))


def test_configured_subsets_are_the_papers_and_studies_ones(config):
    assert configured_subsets(config, "newcom") == ["UWB=12", "UWB=9", "ZigBee=21", "ZigBee=17", "UWB=12+ZigBee=21",
                                                    "UWB=9+ZigBee=17", "all"]
    assert configured_subsets(config, "cricket") == ["3: B1,B3,B4", "4: B1,B3,B4,B6", "6: B1..B6", "all"]


def test_expressions_split_by_technology_and_duplicates_are_dropped(newcom, cricket):
    toa, rss = members(newcom, "UWB=9+ZigBee=17")
    assert len(toa) == 9 and len(rss) == 17 and all(a.startswith("U") for a in toa)
    assert distinct(cricket, ["6: B1..B6", "3: B1,B3,B4", "all"]) == ["6: B1..B6", "3: B1,B3,B4"]
    with pytest.raises(ConfigError, match="'UWB=7' is not defined"):
        members(newcom, "UWB=7")


def test_hybrid_bound_is_below_both_single_technology_bounds(newcom):
    points = path_points(newcom)
    _, toa = crlb(newcom, "UWB=9", NEWCOM, points)
    _, rss = crlb(newcom, "ZigBee=17", NEWCOM, points)
    kind, hybrid = crlb(newcom, "UWB=9+ZigBee=17", NEWCOM, points)
    assert kind == "hybrid" and np.all(hybrid < toa) and np.all(hybrid < rss)


def test_maps_give_gdop_for_ranges_and_crlb_for_rss(cricket, newcom):
    x, y, panels, anchors = floor_maps(cricket, ["3: B1,B3,B4", "all"], NoiseModel(0.05), 0.5)
    (title, values), = [(t, v) for t, v in panels.items() if t.startswith("3:")]
    assert "GDOP" in title and values.shape == (len(y), len(x)) and len(anchors[title]) == 3
    xx, yy = np.meshgrid(x, y)
    xy = cricket.anchors.set_index("anchor_id").loc[["B1", "B3", "B4"], ["x", "y"]].to_numpy(float)
    np.testing.assert_allclose(values * 0.05, toa_crlb(np.column_stack([xx.ravel(), yy.ravel()]), xy, 0.05)
                               .reshape(values.shape))
    _, _, panels, _ = floor_maps(newcom, ["ZigBee=17"], NEWCOM, 1.0)
    assert list(panels) == ["ZigBee=17: RSS CRLB [m] (RSS n 3, sigma 5.5 dB)"]
    with pytest.raises(ConfigError, match="path_loss_exponent and sigma_db"):
        floor_maps(newcom, ["ZigBee=17"], NoiseModel(0.3), 1.0)


@pytest.mark.parametrize("campaign, tech, k, name, rank, count", [
    ("newcom", "uwb", 9, "UWB=9", 168, 220), ("newcom", "zigbee", 17, "ZigBee=17", 3006, 5985),   # straight 25 m rail
    ("cricket", "cricket", 3, "3: B1,B3,B4", 16, 20), ("cricket", "cricket", 4, "4: B1,B3,B4,B6", 5, 15),
])
def test_papers_subsets_rank_as_documented(request, campaign, tech, k, name, rank, count):
    """docs/bounds.md: ranks of the papers' subsets for the default models."""
    model = NoiseModel(0.1, 3.0, 4.0)    # the models of docs/bounds.md (UWB and Cricket sigma 0.1 m; n 3, 4 dB)
    table, named = subset_search(request.getfixturevalue(campaign), tech, k, model)
    assert len(table) == count and list(named) == [name]
    rows = subset_rows(table, named, tech, k, campaign, shown=2)
    ranks = {r["row"]: r["value"] for r in rows if r["column"] == "rank"}
    assert ranks[name] == rank and ranks[f"best 1: {table['members'][0]}"] == 1
    assert max(ranks.values()) == table["rank"].max()


def test_bounds_config_names_declared_datasets(config):
    check_config(config)
    with pytest.raises(ConfigError, match="'bounds.models.nosuch': not a declared dataset"):
        check_config(dict(config, bounds={"models": {"nosuch": {"range_sigma_m": 0.1}}}))
    with pytest.raises(ConfigError, match="'bounds.subset_sizes.cricket': needs 'bounds.models.cricket'"):
        check_config(dict(config, bounds={"subset_sizes": {"cricket": {"cricket": [3]}}}))


def test_picked_subsets_become_campaign_subsets(cricket):
    table, named = subset_search(cricket, "cricket", 3, NoiseModel(0.05))
    picks = picked_subsets(table, named, 2)
    assert list(picks)[0] == "3: B1,B3,B4" and len(picks) == 5
    assert picks["worst 1: " + table["members"].iloc[-1]] == table["members"].iloc[-1]
    extended = with_subsets(cricket, picks)
    assert members(extended, "best 1: " + table["members"][0])[0] == table["members"][0].split(",")
    assert "best 1: " + table["members"][0] not in cricket.spec["subsets"]     # the campaign itself is unchanged
