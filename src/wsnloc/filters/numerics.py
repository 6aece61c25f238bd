"""Numerical guards of the filters on real data, and their counters.

A covariance that round-off (or an inconsistent update) left indefinite would stop a run
with "Matrix is not positive definite". Instead it is **regularised**: made symmetric,
(A + A^T) / 2, and its eigenvalues raised to at least `RELATIVE_FLOOR` times the largest
(and to `ABSOLUTE_FLOOR`), the nearest such matrix in the Frobenius norm (Higham 1988):
  A_reg = V diag(max(lambda_i, floor)) V^T,  floor = max(RELATIVE_FLOOR * max|lambda|, ABSOLUTE_FLOOR).
An update whose innovation covariance is still singular or whose result is not finite is
**skipped** (the prior kept). Both are counted in a `Guards` shared by the filters of one run
(across track restarts) and copied to the estimates' attrs (`regularised`, `skipped`,
`reinitialised`: particle-filter restarts from a fix, filters.particle).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

RELATIVE_FLOOR = 1e-9       # smallest eigenvalue kept, relative to the largest (double precision ~1e-16)
ABSOLUTE_FLOOR = 1e-12      # m^2 (or the state's unit squared): a covariance is never exactly singular


@dataclass
class Guards:
    """Counters of one run: covariances regularised, updates skipped, particle-filter restarts."""

    regularised: int = 0
    skipped: int = 0
    reinitialised: int = 0

    def attrs(self) -> dict:
        return {"regularised": self.regularised, "skipped": self.skipped, "reinitialised": self.reinitialised}


def regularise(A: np.ndarray) -> np.ndarray:
    """The symmetric positive definite matrix nearest to A with eigenvalues >= the floor
    (module docstring)."""
    A = 0.5 * (A + A.T)
    lam, V = np.linalg.eigh(A)
    floor = max(RELATIVE_FLOOR * float(np.max(np.abs(lam), initial=0.0)), ABSOLUTE_FLOOR)
    return (V * np.maximum(lam, floor)) @ V.T


def safe_cholesky(A: np.ndarray, guards: Guards | None = None) -> np.ndarray:
    """Lower Cholesky factor of A; when A is not positive definite (or not finite), of
    regularise(A), counted in guards.regularised. Raises LinAlgError only for a non-finite A."""
    try:
        return np.linalg.cholesky(A)
    except np.linalg.LinAlgError:
        if not np.all(np.isfinite(A)):
            raise
        if guards is not None:
            guards.regularised += 1
        return np.linalg.cholesky(regularise(A))


def usable(*arrays: np.ndarray) -> bool:
    """Whether every array is finite (an update giving anything else is skipped)."""
    return all(np.all(np.isfinite(a)) for a in arrays)
