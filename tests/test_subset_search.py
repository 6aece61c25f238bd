"""Anchor-subset search: agreement with a brute-force loop, geometry sense (spread beats
collinear, singular ranks last), the papers' subsets, and the cost at N = 21, k = 17."""

import time
from itertools import combinations
from math import comb

import numpy as np
import pytest

from wsnloc.metrics import bounds, subset_search

ANCHORS = np.array([[0.0, 0.0], [4.0, 0.0], [8.0, 0.0], [8.0, 6.0], [0.0, 6.0], [4.0, 3.5]])
IDS = ["A", "B", "C", "D", "E", "F"]


def test_memberships_enumerate_all_subsets():
    m = subset_search.memberships(6, 3)
    assert m.shape == (20, 6) and set(m.sum(axis=1)) == {3}
    assert len({tuple(row) for row in m}) == 20


def test_scores_match_brute_force_loop():
    points = np.column_stack([np.linspace(1, 7, 40), 1.5 + np.sin(np.linspace(0, 3, 40))])
    sigma = np.array([0.1, 0.2, 0.1, 0.3, 0.15, 0.1])
    terms = bounds.toa_information_terms(points, ANCHORS, sigma)
    table = subset_search.rank_subsets(terms, IDS, 3)
    for members in combinations(range(6), 3):
        index = list(members)
        expected = bounds.toa_crlb(points, ANCHORS[index], sigma[index]).mean()
        key = ",".join(IDS[i] for i in index)
        assert table.loc[table["members"] == key, "mean_bound_m"].item() == pytest.approx(expected, rel=1e-12)
    assert table["mean_bound_m"].is_monotonic_increasing
    assert list(table["rank"]) == sorted(table["rank"]) and table["rank"].iloc[0] == 1


def test_spread_subset_beats_collinear_and_singular_ranks_last():
    # path along y = 0 through the collinear anchors A, B, C: their FIM is singular there
    points = np.column_stack([np.linspace(0.5, 7.5, 30), np.zeros(30)])
    table = subset_search.rank_subsets(bounds.toa_information_terms(points, ANCHORS, 0.1), IDS, 3)
    spread = subset_search.rank_of(table, ["E", "C", "A"], IDS)
    collinear = subset_search.rank_of(table, ["A", "B", "C"], IDS)
    assert spread < collinear == table["rank"].max()
    assert np.isinf(table.loc[table["members"] == "A,B,C", "mean_bound_m"].item())
    # over the whole room the collinear subset is finite but ranks below the corner triples,
    # which share a rank by symmetry
    _, _, room = bounds.grid_points(8.0, 6.0, 0.5)
    table = subset_search.rank_subsets(bounds.toa_information_terms(room, ANCHORS, 0.1), IDS, 3)
    assert np.all(np.isfinite(table["mean_bound_m"]))
    corners = [subset_search.rank_of(table, m, IDS) for m in ("ACD", "ACE", "ADE", "CDE")]
    assert len(set(corners)) == 1 and corners[0] < subset_search.rank_of(table, "ABC", IDS)
    with pytest.raises(ValueError, match="not among"):
        subset_search.rank_of(table, ["A", "B", "Z"], IDS)


def test_symmetric_subsets_share_a_rank():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    centre = np.array([[0.5, 0.5]])
    table = subset_search.rank_subsets(bounds.toa_information_terms(centre, square, 0.1), "ABCD", 3)
    assert set(table["rank"]) == {1}


def test_zigbee_17_of_21_is_fast(campaign):
    """All 5985 subsets over 400 path points; prints the paper subsets' ranks."""
    zigbee = campaign.anchors_of("zigbee")
    pose = campaign.path.evaluate(np.linspace(0, campaign.path.length, 400))
    points = np.column_stack([pose["x"], pose["y"]])
    terms = bounds.rss_information_terms(points, zigbee[["x", "y"]].to_numpy(), 3.0, 4.0)
    start = time.perf_counter()
    table = subset_search.rank_subsets(terms, zigbee["anchor_id"], 17)
    elapsed = time.perf_counter() - start
    assert len(table) == comb(21, 17) == 5985
    rank = subset_search.rank_of(table, campaign.spec["subsets"]["ZigBee=17"], zigbee["anchor_id"])
    print(f"ZigBee 17 of 21 over 400 points: {elapsed:.3f} s; paper subset rank {rank} of 5985, "
          f"bound {table['mean_bound_m'].iloc[rank - 1]:.3f} m (best {table['mean_bound_m'].iloc[0]:.3f} m)")
    assert elapsed < 1.0
