"""Snakemake adapter: static CRLB / GDOP maps of one dataset's floor and its anchor-subset search."""

from pathlib import Path

import pandas as pd

from wsnloc import results
from wsnloc.analysis.static_bounds import NoiseModel, floor_maps, path_rows, subset_rows, subset_search
from wsnloc.campaign import Campaign
from wsnloc.report import bound_figures
from wsnloc.workflow import end_job, script_logger

sm = snakemake  # noqa: F821  (injected by Snakemake)
log = script_logger(sm.log[0], "static_bounds")
dataset = sm.wildcards.dataset
campaign = Campaign.load(sm.input.campaign)
model = NoiseModel(**sm.params.model)
subsets = list(sm.params.subsets)
x, y, panels, anchors = floor_maps(campaign, subsets, model, sm.params.grid_m)
Path(sm.output.maps).write_bytes(bound_figures.bound_maps(campaign, anchors, x, y, panels))
rows = path_rows(campaign, subsets, model, dataset)
rankings = []
for tech, sizes in sm.params.sizes.items():
    for k in sizes:
        table, named = subset_search(campaign, tech, k, model)
        rows += subset_rows(table, named, tech, k, dataset, sm.params.shown)
        rankings.append(table.assign(tech=tech, k=k))
        log.info("%s: %d subsets of %d %s anchors; named %s", dataset, len(table), k, tech, named)
results.write(rows, sm.output.results)
ranking = pd.concat(rankings, ignore_index=True) if rankings else pd.DataFrame(
    columns=["members", "mean_bound_m", "rank", "tech", "k"])
ranking.to_csv(sm.output.ranking, index=False, float_format="%.6g")
end_job()
