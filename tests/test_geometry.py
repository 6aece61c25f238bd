"""Wall-crossing geometry and the rail path, against hand-computed cases."""

import numpy as np
import pytest

from wsnloc.geometry.path import Path
from wsnloc.geometry import walls
from wsnloc.geometry.walls import count_crossings, wall_pieces

WALL = [{"from": [0, 6], "to": [10, 6], "doors": [[2.5, 3.5]]}]


def test_doors_split_walls_into_pieces():
    pieces = wall_pieces(WALL)
    np.testing.assert_allclose(pieces, [[0, 6, 2.5, 6], [3.5, 6, 10, 6]])


@pytest.mark.parametrize("point, anchor, expected", [
    ((3.0, 8.0), (3.0, 3.0), 0),     # straight through the door
    ((5.0, 8.0), (5.0, 3.0), 1),     # through the solid wall
    ((1.0, 8.0), (1.0, 7.0), 0),     # both on the same side
    ((11.0, 8.0), (11.0, 3.0), 0),   # beyond the wall's end
    ((2.5, 8.0), (2.5, 3.0), 0),     # grazing the door jamb end point is not a crossing
])
def test_single_wall_crossings(point, anchor, expected):
    assert count_crossings(np.array([point]), np.array(anchor), wall_pieces(WALL))[0] == expected


def test_campaign_links_cross_the_expected_walls(campaign):
    # From the corridor at (15, 7.5) to U07 in room S1: corridor wall, then partition x = 6.
    assert campaign.walls_between(np.array([[15.0, 7.5]]), campaign.anchor_position("U07"))[0] == 2
    # From the rail start to U07, the link passes through the door at x in [2.5, 3.5].
    assert campaign.walls_between(np.array([[2.5, 7.5]]), campaign.anchor_position("U07"))[0] == 0
    # Corridor anchors along the corridor are in LOS.
    assert campaign.walls_between(np.array([[10.0, 7.5]]), campaign.anchor_position("U04"))[0] == 0


def test_wall_counts_equal_the_full_count(campaign):
    """Points in and beside the rooms, on wall lines and at door edges, repeated (the cart at
    rest) and NaN, against anchors inside, outside and on wall lines, with the campaign's walls and
    with two diagonal ones added: the same integers as every piece tested at every point."""
    rng = np.random.default_rng(5)
    grid = np.array([(x, y) for x in (0.0, 2.5, 6.0, 8.5, 12.0, 22.5, 30.0) for y in (0.0, 6.0, 7.5, 9.0, 15.0)])
    moving = np.column_stack([rng.uniform(-1.0, 31.0, 600), rng.uniform(-1.0, 16.0, 600)])
    distinct = np.concatenate([grid, moving, [[np.nan, 7.5]]])
    points = np.repeat(distinct, rng.integers(1, 4, len(distinct)), axis=0)
    anchors = np.concatenate([campaign.anchors[["x", "y"]].to_numpy(float), grid[::3], [[15.0, 9.0], [-2.0, 7.0]]])
    diagonal = wall_pieces([{"from": [4.0, 1.0], "to": [20.0, 13.0], "doors": [[5.0, 6.0]]},
                            {"from": [26.0, 2.0], "to": [12.0, 9.0]}])
    for pieces in (campaign.walls, np.concatenate([campaign.walls, diagonal])):   # axis-aligned, then mixed
        for subset in (points, points[:40], points[points[:, 1] > 7.0], points[-40:], points[:1]):   # pruned; one point
            for anchor in anchors:
                got = count_crossings(subset, anchor, pieces)
                expected = walls._crossings(np.atleast_2d(subset), anchor, pieces)
                assert got.dtype == expected.dtype and np.array_equal(got, expected)


def test_rail_length_and_shape(campaign):
    """Seed 004 §4: "a robot moving along a corridor on a 25 m rail": straight, inside the corridor."""
    path = campaign.path
    assert path.length == pytest.approx(25.0)
    pose = path.evaluate(np.linspace(0.0, path.length, 50))
    assert np.all((pose["y"] > 6.0) & (pose["y"] < 9.0))          # corridor between the walls y = 6 and 9
    assert np.all(pose["curvature"] == 0.0)
    assert path.start_pose() == pytest.approx((2.5, 7.5, 0.0))


def test_sharp_corner_path_has_polyline_length():
    path = Path([[1, 1], [5, 1], [5, 3], [1, 3], [1, 1]])
    assert path.length == pytest.approx(12.0)
    p = path.evaluate([4.0, 5.0, 12.0])
    np.testing.assert_allclose(np.column_stack([p["x"], p["y"]]), [[5, 1], [5, 2], [1, 1]])


def test_path_rejects_repeated_points():
    with pytest.raises(ValueError, match="repeated"):
        Path([[0, 0], [0, 0], [1, 0]])
