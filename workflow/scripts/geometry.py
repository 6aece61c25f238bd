"""Snakemake adapter: each dataset's floor plan and, where configured, its static CRLB / GDOP
maps and anchor-subset search."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.static_bounds import NoiseModel, floor_maps, path_rows, subset_rows, subset_search
from wsnloc.campaign import Campaign
from wsnloc.io import tables
from wsnloc.report import bound_figures, figures



def static_bounds(dataset: str, campaign: Campaign, settings: dict, out: dict) -> None:
    """CRLB / GDOP maps of the floor for the configured subsets, the bound along the path and
    the ranking of every anchor subset of the configured sizes, written to out's paths."""
    model = NoiseModel(**settings["model"])
    subsets = list(settings["subsets"])
    x, y, panels, anchors = floor_maps(campaign, subsets, model, sm.params.grid_m)
    Path(out["maps"]).write_bytes(bound_figures.bound_maps(campaign, anchors, x, y, panels))
    rows = path_rows(campaign, subsets, model, dataset)
    rankings = []
    for tech, sizes in settings["sizes"].items():
        for k in sizes:
            table, named = subset_search(campaign, tech, k, model)
            rows += subset_rows(table, named, tech, k, dataset, sm.params.shown)
            rankings.append(table.assign(tech=tech, k=k))
            log.info("%s: %d subsets of %d %s anchors; named %s", dataset, len(table), k, tech, named)
    results.write(rows, out["results"])
    ranking = pd.concat(rankings, ignore_index=True) if rankings else pd.DataFrame(
        columns=["members", "mean_bound_m", "rank", "tech", "k"])
    ranking.to_csv(out["ranking"], index=False, float_format="%.6g")


bounded = list(sm.params.bounds)
for i, (dataset, spec) in enumerate(sm.params.datasets.items()):
    campaign = Campaign.load(spec["campaign"])
    first_run = Path(spec["first_run"])
    Path(sm.output.floor_plans[i]).write_bytes(figures.floor_plan(
        campaign, tables.read(first_run / "truth.parquet"), tables.read(first_run / "anchors.parquet")))
    if dataset in bounded:
        k = bounded.index(dataset)
        static_bounds(dataset, campaign, sm.params.bounds[dataset],
                      {name: getattr(sm.output, name)[k] for name in ("maps", "results", "ranking")})
