"""Facts about a scenario's set-up measured on the estimates, to explain differences from a paper.

- static share: the share of one cell's estimate epochs at which the target stands still,
  i.e. the true speed ||p(t_k) - p(t_{k-1})|| / (t_k - t_{k-1}) is below metrics.tracking.STATIC_SPEED_MPS
  (the first epoch of a run takes the speed of the second);
- measurements per epoch: the mean number of measurements an estimator used per epoch
  (its `n_meas`, e.g. anchors heard), over the epochs of one run.
Each is a per-run value, reported as a results row (mean over runs with its 95% interval)
in table SETUP_TABLE, row = fact, column = scenario.
"""

from __future__ import annotations

import numpy as np
import pandas as pd

from wsnloc import results
from wsnloc.metrics.tracking import moving_mask

SETUP_TABLE = "Set-up"
BIAS_CALIBRATION = "IMU bias measured at rest over (s)"   # a dead reckoning's bias calibration (0: none)


def static_share(cell: pd.DataFrame) -> pd.Series:
    """Per run: share of the cell's epochs with true speed below STATIC_SPEED_MPS (columns
    run, t, true_x, true_y of one cell's scored estimates)."""
    def one(run: pd.DataFrame) -> float:
        t = run["t"].to_numpy(float)
        if len(t) < 2:
            return float("nan")
        return float(np.mean(~moving_mask(t, run["true_x"].to_numpy(float), run["true_y"].to_numpy(float))))
    return cell.groupby("run", sort=True).apply(one, include_groups=False)


def measurements_per_epoch(cell: pd.DataFrame) -> pd.Series:
    """Per run: mean `n_meas` over the cell's epochs."""
    return cell.groupby("run", sort=True)["n_meas"].mean()


def fact_row(experiment: str, fact: str, scenario: str, per_run: pd.Series, metric: str) -> dict:
    """results row of one fact on one scenario (mean over runs with its 95% interval)."""
    return results.row_over_runs(per_run.to_numpy(float), experiment=experiment, table=SETUP_TABLE, row=fact,
                                 column=scenario, scenario=scenario, metric=metric)
