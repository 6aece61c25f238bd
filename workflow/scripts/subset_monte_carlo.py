"""Snakemake adapter: the configured, best and worst anchor subsets of each search through a
registry estimator on every run of one scenario (opt-in, config bounds.monte_carlo)."""

from wsnloc.workflow import start_job

sm = snakemake  # noqa: F821  (given by Snakemake: the rule's input, output, params, wildcards, log)
log = start_job(sm)  # from here on, errors and their tracebacks go to the rule's log

from wsnloc import results
from wsnloc.analysis.static_bounds import NoiseModel, monte_carlo_rows
from wsnloc.campaign import Campaign
from wsnloc.metrics.data_quality import load_runs

campaign = Campaign.load(sm.input.campaign)
runs = load_runs(sm.input.tables, ("ranges", "rss", "truth", "anchors"))
model = NoiseModel(**sm.params.model)
rows = []
for tech, sizes in sm.params.sizes.items():
    if tech not in sm.params.estimators:
        log.info("%s: no estimator in bounds.monte_carlo.estimators, not run", tech)
        continue
    for k in sizes:
        searched, failures = monte_carlo_rows(campaign, runs, sm.params.label, sm.wildcards.dataset, tech, k, model,
                                              sm.params.shown, sm.params.estimators[tech])
        rows += searched
        log.info("%s, %d anchors: %d subsets on %d runs", tech, k, len(searched), len(runs))
        for failure in failures:
            log.warning("no RMSE: %s", failure)
results.write(rows, sm.output.results)
