# Campaign geometry: floor plans, static bounds (CRLB / GDOP maps, anchor-subset search) and the
# opt-in Monte Carlo check of the ranked subsets.
from wsnloc.analysis.static_bounds import check_config as _check_bounds, configured_subsets, monte_carlo_scenarios

_check_bounds(config)
BOUND_DATASETS = list((config.get("bounds") or {}).get("models") or {})
SUBSET_MONTE_CARLO = monte_carlo_scenarios(config)


# One job for every dataset (few datasets, each a second or two of work: one start-up), run
# last beside the summaries: each dataset's floor plan (walls, doors, anchors and the first
# run's true path) and, for the datasets with a noise model in `bounds.models`, the static
# bounds (CRLB / GDOP maps and the anchor-subset search; campaign geometry only, no data).
rule geometry:
    input:
        campaigns=sorted({d["campaign"] for d in config["datasets"].values()}),
        first_runs=[str(Path(first_run_tables(d)).parent) for d in config["datasets"]],   # their shard folders
    output:
        floor_plans=[f"data/processed/{d}/figures/floor_plan.png" for d in config["datasets"]],
        results=[f"data/processed/{d}/bounds/results.csv" for d in BOUND_DATASETS],
        maps=[f"data/processed/{d}/bounds/figures/crlb_maps.png" for d in BOUND_DATASETS],
        ranking=[f"data/processed/{d}/bounds/subset_search.csv" for d in BOUND_DATASETS],
    params:
        datasets={d: {"campaign": spec["campaign"], "first_run": first_run_tables(d)}
                  for d, spec in config["datasets"].items()},
        bounds={d: {"subsets": configured_subsets(config, d), "model": config["bounds"]["models"][d],
                    "sizes": config["bounds"].get("subset_sizes", {}).get(d, {})} for d in BOUND_DATASETS},
        grid_m=config.get("bounds", {}).get("grid_m", 0.25),
        shown=config.get("bounds", {}).get("shown", 3),
    priority: PRIORITY["geometry"]
    log:
        "logs/geometry.log",
    conda:
        ENV
    script:
        "../scripts/geometry.py"


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
    priority: PRIORITY["opt_in"]
    log:
        "logs/subset_monte_carlo/{dataset}-{scenario}.log",
    conda:
        ENV
    script:
        "../scripts/subset_monte_carlo.py"
