"""Arithmetic operations per step of paper D's two trackers, machine-independent.

Counted as the algorithms are implemented in wsnloc.tracking.velocity_bounded and
wsnloc.filters.kalman (dense matrix products, nothing exploited from sparsity or symmetry):
multiplications, additions (subtractions included), divisions and square roots of real
numbers. Comparisons and sign changes are not counted. Conventions:
  dense product (a x b)(b x c):  a c b multiplications, a c (b - 1) additions;
  sum of k numbers:              k - 1 additions;
  ||(dx, dy)|| (hypot):          2 multiplications, 1 addition, 1 square root;
  2 x 2 inverse:                 adjugate / determinant: det = a d - b c (2 mul, 1 add),
                                 1 / det (1 div), 4 products by 1 / det (4 mul).
"""

from __future__ import annotations

from dataclasses import dataclass, fields

OPERATIONS = ("mul", "add", "div", "sqrt")


@dataclass(frozen=True)
class OpCount:
    """Numbers of multiplications, additions, divisions and square roots."""

    mul: int = 0
    add: int = 0
    div: int = 0
    sqrt: int = 0

    def __add__(self, other: "OpCount") -> "OpCount":
        return OpCount(*(getattr(self, f.name) + getattr(other, f.name) for f in fields(self)))

    def times(self, k: int) -> "OpCount":
        return OpCount(*(k * getattr(self, f.name) for f in fields(self)))

    @property
    def total(self) -> int:
        return self.mul + self.add + self.div + self.sqrt

    def as_dict(self) -> dict[str, int]:
        return {"mul": self.mul, "add": self.add, "div": self.div, "sqrt": self.sqrt, "total": self.total}


def matmul(a: int, b: int, c: int) -> OpCount:
    """(a x b) times (b x c), dense."""
    return OpCount(mul=a * b * c, add=a * c * (b - 1))


def elementwise_add(rows: int, cols: int = 1) -> OpCount:
    """Sum or difference of two rows x cols arrays."""
    return OpCount(add=rows * cols)


HYPOT = OpCount(mul=2, add=1, sqrt=1)
INVERSE_2X2 = OpCount(mul=6, add=1, div=1)


def velocity_tracker_step(window: int, bounded: bool = True) -> OpCount:
    """One step of VelocityBoundedTracker.step with a full window of N = `window` steps.

    speed (eq. 1/6) over the N + 1 stored positions, recomputed each step:
      N point differences (2 N add), N segment lengths (N hypot), their sum (N - 1 add),
      elapsed time t_N - t_0 (1 add), speed = length / elapsed (1 div);
    R_b = v_hat (T_i - T_{i-1}) (1 add, 1 mul); offset p_i - x_{i-1} (2 add); l = ||offset||
    (1 hypot); when l >= R_b (`bounded`): x_i = x_{i-1} + (R_b / l) offset (1 div, 2 mul, 2 add).
    """
    if window < 1:
        raise ValueError(f"tracker window must be at least 1, got {window}")
    speed = (elementwise_add(2).times(window) + HYPOT.times(window) + OpCount(add=window - 1)
             + OpCount(add=1) + OpCount(div=1))
    bound = OpCount(mul=1, add=1) + elementwise_add(2) + HYPOT
    projection = OpCount(div=1, mul=2) + elementwise_add(2) if bounded else OpCount()
    return speed + bound + projection


def kalman_predict(n: int) -> OpCount:
    """KalmanFilter.predict without input: x <- F x, P <- F P F^T + Q (n states)."""
    return matmul(n, n, 1) + matmul(n, n, n) + matmul(n, n, n) + elementwise_add(n, n)


def kalman_update(n: int, m: int) -> OpCount:
    """KalmanFilter.update, Joseph form, n states and m = 2 measurements.

    y = z - H x; PHt = P H^T; S = H PHt + R; S^-1; K = PHt S^-1; x <- x + K y;
    J = I - K H; P <- J P J^T + K R K^T.
    """
    if m != 2:
        raise ValueError(f"the inverse is counted for 2 x 2 innovation covariances, got m = {m}")
    innovation = matmul(m, n, 1) + elementwise_add(m)
    gain = matmul(n, n, m) + matmul(m, n, m) + elementwise_add(m, m) + INVERSE_2X2 + matmul(n, m, m)
    state = matmul(n, m, 1) + elementwise_add(n)
    joseph = (matmul(n, m, n) + elementwise_add(n, n) + matmul(n, n, n) + matmul(n, n, n)
              + matmul(n, m, m) + matmul(n, m, n) + elementwise_add(n, n))
    return innovation + gain + state + joseph


def kalman_step(n: int = 4, m: int = 2) -> OpCount:
    """Paper D's comparison KF per fix: one predict and one update (PV model: n = 4, m = 2)."""
    return kalman_predict(n) + kalman_update(n, m)


def cost_table(window: int) -> dict[str, dict]:
    """Operations per step of both trackers (the tracker with its bound active) and the
    Kalman / tracker ratios of total operations and of multiplications."""
    tracker = velocity_tracker_step(window, bounded=True)
    kalman = kalman_step()
    return {"velocity tracker": tracker.as_dict(), "Kalman filter": kalman.as_dict(),
            "Kalman / velocity": {"total": kalman.total / tracker.total, "mul": kalman.mul / tracker.mul}}
