"""Paper A's Table II gain (motion detection) against the share of time the target stands still.

Motion detection can only help while the target is static. For each length of the final
rest (`static_end_s` of the scenario, in s) runs 1..`runs` of `scenario` are simulated
with that rest (analysis.simulated_runs: paired across rests), and paper A's first
hybrid row is estimated without (Table I) and with (Table II) motion detection (RSS
model as configured in experiments.paper_a: calibrated on another run of the same rest).
Per run: the static share of the epochs (analysis.setup_facts) and the gain
  gain = RMSE(Table II) - RMSE(Table I)   (m; negative: motion detection helps).
"""

from __future__ import annotations

import pandas as pd

from wsnloc.analysis.setup_facts import static_share
from wsnloc.analysis.simulated_runs import simulate_tables, with_value
from wsnloc.campaign import Campaign
from wsnloc.estimators.run_data import RunData
from wsnloc.experiments import calibration, paper_a
from wsnloc.metrics.tracking import cell_metrics


def gain_against_rest(campaign: Campaign, scenario: str, rests_s, runs: int, seed: int, spec: dict,
                      dataset: str = "newcom") -> pd.DataFrame:
    """Per final rest and run: rest_s, run, static_share, rmse_plain_m, rmse_detection_m, gain_m.

    spec: experiments.paper_a (its first hybrid row is used).
    """
    hybrid = next((row for row in spec["rows"] if row["measurements"] == "hybrid"), None)
    if hybrid is None:
        raise ValueError("experiments.paper_a.rows: the static-share sweep needs a hybrid row")
    spec = {**spec, "rows": [hybrid]}
    label = f"{dataset}/{scenario}"
    p = paper_a.cell_params(spec, label, paper_a.TABLES[0], hybrid)
    out = []
    for rest_s in rests_s:
        rested = with_value(campaign, ("scenarios", scenario, "static_end_s"), float(rest_s))
        tables = simulate_tables(rested, scenario, runs, seed, dataset)
        zigbee = list(rested.anchors_of("zigbee")["anchor_id"])
        models = calibration.rss_models_for_runs(tables, rested, zigbee, p)
        for name, run_tables in tables.items():
            est = paper_a.run(RunData(run_tables, rested, models[name], name), spec, label).assign(run=name)
            rmse = cell_metrics(est, ["table"], run_tables["truth"]).set_index("table")["rmse"]
            share = static_share(est[est["table"] == "Table I"]).iloc[0]
            out.append({"rest_s": float(rest_s), "run": name, "static_share": share,
                        "rmse_plain_m": rmse["Table I"], "rmse_detection_m": rmse["Table II"],
                        "gain_m": rmse["Table II"] - rmse["Table I"]})
    return pd.DataFrame(out)
