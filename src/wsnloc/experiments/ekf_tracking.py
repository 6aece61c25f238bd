"""The EKF loop shared by papers A and C: one predict/update per estimation period.

Per epoch k: predict (skipped on epochs declared static, paper A's motion detection),
then update with whatever measurements the epoch holds (the measurement vector's size
changes from epoch to epoch; no measurement = no update). The filter starts at the first
epoch whose ranges give a multilateration fix; earlier epochs have no estimate.
Per-epoch diagnostics: number of measurements and NIS of the update.
"""

from __future__ import annotations

from typing import Callable, Sequence

import numpy as np
import pandas as pd

from wsnloc.experiments.epochs import Epoch
from wsnloc.filters.kalman import ExtendedKalmanFilter


def run_ekf(epochs: list[Epoch], F: np.ndarray, Q: np.ndarray, P0: np.ndarray,
            measurements: Sequence[object | None], initial_fix: Callable[[Epoch], np.ndarray | None],
            static: np.ndarray | None = None, B: np.ndarray | None = None,
            inputs: np.ndarray | None = None) -> pd.DataFrame:
    """Track through the epochs; returns t, x, y, n_meas, nis for every epoch after the start.

    measurements[k]: epoch k's measurement model with h, jacobian, R and the vector `z`,
    or None. It depends only on the epoch, so variants of the filter share one list.
    inputs: (len(epochs), k) control input per epoch (PVA acceleration), used with B.
    """
    ekf = None
    rows = []
    for k, (epoch, model) in enumerate(zip(epochs, measurements, strict=True)):
        if ekf is None:
            fix = initial_fix(epoch)
            if fix is None:
                continue
            x0 = np.zeros(len(F))
            x0[:2] = fix
            ekf = ExtendedKalmanFilter(x0, P0, F, Q)
            rows.append((epoch.t, ekf.x[0], ekf.x[1], 0, np.nan))
            continue
        if static is None or not static[k]:
            if B is not None and inputs is not None and np.all(np.isfinite(inputs[k])):
                ekf.predict(u=inputs[k], B=B)
            else:
                ekf.predict()
        nis = np.nan
        if model is not None:
            ekf.update_nonlinear(model.z, model.h, model.jacobian, model.R())
            nis = ekf.nis
        rows.append((epoch.t, ekf.x[0], ekf.x[1], 0 if model is None else len(model.z), nis))
    return pd.DataFrame(rows, columns=["t", "x", "y", "n_meas", "nis"])
