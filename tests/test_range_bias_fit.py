"""metrics.ranging.fit_range_bias (iteratively reweighted least squares) against the
reference it replaces: scipy.optimize.least_squares with the soft-L1 loss."""

import numpy as np
import pytest
from scipy.optimize import least_squares
from scipy.stats import median_abs_deviation

from wsnloc.metrics.ranging import fit_range_bias


def scipy_fit(r, d, ids) -> dict:
    """The former implementation: soft-L1 least_squares from the ordinary fit, f = normalised MAD."""
    anchors, column = np.unique(ids, return_inverse=True)
    design = np.zeros((len(r), 1 + len(anchors)))
    design[:, 0] = d
    design[np.arange(len(r)), 1 + column] = 1.0
    start, *_ = np.linalg.lstsq(design, r, rcond=None)
    f_scale = max(median_abs_deviation(r - design @ start, center=lambda x, axis: 0.0, scale="normal"), 1e-3)
    fit = least_squares(lambda q: design @ q - r, start, loss="soft_l1", f_scale=f_scale)
    residual = r - design @ fit.x
    return {"scale": fit.x[0], "offsets_m": dict(zip(map(str, anchors), fit.x[1:])),
            "sigma_m": median_abs_deviation(residual, scale="normal"), "samples": len(r)}


def ranges(n: int, anchors: int, scale: float, outlier_share: float, seed: int):
    """n ranges r = scale d + b_a + noise (0.05 m), a share of them NLOS (+0.5 .. 4 m), their
    distances and anchors, and the offsets b_a (m)."""
    rng = np.random.default_rng(seed)
    ids = rng.choice([f"A{k}" for k in range(anchors)], n)
    offsets = {f"A{k}": rng.uniform(-0.3, 0.3) for k in range(anchors)}
    d = rng.uniform(0.5, 40.0, n)
    r = scale * d + np.array([offsets[a] for a in ids]) + rng.normal(0.0, 0.05, n)
    nlos = rng.random(n) < outlier_share
    r[nlos] += rng.uniform(0.5, 4.0, nlos.sum())
    return r, d, ids, offsets


@pytest.mark.parametrize("case", [
    dict(n=4000, anchors=6, scale=1.0, outlier_share=0.0, seed=1),      # clean
    dict(n=4000, anchors=8, scale=1.02, outlier_share=0.05, seed=2),    # biased, a few NLOS
    dict(n=3000, anchors=12, scale=0.97, outlier_share=0.4, seed=3),    # outlier-heavy
    dict(n=9, anchors=3, scale=1.01, outlier_share=0.2, seed=4),        # few samples
])
def test_fit_equals_scipy_soft_l1(case):
    r, d, ids, _ = ranges(**case)
    fit, reference = fit_range_bias(r, d, ids), scipy_fit(r, d, ids)
    assert fit["samples"] == reference["samples"]
    assert fit["offsets_m"].keys() == reference["offsets_m"].keys()
    assert fit["scale"] == pytest.approx(reference["scale"], abs=1e-9)
    for anchor, offset in reference["offsets_m"].items():
        assert fit["offsets_m"][anchor] == pytest.approx(offset, abs=1e-8)
    assert fit["sigma_m"] == pytest.approx(reference["sigma_m"], abs=1e-8)


def test_fit_recovers_scale_and_offsets_despite_nlos():
    r, d, ids, offsets = ranges(n=6000, anchors=4, scale=1.03, outlier_share=0.05, seed=5)
    fit = fit_range_bias(r, d, ids)
    assert fit["scale"] == pytest.approx(1.03, abs=2e-3)
    assert fit["sigma_m"] == pytest.approx(0.05, rel=0.3)      # the NLOS share widens the MAD a little
    for anchor, offset in offsets.items():
        assert fit["offsets_m"][anchor] == pytest.approx(offset, abs=0.05)   # NLOS shift a mean by ~0.11 m


def test_fit_needs_more_samples_than_unknowns_and_two_distances():
    with pytest.raises(ValueError):
        fit_range_bias([1.0, 2.0, 3.0], [1.0, 2.0, 3.0], ["A", "B", "C"])
    with pytest.raises(ValueError):
        fit_range_bias([1.0, 1.1, 0.9, 1.0], [1.0, 1.0, 1.0, 1.0], ["A", "A", "A", "A"])


@pytest.mark.parametrize("seed, outlier_share", [(6, 0.05), (7, 0.4)])
def test_fit_is_a_stationary_point_of_the_soft_l1_cost(seed, outlier_share):
    """sum_i w_i e_i (d_i, 1_a(i)) = 0 with w_i = 1 / sqrt(1 + (e_i / f)^2), to rounding: the
    IRLS fit is the minimiser itself (scipy's stops when the cost stalls, ~1e-8 m away)."""
    r, d, ids, _ = ranges(n=20000, anchors=10, scale=1.01, outlier_share=outlier_share, seed=seed)
    fit = fit_range_bias(r, d, ids)
    anchors, column = np.unique(ids, return_inverse=True)
    design = np.column_stack([d, (column[:, None] == np.arange(len(anchors))).astype(float)])
    start, *_ = np.linalg.lstsq(design, r, rcond=None)
    f_scale = median_abs_deviation(r - design @ start, center=lambda x, axis: 0.0, scale="normal")
    residual = r - design @ np.r_[fit["scale"], [fit["offsets_m"][a] for a in anchors]]
    gradient = design.T @ (residual / np.sqrt(1.0 + (residual / f_scale) ** 2))
    assert np.abs(gradient).max() < 1e-11 * np.abs(design).sum(axis=0).max()   # scipy: 4e-10 at seed 7
