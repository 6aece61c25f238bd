"""Anchor-subset search: rank all C(N, k) subsets of k anchors by their static CRLB along a path.

Score of a subset S (m): the mean over the path points p_j of the position bound
sqrt(trace(J_S(p_j)^-1)), J_S(p) = sum_{i in S} J_i(p) (see metrics.bounds). Vectorised: the
per-anchor informations (P, N, 3) are combined with the (C, N) 0/1 membership matrix in one
matrix product, (C, N) @ (N, 3 P), in chunks of subsets to bound memory. A subset whose
information is singular at some path point has an infinite score and ranks last.
Cost: O(C N P) multiply-adds, e.g. C(21, 17) = 5985 subsets x 21 anchors x 400 points =
50 M; measured in tests/test_subset_search.py.
"""

from __future__ import annotations

from itertools import combinations

import numpy as np
import pandas as pd

from wsnloc.metrics.bounds import position_bound

CHUNK = 1024          # subsets per matrix product: 1024 x 3 P floats (10 MB at P = 400)
TIE_TOLERANCE = 1e-9  # relative: scores this close share a rank (symmetric layouts)


def memberships(n_anchors: int, k: int) -> np.ndarray:
    """(C(N, k), N) 0/1 matrix, one row per k-subset, in itertools.combinations order."""
    rows = np.array(list(combinations(range(n_anchors), k)), dtype=np.intp).reshape(-1, k)
    out = np.zeros((len(rows), n_anchors))
    np.put_along_axis(out, rows, 1.0, axis=1)
    return out


def mean_bounds(terms, membership) -> np.ndarray:
    """Mean over points of the position bound of each subset (C,), in m.

    terms: (P, N, 3) per-anchor information at each path point (bounds.*_information_terms);
    membership: (C, N) 0/1 rows.
    """
    terms = np.asarray(terms, dtype=float)
    P, N, _ = terms.shape
    flat = terms.transpose(1, 0, 2).reshape(N, 3 * P)
    out = np.empty(len(membership))
    for start in range(0, len(membership), CHUNK):
        information = (membership[start:start + CHUNK] @ flat).reshape(-1, P, 3)
        out[start:start + CHUNK] = position_bound(information).mean(axis=1)
    return out


def rank_subsets(terms, anchor_ids, k: int) -> pd.DataFrame:
    """All k-subsets of the anchors ranked by mean bound (rank 1 = best).

    Returns columns `members` (comma-joined anchor ids in the given order), `mean_bound_m`
    and `rank`, sorted by rank; ties (within 1e-9 relative) share the best rank.
    """
    anchor_ids = list(anchor_ids)
    if not 1 <= k <= len(anchor_ids):
        raise ValueError(f"subset size k={k} must be between 1 and the number of anchors ({len(anchor_ids)})")
    membership = memberships(len(anchor_ids), k)
    scores = mean_bounds(terms, membership)
    ordered = np.sort(scores)
    rank = np.searchsorted(ordered, scores * (1.0 - TIE_TOLERANCE), side="left") + 1
    ids = np.asarray(anchor_ids, dtype=object)
    members = [",".join(ids[row.astype(bool)]) for row in membership]
    table = pd.DataFrame({"members": members, "mean_bound_m": scores, "rank": rank})
    return table.sort_values(["rank", "members"], kind="stable").reset_index(drop=True)


def rank_of(table: pd.DataFrame, members, anchor_ids) -> int:
    """Rank of a given subset (anchor ids, any order) in a rank_subsets table."""
    chosen = set(members)
    key = ",".join(a for a in anchor_ids if a in chosen)
    match = table.loc[table["members"] == key, "rank"]
    if len(chosen) != len(key.split(",")) or match.empty:
        raise ValueError(f"subset {sorted(chosen)} is not among the ranked subsets")
    return int(match.iloc[0])
