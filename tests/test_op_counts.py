"""Operation counts of paper D's trackers, checked by running scalar re-implementations on a
number type that counts its operations, whose outputs match the real code."""

import math
from collections import deque

import numpy as np
import pytest

from wsnloc.filters.kalman import KalmanFilter
from wsnloc.filters.motion_models import constant_velocity
from wsnloc.metrics.op_counts import (OpCount, cost_table, kalman_predict, kalman_update, matmul,
                                      velocity_tracker_step)
from wsnloc.tracking.velocity_bounded import VelocityBoundedTracker


class Tally:
    def __init__(self):
        self.mul = self.add = self.div = self.sqrt = 0

    def count(self) -> OpCount:
        return OpCount(self.mul, self.add, self.div, self.sqrt)


class Num:
    """A real number that counts +, -, *, / and sqrt into a shared Tally."""

    def __init__(self, value, tally):
        self.v, self.tally = float(value), tally

    def _other(self, x):
        return x.v if isinstance(x, Num) else float(x)

    def __add__(self, x):
        self.tally.add += 1
        return Num(self.v + self._other(x), self.tally)

    def __sub__(self, x):
        self.tally.add += 1
        return Num(self.v - self._other(x), self.tally)

    def __mul__(self, x):
        self.tally.mul += 1
        return Num(self.v * self._other(x), self.tally)

    def __truediv__(self, x):
        self.tally.div += 1
        return Num(self.v / self._other(x), self.tally)

    def __neg__(self):
        return Num(-self.v, self.tally)                 # sign changes are not counted

    def __ge__(self, x):
        return self.v >= self._other(x)

    def sqrt(self):
        self.tally.sqrt += 1
        return Num(math.sqrt(self.v), self.tally)


# ---- scalar re-implementation of the velocity-bounded tracker (full window, moving) ----

def hypot(dx, dy):
    return (dx * dx + dy * dy).sqrt()


def tracker_step(history, position, last_t, t, raw):
    diffs = [(b[1][0] - a[1][0], b[1][1] - a[1][1]) for a, b in zip(list(history)[:-1], list(history)[1:])]
    lengths = [hypot(dx, dy) for dx, dy in diffs]
    total = lengths[0]
    for value in lengths[1:]:
        total = total + value
    speed = total / (history[-1][0] - history[0][0])
    bound = speed * (t - last_t)
    offset = (raw[0] - position[0], raw[1] - position[1])
    length = hypot(*offset)
    if length >= bound:
        scale = bound / length
        return (position[0] + scale * offset[0], position[1] + scale * offset[1]), True
    return raw, False


# ---- scalar re-implementation of KalmanFilter (dense products, Joseph form) ----

def mm(a, b):
    rows, inner, cols = len(a), len(b), len(b[0])
    out = []
    for i in range(rows):
        row = []
        for j in range(cols):
            acc = a[i][0] * b[0][j]
            for k in range(1, inner):
                acc = acc + a[i][k] * b[k][j]
            row.append(acc)
        out.append(row)
    return out


def madd(a, b, sign=1):
    return [[x + y if sign > 0 else x - y for x, y in zip(ra, rb)] for ra, rb in zip(a, b)]


def tr(a):
    return [list(col) for col in zip(*a)]


def inv2(s):
    (a, b), (c, d) = s
    r = Num(1.0, a.tally) / (a * d - b * c)
    return [[d * r, -b * r], [-c * r, a * r]]


def kf_predict(x, P, F, Q):
    return mm(F, x), madd(mm(mm(F, P), tr(F)), Q)


def kf_update(x, P, z, H, R, I):
    y = madd(z, mm(H, x), sign=-1)
    PHt = mm(P, tr(H))
    S = madd(mm(H, PHt), R)
    K = mm(PHt, inv2(S))
    x = madd(x, mm(K, y))
    J = madd(I, mm(K, H), sign=-1)
    P = madd(mm(mm(J, P), tr(J)), mm(mm(K, R), tr(K)))
    return x, P


def as_nums(a, tally):
    return [[Num(v, tally) for v in row] for row in np.atleast_2d(a)]


def values(a):
    return np.array([[v.v for v in row] for row in a])


def test_closed_forms():
    assert matmul(2, 3, 4) == OpCount(mul=24, add=16)
    assert velocity_tracker_step(6) == OpCount(mul=17, add=30, div=2, sqrt=7)
    assert velocity_tracker_step(6, bounded=False) == OpCount(mul=15, add=28, div=1, sqrt=7)
    assert kalman_predict(4) == OpCount(mul=144, add=124)
    assert kalman_update(4, 2) == OpCount(mul=294, add=233, div=1)
    table = cost_table(6)
    assert table["Kalman / velocity"]["total"] == pytest.approx((438 + 357 + 1) / (17 + 30 + 2 + 7))
    with pytest.raises(ValueError, match="window"):
        velocity_tracker_step(0)


@pytest.mark.parametrize("window", [1, 3, 6, 10])
def test_tracker_counts_match_a_counting_run_that_reproduces_the_real_tracker(window):
    rng = np.random.default_rng(window)
    t = np.arange(40) * 0.5
    fixes = np.column_stack([0.3 * t, 0.1 * t]) + rng.normal(0, 0.8, (40, 2))
    real = VelocityBoundedTracker(window, "raw")
    outputs = [real.step(tk, fk) for tk, fk in zip(t, fixes)]
    history = deque(((tk, fk) for tk, fk in zip(t[:window + 1], fixes[:window + 1])), maxlen=window + 1)
    seen = set()
    for k in range(window + 1, len(t)):                     # full window from here on
        tally = Tally()
        hist = deque(((Num(tj, tally), (Num(pj[0], tally), Num(pj[1], tally))) for tj, pj in history),
                     maxlen=window + 1)
        position = (Num(outputs[k - 1][0], tally), Num(outputs[k - 1][1], tally))
        out, bounded = tracker_step(hist, position, Num(t[k - 1], tally), Num(t[k], tally),
                                    (Num(fixes[k][0], tally), Num(fixes[k][1], tally)))
        assert [out[0].v, out[1].v] == pytest.approx(outputs[k], abs=1e-12)
        assert tally.count() == velocity_tracker_step(window, bounded)
        seen.add(bounded)
        history.append((t[k], fixes[k]))
    assert seen == {True, False}                            # both branches were counted


def test_kalman_counts_match_a_counting_run_that_reproduces_the_real_filter():
    F, Q = constant_velocity(0.5, 0.5)
    H = np.hstack([np.eye(2), np.zeros((2, 2))])
    R = np.eye(2) * 1.5**2
    P0 = np.diag([2.25, 2.25, 0.25, 0.25])
    real = KalmanFilter(np.array([1.0, 2.0, 0.0, 0.0]), P0, F, Q, H, R)
    tally = Tally()
    x, P = as_nums(np.array([[1.0], [2.0], [0.0], [0.0]]), tally), as_nums(P0, tally)
    Fn, Qn, Hn, Rn, In = (as_nums(a, tally) for a in (F, Q, H, R, np.eye(4)))
    for z in ([1.3, 2.1], [1.2, 2.4], [1.6, 2.2]):
        real.predict()
        real.update(np.array(z))
        before = tally.count()
        x, P = kf_predict(x, P, Fn, Qn)
        predicted = tally.count()
        x, P = kf_update(x, P, as_nums(np.array(z)[:, None], tally), Hn, Rn, In)
        after = tally.count()
        assert values(x)[:, 0] == pytest.approx(real.x, rel=1e-12)
        assert values(P) == pytest.approx(real.P, rel=1e-12)
        assert OpCount(*(b - a for a, b in zip(_ops(before), _ops(predicted)))) == kalman_predict(4)
        assert OpCount(*(b - a for a, b in zip(_ops(predicted), _ops(after)))) == kalman_update(4, 2)


def _ops(count: OpCount):
    return count.mul, count.add, count.div, count.sqrt
