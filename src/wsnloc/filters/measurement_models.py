"""Measurement models h(x) and their Jacobians H = dh/dx for range and RSS observations.

Anchors a_i = (x_i, y_i) (m, 2), or (x_i, y_i, z_i) (m, 3) for a 3-D state: the position p
occupies the first 2 or 3 state entries, as many as the anchors have coordinates;
d_i = ||p - a_i|| (floored at 1 mm to keep the Jacobian finite).
- TOA range (paper A eq. for h_TOA):   h_i = d_i,  H_i = [(x - x_i)/d_i, (y - y_i)/d_i, 0 ...]
  (3-D state: H_i = [(x - x_i)/d_i, (y - y_i)/d_i, (z - z_i)/d_i, 0 ...])
  with a known height difference dz_i between anchor and tag (3-D ranges, 2-D state):
  h_i = sqrt(d_i^2 + dz_i^2),  H_i = [(x - x_i)/h_i, (y - y_i)/h_i, 0 ...]
- RSS (log-normal shadowing):          h_i = P0 - 10 n log10(D_i / d0),  D_i = max(sqrt(d_i^2 + dz_i^2), d0)
                                       H_i = [-10 n / ln10 (x - x_i)/D_i^2, -10 n / ln10 (y - y_i)/D_i^2, 0 ...]
  (0 where the distance is below d0): the log-distance model holds from the reference distance
  d0 on (Rappaport, Wireless Communications, sec. 4.9); below it, the 1/d^2 Jacobian of a
  horizontal distance near a receiver would throw the state far away on one sample. dz_i:
  receiver height - tag height (3-D distance), 0 in 2-D.
- hybrid: the two stacked, R = blockdiag(R_TOA, R_RSS).
- TDOA range difference of pair i = (receiver a_i, reference receiver b_i), with r_j the
  (3-D when dz_j is known) distance to receiver j:
                                       h_i = r_{a_i} - r_{b_i}
                                       H_i = [(p - a_i)/r_{a_i} - (p - b_i)/r_{b_i}, 0 ...]
  Each receiver's arrival time carries its own noise (sigma_j, in m): with the incidence
  matrix D (D[i, a_i] = 1, D[i, b_i] = -1) the pairs' noise is R = D diag(sigma^2) D^T, so
  two pairs sharing a reference are correlated (covariance sigma_ref^2; correlation 1/2 for
  equal sigmas) and one pair has variance sigma_a^2 + sigma_b^2.
h_many(X) evaluates h at N states at once, X (N, n) -> (N, m) (particle filters, the UKF's
sigma points); linearise(x) gives (h(x), H(x)) from one evaluation of the geometry (the EKF).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

MIN_DISTANCE = 1e-3


def _norm(diff):
    """||diff|| over the last axis of (..., 2) or (..., 3) offsets (np.hypot in 2-D)."""
    if diff.shape[-1] == 2:
        return np.hypot(diff[..., 0], diff[..., 1])
    return np.sqrt(np.sum(diff**2, axis=-1))


def _geometry(x, anchors):
    """(p - a_i (m, k), d_i (m,)) with k = 2 or 3, the anchors' coordinates."""
    diff = np.asarray(x, dtype=float)[None, :anchors.shape[1]] - anchors
    return diff, distance(diff)


def distance(diff: np.ndarray) -> np.ndarray:
    """d = max(||p - a||, 1 mm) of displacements diff = p - a (..., k), k = 2 (horizontal) or 3, in m."""
    return np.maximum(_norm(diff), MIN_DISTANCE)


def range_rows(diff: np.ndarray, dz: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """TOA range h and the position columns of its Jacobian for displacements diff = p - a
    (..., k) and height differences dz (...; None: none): h = sqrt(d^2 + dz^2),
    H_p = (p - a) / h (h floored at 1 mm). Any leading shape: one filter's anchors or every
    run's padded measurements (estimators.array_ekf)."""
    d = distance(diff)
    h = d if dz is None else np.sqrt(d**2 + dz**2)
    return h, diff / np.maximum(h, MIN_DISTANCE)[..., None]


def rss_rows(diff: np.ndarray, p0_dbm, exponent, d0_m, dz: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """RSS h = P0 - 10 n log10(D / d0), D = max(sqrt(d^2 + dz^2), d0), and the position columns
    of its Jacobian, H_p = -10 n / ln10 (p - a) / D^2 (0 below d0: module docstring), for
    displacements diff (..., k) and height differences dz (...; None: none); P0, n, d0
    scalars or arrays of the leading shape."""
    full, D = _rss_distance(distance(diff), d0_m, dz)
    gain = np.where(full >= d0_m, -10.0 * exponent / np.log(10.0) / D**2, 0.0)
    return p0_dbm - 10.0 * exponent * np.log10(D / d0_m), diff * gain[..., None]


def _rss_distance(d: np.ndarray, d0_m, dz: np.ndarray | None) -> tuple[np.ndarray, np.ndarray]:
    """(sqrt(d^2 + dz^2), D = max(sqrt(d^2 + dz^2), d0)) of distances d (m); dz None: none."""
    full = d if dz is None else np.sqrt(d**2 + dz**2)
    return full, np.maximum(full, d0_m)


def _distances_many(X, anchors):
    """Distances (N, m) from N states X (N, n) to the anchors (in the anchors' 2 or 3
    coordinates; horizontal ones for 2-D anchors), floored like _geometry."""
    X = np.asarray(X, dtype=float)
    return distance(X[:, None, :anchors.shape[1]] - anchors[None])


@dataclass
class RangeModel:
    anchors: np.ndarray        # (m, 2), or (m, 3) with a 3-D state
    sigma_m: np.ndarray        # (m,) range noise std
    dz_m: np.ndarray | None = None   # (m,) anchor height - tag height with 2-D anchors; None: no offset

    def h(self, x) -> np.ndarray:
        return range_rows(_geometry(x, self.anchors)[0], self.dz_m)[0]

    def h_many(self, X) -> np.ndarray:
        """h at every row of X (N, n): (N, m) ranges in m."""
        d = _distances_many(X, self.anchors)
        return d if self.dz_m is None else np.sqrt(d**2 + self.dz_m[None, :] ** 2)

    def jacobian(self, x) -> np.ndarray:
        return self.linearise(x)[1]

    def linearise(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(h(x), H(x)) (m,), (m, n)."""
        h, rows = range_rows(_geometry(x, self.anchors)[0], self.dz_m)
        H = np.zeros((len(self.anchors), len(x)))
        H[:, :self.anchors.shape[1]] = rows
        return h, H

    def R(self) -> np.ndarray:
        R = np.zeros((len(self.anchors), len(self.anchors)))
        np.fill_diagonal(R, np.asarray(self.sigma_m, dtype=float) ** 2)     # sigma_m (m,) or one for all
        return R


@dataclass
class RssModel:
    anchors: np.ndarray        # (m, 2), or (m, 3) with a 3-D state
    p0_dbm: float
    exponent: float
    sigma_db: float
    d0_m: float = 1.0
    dz_m: np.ndarray | None = None   # (m,) receiver height - tag height; None: 2-D

    def h(self, x) -> np.ndarray:
        return rss_rows(_geometry(x, self.anchors)[0], self.p0_dbm, self.exponent, self.d0_m, self.dz_m)[0]

    def h_many(self, X) -> np.ndarray:
        """h at every row of X (N, n): (N, m) RSS in dBm."""
        dz = None if self.dz_m is None else self.dz_m[None, :]
        D = _rss_distance(_distances_many(X, self.anchors), self.d0_m, dz)[1]
        return self.p0_dbm - 10.0 * self.exponent * np.log10(D / self.d0_m)

    def jacobian(self, x) -> np.ndarray:
        return self.linearise(x)[1]

    def linearise(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(h(x), H(x)) (m,), (m, n)."""
        h, rows = rss_rows(_geometry(x, self.anchors)[0], self.p0_dbm, self.exponent, self.d0_m, self.dz_m)
        H = np.zeros((len(self.anchors), len(x)))
        H[:, :self.anchors.shape[1]] = rows
        return h, H

    def R(self) -> np.ndarray:
        return np.eye(len(self.anchors)) * self.sigma_db**2


@dataclass
class TdoaModel:
    """Range differences of receiver pairs (module docstring). The position is the state's first
    two entries, or three with 3-D receivers (k, 3): H then has (z - z_j) / r_j as for x and y."""

    receivers: np.ndarray      # (k, 2) receiver (anchor) positions, or (k, 3) with a 3-D state
    pairs: np.ndarray          # (m, 2) int: (receiver, reference receiver) of each range difference
    sigma_m: np.ndarray        # (k,) or scalar: arrival-time noise std of each receiver, in m
    dz_m: np.ndarray | None = None   # (k,) receiver height - tag height; None: 2-D distances

    def h(self, x) -> np.ndarray:
        r, _ = range_rows(_geometry(x, self.receivers)[0], self.dz_m)
        return r[self.pairs[:, 0]] - r[self.pairs[:, 1]]

    def h_many(self, X) -> np.ndarray:
        """h at every row of X (N, n): (N, m) range differences in m."""
        d = _distances_many(X, self.receivers)
        r = d if self.dz_m is None else np.sqrt(d**2 + self.dz_m[None, :] ** 2)
        return r[:, self.pairs[:, 0]] - r[:, self.pairs[:, 1]]

    def jacobian(self, x) -> np.ndarray:
        return self.linearise(x)[1]

    def linearise(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(h(x), H(x)) (m,), (m, n)."""
        diff, _ = _geometry(x, self.receivers)
        r, unit = range_rows(diff, self.dz_m)
        H = np.zeros((len(self.pairs), len(x)))
        H[:, :diff.shape[1]] = unit[self.pairs[:, 0]] - unit[self.pairs[:, 1]]
        return r[self.pairs[:, 0]] - r[self.pairs[:, 1]], H

    def pair_rows(self, X, pair) -> tuple[np.ndarray, np.ndarray]:
        """(h_i, the position columns of H_i) of pair `pair[i]` at the position X[i] (N, k), one
        row per measurement: range differences taken at different positions (a track); the
        equations of h and jacobian (module docstring)."""
        X = np.asarray(X, dtype=float)[:, :self.receivers.shape[1]]
        ends = self.pairs[np.asarray(pair, dtype=np.intp)]
        (r_a, u_a), (r_b, u_b) = (range_rows(X - self.receivers[j], None if self.dz_m is None else self.dz_m[j])
                                  for j in (ends[:, 0], ends[:, 1]))
        return r_a - r_b, u_a - u_b

    def incidence(self) -> np.ndarray:
        """D (m, k): +1 at each pair's receiver, -1 at its reference."""
        D = np.zeros((len(self.pairs), len(self.receivers)))
        rows = np.arange(len(self.pairs))
        D[rows, self.pairs[:, 0]], D[rows, self.pairs[:, 1]] = 1.0, -1.0
        return D

    def R(self) -> np.ndarray:
        D = self.incidence()
        variances = np.broadcast_to(np.asarray(self.sigma_m, dtype=float) ** 2, (len(self.receivers),))
        return (D * variances) @ D.T


@dataclass
class Stacked:
    """Several models observed at once: z = [z_1; z_2; ...], with the measured vector z."""

    parts: list
    z: np.ndarray

    def __post_init__(self):
        self._R = None

    def h(self, x) -> np.ndarray:
        return np.concatenate([p.h(x) for p in self.parts])

    def h_many(self, X) -> np.ndarray:
        """h at every row of X (N, n): (N, m), the parts side by side."""
        return np.hstack([p.h_many(X) for p in self.parts])

    def jacobian(self, x) -> np.ndarray:
        return self.linearise(x)[1]

    def linearise(self, x) -> tuple[np.ndarray, np.ndarray]:
        """(h(x), H(x)): the parts' stacked (one part: its own)."""
        if len(self.parts) == 1:
            return self.parts[0].linearise(x)
        hs, Hs = zip(*(p.linearise(x) for p in self.parts))
        return np.concatenate(hs), np.vstack(Hs)

    def R(self) -> np.ndarray:
        """blockdiag(R_1, R_2, ...); built once (it does not depend on the state), so filter
        variants run on the same epochs share it. Read-only."""
        if self._R is None and len(self.parts) == 1:
            self._R = self.parts[0].R()
            self._R.flags.writeable = False
        if self._R is None:
            blocks = [p.R() for p in self.parts]
            n = sum(len(b) for b in blocks)
            self._R = np.zeros((n, n))
            k = 0
            for b in blocks:
                self._R[k:k + len(b), k:k + len(b)] = b
                k += len(b)
            self._R.flags.writeable = False
        return self._R
