"""Time order of a log's records: which records to keep so that time never goes backwards.

A raw log is written in time order, so a record out of order is damage. Refusing every
record earlier than the latest one seen lets a single far-future glitch take all the
records after it; instead the kept records are the longest subsequence in time order
(non-decreasing, or strictly increasing for sample streams), i.e. the fewest records are
refused. Among equally long subsequences the one taking the earliest records wins, so
that of two conflicting records the first one written is kept. O(n log n); a log that is
already in order costs one vectorised comparison.
"""

from __future__ import annotations

from bisect import bisect_left, bisect_right

import numpy as np

from wsnloc.io.rawlines import Quarantine


def in_order(t: np.ndarray, strict: bool) -> bool:
    """Whether `t` is non-decreasing (strictly increasing when `strict`)."""
    steps = np.diff(np.asarray(t, dtype=float))
    return bool(np.all(steps > 0) if strict else np.all(steps >= 0))


def longest_ordered(t: np.ndarray, strict: bool) -> np.ndarray:
    """Boolean mask of the records kept: a longest subsequence of `t` in time order.

    `strict`: each kept time must be later than the previous kept one (else later or
    equal). Ties between equally long subsequences go to the lexicographically earliest
    set of indices.
    """
    t = np.asarray(t, dtype=float)
    keep = np.ones(len(t), dtype=bool)
    if in_order(t, strict):
        return keep
    # Length of the longest ordered subsequence starting at each index, from the right:
    # read backwards, an ordered subsequence of t is one of -t in the same (non-strict or
    # strict) order, so the classic patience tails give it in O(n log n).
    insert = bisect_left if strict else bisect_right
    tails: list[float] = []
    longest_from = np.empty(len(t), dtype=np.int64)
    for i in range(len(t) - 1, -1, -1):
        value = -t[i]
        k = insert(tails, value)
        if k == len(tails):
            tails.append(value)
        else:
            tails[k] = value
        longest_from[i] = k + 1
    # Greedy from the left: the first index that can still start a subsequence of the
    # remaining length and follows the last kept time is kept.
    keep[:] = False
    needed, last = len(tails), -np.inf
    for i in range(len(t)):
        if needed and longest_from[i] == needed and (t[i] > last if strict else t[i] >= last):
            keep[i] = True
            needed -= 1
            last = t[i]
    return keep


def out_of_order_reasons(t: np.ndarray, keep: np.ndarray, strict: bool, unit: str = "ms") -> dict[int, str]:
    """Why each refused record (index not in `keep`) is out of order, compared with the
    kept records around it: earlier than the last kept one ("time goes backwards"), equal to
    it ("time repeats"), or later than the next kept one ("time jumps ahead")."""
    if keep.all():                          # the usual case: nothing refused
        return {}
    t = np.asarray(t, dtype=float)
    kept_times = np.where(keep, t, -np.inf)
    previous = np.maximum.accumulate(np.concatenate([[-np.inf], kept_times[:-1]]))
    later_kept = np.where(keep, t, np.inf)
    following = np.minimum.accumulate(later_kept[::-1])[::-1]
    following = np.concatenate([following[1:], [np.inf]])
    reasons = {}
    for i in np.flatnonzero(~keep):
        if t[i] < previous[i]:
            reasons[int(i)] = f"time goes backwards: {t[i]:g} {unit} after {previous[i]:g} {unit}"
        elif strict and t[i] == previous[i]:
            reasons[int(i)] = f"time repeats: {t[i]:g} {unit} after {previous[i]:g} {unit}"
        else:
            reasons[int(i)] = (f"time jumps ahead: {t[i]:g} {unit} is later than the records after it "
                               f"({following[i]:g} {unit} next)")
    return reasons


def keep_in_time_order(file: str, parsed: list[tuple[int, str, float, object]],
                       refused: list[tuple[int, str, str]], quarantine: Quarantine, strict: bool) -> list:
    """Payloads of the parsed lines that are in time order, in file order.

    `parsed`: (line number, text, t_ms, payload) of each line that parsed; `refused`:
    (line number, text, reason) of those that did not. Every refused or out-of-order line
    goes to the quarantine, in file order.
    """
    t_ms = np.array([line[2] for line in parsed], dtype=float)
    keep = longest_ordered(t_ms, strict)
    refused = refused + [(parsed[i][0], parsed[i][1], reason)
                         for i, reason in out_of_order_reasons(t_ms, keep, strict).items()]
    for number, text, reason in sorted(refused):
        quarantine.add(file, number, text, reason)
    return [line[3] for line, kept in zip(parsed, keep) if kept]
