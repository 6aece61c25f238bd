"""The data summary's measurement geometry (metrics.ranging: range_errors, rss_with_distance)
and per-anchor counts (metrics.data_quality._per_anchor_counts) equal the former
implementations, kept here as references, on runs with walls, 3-D anchors and gaps."""

import numpy as np
import pandas as pd
import pytest

from synthetic import tables_for, walk
from wsnloc.campaign import Campaign
from wsnloc.metrics.data_quality import _per_anchor_counts
from wsnloc.metrics.ranging import range_errors, rss_with_distance, truth_at

ANCHORS = {"A1": (0.0, 0.0), "A2": (20.0, 0.0), "A3": (20.0, 20.0), "A4": (0.0, 20.0), "A5": (10.0, 10.0)}
HEIGHTS = {"A1": 2.5, "A2": 2.4, "A3": None, "A4": 2.6, "A5": None}      # None: no height (2-D link)
WALLS = [{"from": [10.0, -1.0], "to": [10.0, 21.0], "doors": [[4.0, 5.0]]},
         {"from": [-1.0, 12.0], "to": [21.0, 12.0]}]


def reference_with_geometry(frame, truth, campaign, anchors=None):
    """The former metrics.ranging._with_geometry (one groupby over the anchors, pandas columns)."""
    frame = frame.copy()
    position = truth_at(truth, frame["t"].to_numpy())
    frame["true_x"], frame["true_y"] = position[:, 0], position[:, 1]
    frame = frame[np.isfinite(frame["true_x"])]
    anchors = campaign.anchors if anchors is None else anchors
    heights = anchors["z"] if "z" in anchors else np.full(len(anchors), np.nan)
    position_of = {a: (np.array([x, y], dtype=float), float(z))
                   for a, x, y, z in zip(anchors["anchor_id"], anchors["x"], anchors["y"], heights)}
    tag_height = campaign.tag_height_m
    points = frame[["true_x", "true_y"]].to_numpy()
    distance = np.full(len(frame), np.nan)
    walls = np.full(len(frame), -1)
    for anchor_id, rows in frame.groupby("anchor_id").indices.items():
        a, z = position_of[anchor_id]
        dz = z - tag_height if tag_height is not None and np.isfinite(z) else 0.0
        pts = points[rows]
        distance[rows] = np.sqrt((pts[:, 0] - a[0]) ** 2 + (pts[:, 1] - a[1]) ** 2 + dz**2)
        walls[rows] = campaign.walls_between(pts, a)
    frame["true_distance_m"] = distance
    frame["walls"] = walls
    frame["los"] = frame["walls"] == 0
    return frame


def reference_per_anchor_counts(runs):
    """The former data_quality._per_anchor_counts (three groupby sizes per run)."""
    frames = []
    for run, data in runs.items():
        r = data["ranges"]
        counts = pd.DataFrame({
            "ranges_valid": r[r["status"] == 0].groupby("anchor_id").size(),
            "ranges_flagged": r[r["status"] != 0].groupby("anchor_id").size(),
            "rss": data["rss"].groupby("anchor_id").size(),
        })
        anchors = data["anchors"].set_index("anchor_id")
        counts = counts.reindex(anchors.index).fillna(0).assign(tech=anchors["tech"], run=run)
        frames.append(counts.reset_index())
    all_runs = pd.concat(frames)
    mean = all_runs.groupby(["anchor_id", "tech"], sort=False)[["ranges_valid", "ranges_flagged", "rss"]].mean()
    return mean.round(1).reset_index()


def campaign(tag_height_m=None) -> Campaign:
    anchors = [{"id": a, "tech": "uwb" if a < "A4" else "zigbee", "x": x, "y": y,
                **({"z": HEIGHTS[a]} if HEIGHTS[a] is not None else {})} for a, (x, y) in ANCHORS.items()]
    spec = {"anchors": anchors, "walls": WALLS, **({"tag_height_m": tag_height_m} if tag_height_m else {})}
    return Campaign(name="site", format="generic", spec=spec, source="site.yaml")


def run_tables(seed: int, site: Campaign) -> dict[str, pd.DataFrame]:
    """A walk with ranges in random anchor order (a few flagged, some before the truth starts
    or after it ends) and RSS of every anchor, string-typed ids as the Parquet tables have."""
    rng = np.random.default_rng(seed)
    times = np.sort(rng.uniform(-3.0, 130.0, 900))
    ids = rng.choice(list(ANCHORS), len(times))
    tables = tables_for(times, ids, walk, ANCHORS, noise_m=0.05, rng=rng, rss_times=np.arange(0.0, 125.0, 0.7))
    tables["truth"] = tables["truth"][tables["truth"]["t"].between(0.0, 120.0)].reset_index(drop=True)
    tables["ranges"]["status"] = np.where(rng.random(len(times)) < 0.1, 2, 0).astype(np.int32)
    tables["anchors"] = site.anchors.copy()
    for name in ("ranges", "rss", "anchors"):
        tables[name] = tables[name].astype({"anchor_id": "string"})
    return tables


@pytest.mark.parametrize("tag_height_m", [None, 1.2])
def test_range_errors_and_rss_geometry_equal_the_former_implementation(tag_height_m):
    site = campaign(tag_height_m)
    tables = run_tables(7, site)
    valid = tables["ranges"][tables["ranges"]["status"] == 0]
    expected = reference_with_geometry(valid, tables["truth"], site, tables["anchors"])
    expected["error_m"] = expected["range_m"] - expected["true_distance_m"]
    errors = range_errors(tables["ranges"], tables["truth"], site, tables["anchors"])
    pd.testing.assert_frame_equal(errors, expected, check_exact=True)
    assert errors["los"].any() and not errors["los"].all()          # the walls are crossed by some links
    assert len(errors) < len(valid)                                  # ranges outside the truth span left out
    rss = rss_with_distance(tables["rss"], tables["truth"], site)    # the campaign's anchors
    pd.testing.assert_frame_equal(rss, reference_with_geometry(tables["rss"], tables["truth"], site),
                                  check_exact=True)


def test_geometry_of_no_rows_and_of_an_unknown_anchor():
    site = campaign()
    tables = run_tables(8, site)
    empty = rss_with_distance(tables["rss"].iloc[:0], tables["truth"], site)
    pd.testing.assert_frame_equal(empty, reference_with_geometry(tables["rss"].iloc[:0], tables["truth"], site),
                                  check_exact=True)
    stranger = tables["rss"].assign(anchor_id=tables["rss"]["anchor_id"].replace("A2", "X9"))
    with pytest.raises(KeyError):
        rss_with_distance(stranger, tables["truth"], site)


def test_per_anchor_counts_equal_the_former_implementation():
    site = campaign()
    runs = {f"run-{k}": run_tables(10 + k, site) for k in range(3)}
    runs["run-1"]["rss"] = runs["run-1"]["rss"][runs["run-1"]["rss"]["anchor_id"] != "A3"]   # an anchor unheard
    runs["run-2"]["anchors"] = runs["run-2"]["anchors"].iloc[1:]                              # an anchor not listed
    counts = _per_anchor_counts(runs)
    pd.testing.assert_frame_equal(counts, reference_per_anchor_counts(runs), check_exact=True)
    assert counts.set_index("anchor_id").loc["A3", "rss"] == pytest.approx(
        np.mean([(runs[r]["rss"]["anchor_id"] == "A3").sum() for r in ("run-0", "run-1", "run-2")]), abs=0.05)
