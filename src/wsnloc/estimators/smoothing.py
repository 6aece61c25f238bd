"""Offline fixed-interval smoothing of a Bayesian filter run: record the forward pass, then
run the Rauch-Tung-Striebel smoother (filters.smoother.rts_smooth) over it.

The forward pass is a chain of nodes per track segment (a segment starts at the
initiator and ends when the coasting limit drops the track). Each node holds the filtered
mean x_j|j and covariance P_j|j and the step that predicted it from the node before:
F_j, Q_j and the input B_j u_j of motion.MotionModel.matrices(t_j - t_j-1), or F = I,
Q = 0 when the filter did not predict (static epoch, or measurements sharing a time).
Backward pass per segment, as in rts_smooth:
  C_j = P_j|j F_j+1^T (F_j+1 P_j|j F_j+1^T + Q_j+1)^-1
  x_j|N = x_j|j + C_j (x_j+1|N - F_j+1 x_j|j - B_j+1 u_j+1),  P_j|N = P_j|j + C_j (P_j+1|N - P_j+1|j) C_j^T
The estimator's outputs are nodes marked with output(); the smoothed (x, P) of those nodes,
in output order, replace the filtered ones.

Output times in the two update modes:
- `epoch`: one node per output time t_k (after its update), so the smoother sees exactly
  the forward filter's predictions.
- `sequential`: nodes at every update time (each measurement's own time) and at every
  output time: the recorded forward pass steps the filter to t_k (a predict without an
  update) instead of predicting to t_k without storing it. Since the white-acceleration
  Q(dt) of motion_models is piecewise constant over each step, Q(a) and Q(b) in sequence
  differ slightly from Q(a + b): this forward pass is the sequential filter with its
  predictions split at the output times (identical means when no process noise enters).
"""

from __future__ import annotations

import numpy as np

from wsnloc.filters.smoother import rts_smooth


class ForwardPass:
    """Filtered states of one run, by track segment, and which of them were output."""

    def __init__(self):
        self.segments: list[list[tuple]] = []       # nodes (x, P, F, Q, B, u) per segment
        self.outputs: list[tuple[int, int]] = []     # (segment, node) of every output, in order

    def start(self, filt) -> None:
        """A new track segment starting at the filter's initial state."""
        self.segments.append([])
        self.node(filt, None)

    def node(self, filt, step: tuple | None) -> None:
        """The filter's state after a predict step (F, Q, B, u) (None: no predict) and any update."""
        n = len(filt.x)
        F, Q, B, u = step if step is not None else (np.eye(n), np.zeros((n, n)), None, None)
        self.segments[-1].append((np.array(filt.x, dtype=float), np.array(filt.P, dtype=float), F, Q, B, u))

    def output(self) -> None:
        """The last node is the estimate output at this output time."""
        self.outputs.append((len(self.segments) - 1, len(self.segments[-1]) - 1))

    def smooth(self) -> list[tuple[np.ndarray, np.ndarray]]:
        """Smoothed (x (n,), P (n, n)) of every output, in output order."""
        smoothed = [_smooth_segment(nodes) for nodes in self.segments]
        return [(smoothed[s][0][j], smoothed[s][1][j]) for s, j in self.outputs]


def _smooth_segment(nodes: list[tuple]) -> tuple[np.ndarray, np.ndarray]:
    xs, Ps, Fs, Qs, Bs, us = zip(*nodes)
    with_input = [k for k, B in enumerate(Bs) if B is not None]
    if not with_input:
        return rts_smooth(xs, Ps, Fs, Qs)
    n, m = Bs[with_input[0]].shape
    B_all = np.array([np.zeros((n, m)) if B is None else B for B in Bs])
    u_all = np.array([np.full(m, np.nan) if u is None else u for u in us])
    return rts_smooth(xs, Ps, Fs, Qs, u_all, B_all)
