"""Options of the Bayesian filters' measurement update, as one adapter around any filter
with the KalmanFilter interface (x, P, predict(F, Q, u, B), update(z, H, R, hx)):

- innovation gating and robust M-estimator updates (estimators.robust);
- range self-calibration: state augmented with a common scale and/or offset
  (estimators.self_calibration);
- NLOS-aware range noise: sigma_i = range_sigma_m + n_i range_sigma_per_wall_m, with n_i
  the campaign walls crossed by the straight line from the current position estimate to
  anchor i (so links through walls, which carry excess path and multipath, weigh less);
- site bound on RSS alone (`rss_site_margin_m`): after each update the position is projected
  onto the receivers' bounding box enlarged by the margin (estimate projection, Simon 2010,
  "Kalman filtering with state constraints", IET Control Theory Appl. 4(8)); RSS barely
  changes with position outside the receivers' hull, where a filter drifts unopposed, and a
  tag that every receiver hears is among them.

The gate and the robust update are one pluggable component, the **updater**
(`default_updater(p)`): a callable updater(filt, z, H, R, hx, S) -> bool mask of the measurements
used, which updates `filt` (x, P, update(z, H, R, hx, S)) with the model linearised at the prior
(the EKF's Jacobian, or a filter's own `linearise(h_many) -> (hx, H, Omega)`, the UKF's
statistical linear regression, Omega added to R); S = H P- H^T + R is the prior's innovation
covariance, computed once per update for the innovation record, the gate and the update
(robust.robust_update with the configured gate and loss by default; pass another as `updater`
to configured_factory / ConfiguredFilter for another gate or likelihood). The adapter counts
the measurements offered and gated over a run (across track restarts), judges the track lost
from the gate's recent rejections, at once where a fix on the rejected ranges fits them far
better than the track (`gate_refix`; `lost`, which the deleter reads: core.CoastingDeleter)
and exposes the calibration states; bayes.run_filter copies them to the estimates' attrs.
"""

from __future__ import annotations

from collections import deque
from dataclasses import dataclass, field
from functools import partial
from typing import Callable

import numpy as np

from wsnloc.errors import ConfigError
from wsnloc.estimators import robust, self_calibration
from wsnloc.estimators.motion import STEP_CACHE
from wsnloc.estimators.parameters import Param
from wsnloc.filters.kalman import innovation_covariance
from wsnloc.filters.measurement_models import RangeModel
from wsnloc.geometry.lateration import multilateration

CALIBRATION_KEYS = {"scale": "range_scale", "offset": "range_offset_m"}    # the attrs of the self-calibration states
STANDARD_GATE = 0.999     # the registry's gate (3.29 sigma): tracker, Kalman filters and the self-fit's passes
LOSS_WINDOW = 10          # updates over which the gate's rejections are judged
REFIX_RATIO = 2.0         # a fix explains the recent ranges this many times better than the track did: lost
REFIX_ANCHORS = 4         # ... a fix on the ranges of at least this many anchors

PARAMS = (
    Param("gate_probability", 0.0, "1", "innovation gate: reject a measurement whose squared normalised "
          "innovation y_i^2 / S_ii exceeds the chi-square (1 dof) quantile at this probability (0: no gate; "
          "0.999: beyond 3.29 sigma)", minimum=0.0),
    Param("robust_loss", "none", "", "M-estimator update by iteratively reweighted R: huber (convex; clean data "
          "with occasional outliers) or cauchy (redescending; frequent large outliers such as reflections)",
          str, robust.LOSSES),
    Param("robust_c", 0.0, "sigma", "loss tuning constant in units of the range sigma (0: the loss's 95% "
          "Gaussian-efficiency default, huber 1.345, cauchy 2.385)", minimum=0.0),
    Param("gate_loss_share", 0.5, "1", "gate: when it rejected more than this share of the measurements of the "
          f"last {LOSS_WINDOW} updates the position covariance is widened to cover the rejected innovations (a "
          "widening); when it does so again right after a widening (or with gate_refix at once, if a fix explains "
          "those measurements better) the track is lost: dropped (a reset) and restarted by the initiator (1: never)",
          minimum=0.0),
    Param("gate_refix", True, "", "gate: when it rejected more than gate_loss_share, drop the track at once (no "
          f"widening) if its mean |innovation| over the last {LOSS_WINDOW} updates' ranges is {REFIX_RATIO:g}x the "
          "mean |residual| of a fix on them: a track ranged one anchor at a time that passed close to an anchor "
          "can take the mirror branch, which a widening does not leave", bool),
    Param("range_self_calibration", "none", "", "augment the state with a common range scale and/or offset "
          "(needs >= 4 anchors and a moving target; no truth)", str, self_calibration.MODES),
    Param("range_scale_sigma", 0.1, "1", "self-calibration: prior sigma of the range scale (around 1)",
          minimum=1e-9),
    Param("range_offset_sigma_m", 0.5, "m", "self-calibration: prior sigma of the range offset (around 0)",
          minimum=1e-9),
    Param("rss_site_margin_m", 2.0, "m", "RSS only: keep the position inside the receivers' bounding box "
          "enlarged by this margin (projection after each update; a large value: off)", minimum=0.0),
    Param("range_sigma_per_wall_m", 0.0, "m", "NLOS-aware noise: add this to the range sigma per campaign wall "
          "crossed by the line from the position estimate to the anchor (0: off)", minimum=0.0),
)


@dataclass
class UpdateCounts:
    """Measurements offered to and rejected by the gate over a run, and the latest
    self-calibration states (range_scale, range_offset_m)."""

    offered: int = 0
    gated: int = 0
    track_losses: int = 0
    refixes: int = 0          # the track losses found by gate_refix (a fix explained the recent ranges better)
    widenings: int = 0
    calibration: dict = field(default_factory=dict)
    # per update, gated ones included: the innovations y and their variances S_ii, one array each (two
    # lists of arrays rather than a list of pairs: a pass keeps no object per update for the garbage
    # collector to scan)
    innovation_y: list = field(default_factory=list)
    innovation_S: list = field(default_factory=list)

    def attrs(self) -> dict:
        """Counters for the estimates' attrs: gated, offered, gated_share, gate_widenings,
        gate_track_losses, gate_refixes and the self-calibration states."""
        share = self.gated / self.offered if self.offered else 0.0
        return {"gated": self.gated, "offered": self.offered, "gated_share": share, "gate_widenings": self.widenings,
                "gate_track_losses": self.track_losses, "gate_refixes": self.refixes, **self.calibration}

    def innovation_arrays(self) -> tuple[np.ndarray, np.ndarray]:
        """(y, S_ii) of every measurement offered over the run (m or dB, and its square)."""
        if not self.innovation_y:
            return np.zeros(0), np.zeros(0)
        return np.concatenate(self.innovation_y), np.concatenate(self.innovation_S)


def default_updater(p: dict) -> Callable:
    """The configured gate and robust update: robust.robust_update with gate_probability,
    robust_loss and robust_c (0: the loss's default tuning)."""
    loss = p["robust_loss"]
    options = robust.UpdateOptions(p["gate_probability"], loss, p["robust_c"] or robust.DEFAULT_TUNING.get(loss, 0.0))
    return partial(robust.robust_update, options=options)


class ConfiguredFilter:
    """A filter with the configured update options (see the module docstring); `updater`: the
    gate and robust update (default default_updater(p))."""

    def __init__(self, filt, p: dict, counts: UpdateCounts, campaign=None, updater: Callable | None = None,
                 bounds: np.ndarray | None = None):
        self.filt, self.counts, self.campaign, self.bounds = filt, counts, campaign, bounds
        self.loss_share, self.refix = p["gate_loss_share"], p["gate_refix"]
        self.recent: deque = deque(maxlen=LOSS_WINDOW)   # (offered, gated, max y^2 / S) of the last updates
        self.recent_models: deque = deque(maxlen=LOSS_WINDOW)     # their (measurement model, innovations y)
        self.lost = self.widened = False
        self.gate_probability = p["gate_probability"] or STANDARD_GATE
        self.gated_filter = any(p[k] != off for k, off in OFF.items())
        self.mode = p["range_self_calibration"]
        self.extra = len(self_calibration.extra_states(self.mode))
        self.calibration_keys = [CALIBRATION_KEYS[name] for name in self_calibration.extra_states(self.mode)]
        self.updater = updater or default_updater(p)
        self.per_wall = p["range_sigma_per_wall_m"]
        self.used, self.kept = 0, None
        self._augmented: dict = {}      # id of (F, Q, B) -> ((F, Q, B), their augmentation)

    # -- the interface the filter loops use --
    @property
    def x(self) -> np.ndarray:
        return self.filt.x

    @property
    def P(self) -> np.ndarray:
        return self.filt.P

    @property
    def nis(self) -> float:
        return self.filt.nis if self.used else float("nan")

    def predict(self, F, Q, u=None, B=None) -> None:
        if self.extra:
            F, Q, B = self._augment(F, Q, B)
        self.filt.predict(F, Q, u=u, B=B)

    def _augment(self, F, Q, B) -> tuple:
        """self_calibration.augment_motion of (F, Q, B), kept for the next steps with the same
        matrices (motion.MotionModel.matrices shares them per step length: a sequential filter
        meets the few intervals of its anchors' schedule again and again). Keyed by the matrices'
        identity; each entry holds the matrices themselves, so no other arrays can take their
        ids while it is kept; at most motion.STEP_CACHE entries."""
        key = (id(F), id(Q), id(B))
        if key not in self._augmented:
            if len(self._augmented) >= STEP_CACHE:
                self._augmented.clear()
            self._augmented[key] = ((F, Q, B), self_calibration.augment_motion(F, Q, B, self.extra))
        return self._augmented[key][1]

    def update_model(self, model) -> None:
        """Linearise at the prior (calibration states applied), set the per-link noise, then
        the gated / robust update; `used` = measurements kept; `lost` when the gate rejected
        more than gate_loss_share of the last LOSS_WINDOW updates' measurements again right after
        a widening (widen: the first time, the covariance is widened instead). The innovations
        y = z - h(x-) and their variances S_ii = (H P- H' + R)_ii are recorded (counts) for the
        maximum-likelihood noise fit (estimators.self_fit)."""
        R = self.noise(model)
        if hasattr(self.filt, "linearise"):     # the UKF: statistical linear regression over its sigma points
            hx, H, omega = self.filt.linearise(lambda X: self_calibration.h_many(model, X, self.mode))
            R = R + omega
        else:
            hx, H = self_calibration.linearise(model, self.filt.x, self.mode)
        y = model.z - hx
        S = innovation_covariance(self.filt.P, H, R)
        variances = np.diag(S)
        self.counts.innovation_y.append(y)
        self.counts.innovation_S.append(variances)
        keep = self.updater(self.filt, model.z, H, R, hx, S=S)
        if self.bounds is not None:         # estimate projection onto the site box
            self.filt.x[:2] = np.clip(self.filt.x[:2], self.bounds[0], self.bounds[1])
        offered = len(keep)
        self.kept = keep                # which of the model's rows were used (core.Support)
        self.used = used = int(np.count_nonzero(keep))
        if self.gated_filter:            # offered / gated count what a gate saw (the bare array EKF has none)
            self.counts.offered += offered
            self.counts.gated += offered - used
        if self.extra:
            self.counts.calibration = dict(zip(self.calibration_keys, self.filt.x[-self.extra:].tolist()))
        self.recent.append((offered, offered - used, float((y**2 / variances).max(initial=0.0))))
        if self.refix:                  # what fix_explains_better reads; nothing to keep without it
            self.recent_models.append((model, y))
        if len(self.recent) < LOSS_WINDOW:
            return
        if sum(r[1] for r in self.recent) > self.loss_share * sum(r[0] for r in self.recent):
            refix = not self.widened and self.refix and self.fix_explains_better()
            if self.widened or refix:
                self.lost = True        # the deleter drops the track (core.update_step, CoastingDeleter)
                self.counts.track_losses += 1
                self.counts.refixes += refix
            else:
                self.widen()
        else:
            self.widened = False

    def fix_explains_better(self) -> bool:
        """Whether a position fix explains the recent updates' ranges better than the track did.
        Over the ranges of the last LOSS_WINDOW updates, as horizontal distances d_i to their
        anchors a_i: the track's mean |y_i|, its innovations (the prior's range error, each at
        its own time, what the gate judged), against mean_i |d_i - ||p_fix - a_i||| with p_fix
        the multilateration of the per-anchor means; True when the track's is REFIX_RATIO times
        larger. The fix is one point for the whole window, so on a moving target its residuals
        carry the motion and the track's do not: the test leans to the track. Ranged one anchor
        at a time, a track that passes close to an anchor can take the mirror branch, where two
        anchors' circles meet again: those two keep it there, the gate rejects the rest, and after
        a widening their next ranges shrink the covariance again before the others are taken
        back (simulated walks: 12-15 s, up to 35 m off). False (widen) unless every recent update
        is of ranges alone, with a 2-D state, from at least REFIX_ANCHORS anchors (with 3 the fix
        meets every anchor's mean range but for one degree of freedom: it would explain any
        ranges)."""
        models = [model for model, _ in self.recent_models]
        parts = [part for model in models for part in getattr(model, "parts", [model])]
        if not all(isinstance(part, RangeModel) and part.anchors.shape[1] == 2 for part in parts):
            return False
        anchors = np.vstack([part.anchors for part in parts])
        names, which = np.unique(anchors, axis=0, return_inverse=True)
        if len(names) < REFIX_ANCHORS:
            return False
        z = np.concatenate([model.z for model in models])
        dz = np.concatenate([np.zeros(len(part.anchors)) if part.dz_m is None else part.dz_m for part in parts])
        d = np.sqrt(np.maximum(z**2 - dz**2, 0.0))
        which = which.ravel()
        fix = multilateration(names, np.bincount(which, d) / np.bincount(which))
        if fix is None:
            return False
        track = np.mean(np.abs(np.concatenate([y for _, y in self.recent_models])))
        return bool(track > REFIX_RATIO * np.mean(np.abs(d - np.hypot(*(fix - anchors).T))))

    def widen(self) -> None:
        """The gate rejected most recent measurements: the model, not the data, is wrong (a turn the
        motion model did not expect, a bias, a gap). The position covariance is scaled by the largest
        recent normalised innovation squared y^2 / S over the gate's threshold (at least 4), so the
        rejected measurements fall inside the gate again and the track is pulled back instead of
        dropped; the window starts afresh."""
        worst = max(d2 for _, _, d2 in self.recent)
        factor = max(worst / robust.gate_threshold(self.gate_probability), 4.0)
        self.filt.P[:2, :] *= np.sqrt(factor)
        self.filt.P[:, :2] *= np.sqrt(factor)
        self.widened = True
        self.recent.clear()
        self.counts.widenings += 1

    def noise(self, model) -> np.ndarray:
        """R of the model (not to be written to); with range_sigma_per_wall_m the range rows get
        sigma + n_walls * per_wall."""
        if not self.per_wall:
            return model.R()
        R = np.array(model.R(), dtype=float)
        k = 0
        for part in getattr(model, "parts", [model]):
            if isinstance(part, RangeModel):
                m = len(part.anchors)
                walls = np.array([self.campaign.walls_between(self.filt.x[None, :2], a)[0] for a in part.anchors])
                sigma = part.sigma_m + walls * self.per_wall          # (m,): sigma_m (m,) or one for all
                R[k:k + m, k:k + m] = np.diag(sigma**2)
            else:
                m = len(part.R())
            k += m
        return R



OFF = {"gate_probability": 0.0, "robust_loss": "none", "range_self_calibration": "none",
       "range_sigma_per_wall_m": 0.0}


def site_bounds(anchor_xy: np.ndarray, p: dict) -> np.ndarray | None:
    """[[x_min, y_min], [x_max, y_max]] (m) of the RSS site bound (module docstring): the
    anchors' bounding box enlarged by rss_site_margin_m; None when the filter reads ranges."""
    if p.get("measurements") != "rss" or not len(anchor_xy) or p.get("filter") == "pf":
        return None                     # (a particle filter has no linearised update to project)
    margin = p["rss_site_margin_m"]
    return np.array([anchor_xy.min(0) - margin, anchor_xy.max(0) + margin])


def configured_factory(make, p: dict, counts: UpdateCounts, campaign=None, updater: Callable | None = None,
                       bounds: np.ndarray | None = None):
    """Wrap a filter factory make(x0, P0, motion) so that its filters have the update options
    (updater: the gate and robust update, default default_updater(p); bounds: site_bounds); with
    every option off, the factory itself (any filter, linearised or not)."""
    active = [k for k, off in OFF.items() if p[k] != off] + (["rss_site_margin_m"] if bounds is not None else [])
    if not active:
        return make
    if p["range_sigma_per_wall_m"] and (campaign is None or campaign.walls.size == 0):
        raise ConfigError("config key 'range_sigma_per_wall_m': NLOS-aware noise needs the campaign's walls "
                          f"({'no campaign' if campaign is None else campaign.source + ' has none'})")

    def factory(x0: np.ndarray, P0: np.ndarray, motion):
        x, P = self_calibration.augment_prior(x0, P0, p["range_self_calibration"], p["range_scale_sigma"],
                                              p["range_offset_sigma_m"])
        filt = make(x, P, _AugmentedMotion(motion, len(x) - len(x0)))
        if not hasattr(filt, "update"):
            raise ConfigError(f"config key '{active[0]}': the update options need a linearised filter with "
                              f"update(z, H, R, hx) (filter {p['filter']!r} has none)")
        return ConfiguredFilter(filt, p, counts, campaign, updater, bounds)
    return factory


@dataclass(frozen=True)
class _AugmentedMotion:
    """A motion model whose matrices cover the calibration states too (for the factory's F, Q)."""

    motion: object
    extra: int

    @property
    def period_s(self) -> float:
        return self.motion.period_s

    def matrices(self, dt: float):
        return self_calibration.augment_motion(*self.motion.matrices(dt), self.extra)
