# Static bounds: CRLB / GDOP maps and the anchor-subset search, one job per dataset with a
# noise model in config `bounds.models` (no data needed: campaign geometry only).
from wsnloc.analysis.static_bounds import check_config as _check_bounds, configured_subsets, monte_carlo_scenarios

_check_bounds(config)
BOUND_DATASETS = list((config.get("bounds") or {}).get("models") or {})
SUBSET_MONTE_CARLO = monte_carlo_scenarios(config)


rule static_bounds:
    input:
        campaign=campaign_file,
    output:
        results="data/processed/{dataset}/bounds/results.csv",
        maps="data/processed/{dataset}/bounds/figures/crlb_maps.png",
        ranking="data/processed/{dataset}/bounds/subset_search.csv",
    params:
        subsets=lambda w: configured_subsets(config, w.dataset),
        model=lambda w: config["bounds"]["models"][w.dataset],
        sizes=lambda w: config["bounds"].get("subset_sizes", {}).get(w.dataset, {}),
        grid_m=config.get("bounds", {}).get("grid_m", 0.25),
        shown=config.get("bounds", {}).get("shown", 3),
    priority: PRIORITY["bounds"]
    log:
        "logs/static_bounds/{dataset}.log",
    conda:
        ENV
    script:
        "../scripts/static_bounds.py"


rule subset_monte_carlo:
    input:
        tables=lambda w: tables_of(w.dataset, w.scenario),
        campaign=campaign_file,
    output:
        results="data/processed/{dataset}/{scenario}/bounds/subset_monte_carlo.csv",
    params:
        label="{dataset}/{scenario}",
        model=lambda w: config["bounds"]["models"][w.dataset],
        sizes=lambda w: config["bounds"]["subset_sizes"][w.dataset],
        shown=config.get("bounds", {}).get("shown", 3),
        estimators=config.get("bounds", {}).get("monte_carlo", {}).get("estimators", {}),
    priority: PRIORITY["cell"]
    log:
        "logs/subset_monte_carlo/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/subset_monte_carlo.py"
