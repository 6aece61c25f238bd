"""Time order of a log's records: the fewest records refused, ties to the earliest records."""

from itertools import combinations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st

from wsnloc.io.timeorder import longest_ordered, out_of_order_reasons


def ordered_by_brute_force(t, strict):
    """The specification itself: the largest set of indices whose times are in order,
    the lexicographically earliest of those; by trying every subset, largest first."""
    for size in range(len(t), 0, -1):
        for subset in combinations(range(len(t)), size):
            values = [t[i] for i in subset]
            if all((b > a) if strict else (b >= a) for a, b in zip(values, values[1:])):
                return list(subset)
    return []


@settings(max_examples=200, deadline=None)
@given(t=st.lists(st.integers(0, 6), max_size=10), strict=st.booleans())
def test_longest_ordered_equals_brute_force(t, strict):
    keep = longest_ordered(np.array(t, dtype=float), strict)
    assert np.flatnonzero(keep).tolist() == ordered_by_brute_force(t, strict)


def test_one_far_future_glitch_is_refused_alone():
    t = np.array([10.0, 20.0, 1e9, 30.0, 40.0, 50.0])
    keep = longest_ordered(t, strict=False)
    assert keep.tolist() == [True, True, False, True, True, True]
    assert out_of_order_reasons(t, keep, strict=False) == {
        2: "time jumps ahead: 1e+09 ms is later than the records after it (30 ms next)"}


def test_one_far_past_glitch_is_refused_alone():
    t = np.array([10.0, 20.0, -5.0, 30.0])
    keep = longest_ordered(t, strict=True)
    assert keep.tolist() == [True, True, False, True]
    assert out_of_order_reasons(t, keep, strict=True) == {2: "time goes backwards: -5 ms after 20 ms"}


def test_repeated_time_is_refused_only_when_strict():
    t = np.array([1.0, 2.0, 2.0, 3.0])
    assert longest_ordered(t, strict=False).all()
    keep = longest_ordered(t, strict=True)
    assert keep.tolist() == [True, True, False, True]
    assert out_of_order_reasons(t, keep, strict=True)[2] == "time repeats: 2 ms after 2 ms"
