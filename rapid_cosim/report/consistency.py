"""Are per-test estimates consistent with one parameter vector? Gaussian statistics on
estimates with covariances (per-test Laplace approximations) and a reference (the
joint fit or the precision-weighted mean of the per-test estimates).

Homogeneity: with n independent estimates ``theta_i ~ N(theta, C_i)`` of one ``theta``
(d parameters), the precision-weighted mean ``m = C_m sum_i C_i^-1 theta_i`` with
``C_m = (sum_i C_i^-1)^-1`` is the best linear estimate, and

    chi2 = sum_i (theta_i - m)^T C_i^-1 (theta_i - m)  ~  chi-square with d (n - 1) dof.

The standardised residual of parameter k of test i is
``z_ik = (theta_ik - m_k) / sqrt((C_i - C_m)_kk)``: ``theta_i - m`` has covariance
``C_i - C_m`` (the mean contains theta_i), so each z is N(0, 1) under homogeneity.
A joint fit of all the data is, for a linear-Gaussian model, exactly ``m`` with
covariance ``C_m``; against a joint posterior mean the same formulas apply with it in
place of ``m``.

The Birge ratio ``sqrt(chi2 / dof)`` is the factor by which every per-test standard
error would have to grow for the spread to be consistent.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np
from scipy import stats


@dataclass(frozen=True)
class Homogeneity:
    reference: np.ndarray  # (d,) the mean the estimates are compared with
    reference_cov: np.ndarray  # (d, d)
    chi2: float
    dof: int
    p_value: float
    birge_ratio: float
    z: np.ndarray  # (n, d) standardised residuals
    chi2_per_estimate: np.ndarray  # (n,) each estimate's term of chi2


def weighted_mean(estimates: np.ndarray, covs: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Precision-weighted mean of estimates (n, d) with covariances (n, d, d), and its covariance."""
    P = np.linalg.inv(covs)
    cov_m = np.linalg.inv(P.sum(axis=0))
    m = cov_m @ np.einsum("nij,nj->i", P, estimates)
    return m, cov_m


def homogeneity(estimates: Sequence, covs: Sequence, reference=None, reference_cov=None) -> Homogeneity:
    """Chi-square homogeneity test and z-scores of ``estimates`` (n, d) with ``covs``
    (n, d, d) against ``reference`` (default: their precision-weighted mean).

    ``reference_cov`` is the covariance of the reference, subtracted from each ``C_i``
    for the z-scores (default: that of the weighted mean); where ``C_i - C_ref`` is not
    positive on the diagonal (a reference no better determined than the estimate),
    ``C_i`` alone is used. dof is ``d (n - 1)``: the reference is fitted to the same data.
    """
    x = np.atleast_2d(np.asarray(estimates, dtype=float))
    C = np.asarray(covs, dtype=float).reshape(x.shape[0], x.shape[1], x.shape[1])
    n, d = x.shape
    if n < 2:
        raise ValueError("homogeneity needs at least two estimates")
    m, cov_m = weighted_mean(x, C)
    ref = m if reference is None else np.asarray(reference, dtype=float)
    ref_cov = cov_m if reference_cov is None else np.asarray(reference_cov, dtype=float)
    P = np.linalg.inv(C)
    dev = x - ref
    terms = np.einsum("ni,nij,nj->n", dev, P, dev)
    chi2 = float(terms.sum())
    dof = d * (n - 1)
    var = np.einsum("nkk->nk", C) - np.diag(ref_cov)[None, :]
    var = np.where(var > 0, var, np.einsum("nkk->nk", C))
    z = dev / np.sqrt(var)
    return Homogeneity(ref, ref_cov, chi2, dof, float(stats.chi2.sf(chi2, dof)), float(np.sqrt(chi2 / dof)), z, terms)


def ellipse(mean, cov, level: float = 0.9, n: int = 100) -> np.ndarray:
    """Points (n, 2) on the ``level`` contour of a 2-D Gaussian."""
    r = np.sqrt(stats.chi2.ppf(level, 2))
    vals, vecs = np.linalg.eigh(np.asarray(cov, dtype=float))
    vals = np.clip(vals, 0.0, None)
    t = np.linspace(0, 2 * np.pi, n)
    circle = np.column_stack([np.cos(t), np.sin(t)])
    return np.asarray(mean, dtype=float) + r * (circle * np.sqrt(vals)) @ vecs.T
