"""Real-data references beside our estimators, per converted run (see wsnloc.references).

`reference_scores(run_dir, tables, donor, campaign)`: {reference name: RMSE (m)} of one
converted generic run, every value scored as our estimators are:
- the dataset's published tracks stored beside the run (cucudasluv: `LS.csv`, `ESKF.csv`),
- on an RSS-only run with a donor (another run of the same site, with truth): the plain gated
  EKF on the log-distance model fitted on the donor, and the weighted centroid of the 3
  strongest receivers per second (which needs no donor).
`published_scores(run_dir)`: the values the dataset itself publishes (reference column only).
"""

from __future__ import annotations

from pathlib import Path

import pandas as pd

from wsnloc import references, results
from wsnloc.campaign import Campaign, generic_site


def reference_scores(run_dir: str | Path, tables: dict[str, pd.DataFrame], donor: dict[str, pd.DataFrame] | None,
                     campaign: Campaign | None) -> dict[str, float]:
    truth = tables["truth"]
    out = {f"{name}.csv": references.rmse_of(track, truth)
           for name, track in references.published_tracks(run_dir).items()}
    if len(tables["rss"]) and not len(tables["ranges"]):
        out["weighted centroid (3 strongest, 1 s)"] = references.rmse_of(
            references.weighted_centroid(tables["rss"], tables["anchors"]), truth)
        if donor is not None:
            site = campaign or generic_site()
            model = references.fit_donor_model(donor["rss"], donor["truth"], donor["anchors"], site)
            out["gated EKF, path loss fitted on donor"] = references.rmse_of(
                references.path_loss_ekf(tables["rss"], tables["anchors"], model, site.tag_height_m), truth)
    return out


def published_scores(run_dir: str | Path) -> dict[str, float]:
    return references.published_values(run_dir)


def reference_rows(study: str, label: str, per_run: dict[str, dict[str, float]],
                   published: dict[str, dict[str, float]]) -> list[dict]:
    """results.csv rows of a scenario's references: the mean RMSE over its runs of each reference
    scored our way (row 'reference: <name>'), and the dataset's published RMSE_2d as paper_value
    of the same reference where it has one (e.g. LS.csv <- 'LS RMSE_2d')."""
    names = list(dict.fromkeys(n for scores in per_run.values() for n in scores))
    rows = []
    for name in names:
        values = [scores.get(name) for scores in per_run.values()]
        key = f"{name.removesuffix('.csv')} RMSE_2d"
        paper = [p[key] for p in published.values() if key in p]
        rows.append(results.row_over_runs(values, experiment=f"study:{study}", table="references",
                                          row=f"reference: {name}", column="rmse", scenario=label, metric="rmse_m",
                                          paper_value=sum(paper) / len(paper) if paper else None))
    return rows


def scenario_reference_rows(study: str, scenarios: list[dict]) -> list[dict]:
    """results.csv reference rows of a study's scenarios, each {label, campaign, runs: [{run,
    raw_dir, tables}]} (the workflow's study_references); a run's donor is the next run of its
    scenario (cyclically), as for the study cells' calibration."""
    from wsnloc.io import tables as canonical

    rows = []
    for scenario in scenarios:
        campaign = Campaign.load(scenario["campaign"])
        runs = scenario["runs"]
        loaded = [{name: canonical.read(Path(r["tables"]) / f"{name}.parquet")
                   for name in ("ranges", "rss", "truth", "anchors")} for r in runs]
        per_run, published = {}, {}
        for i, run in enumerate(runs):
            donor = loaded[(i + 1) % len(runs)] if len(runs) > 1 else None
            per_run[run["run"]] = reference_scores(run["raw_dir"], loaded[i], donor, campaign)
            published[run["run"]] = published_scores(run["raw_dir"])
        rows += reference_rows(study, scenario["label"], per_run, published)
    return rows
