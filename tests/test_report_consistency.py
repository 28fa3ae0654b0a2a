"""The consistency statistics on cases with known answers."""

import numpy as np
import pytest
from scipy import stats

from rapid_cosim.report.consistency import ellipse, homogeneity, weighted_mean


def test_two_estimates_in_one_dimension():
    h = homogeneity([[0.0], [2.0]], [[[1.0]], [[1.0]]])
    assert h.reference == pytest.approx([1.0])
    assert h.reference_cov == pytest.approx(np.array([[0.5]]))
    assert h.chi2 == pytest.approx(2.0) and h.dof == 1
    assert h.p_value == pytest.approx(stats.chi2.sf(2.0, 1))
    # theta_i - mean has variance 1 - 0.5: z = -1 / sqrt(0.5)
    assert h.z[:, 0] == pytest.approx([-np.sqrt(2), np.sqrt(2)])
    assert h.birge_ratio == pytest.approx(np.sqrt(2))


def test_weighted_mean_weights_by_precision():
    m, c = weighted_mean(np.array([[0.0, 0.0], [3.0, 3.0]]), np.array([np.eye(2), 2 * np.eye(2)]))
    assert m == pytest.approx([1.0, 1.0]) and c == pytest.approx(np.eye(2) * 2 / 3)


def test_homogeneous_estimates_give_chi_square_with_the_right_dof():
    rng = np.random.default_rng(1)
    d, n = 2, 8
    covs = []
    for _ in range(n):
        a = rng.normal(size=(d, d))
        covs.append(a @ a.T + 0.1 * np.eye(d))
    covs = np.array(covs)
    chi2, z = [], []
    for _ in range(2000):
        x = np.array([rng.multivariate_normal([0.05, 3.0], c) for c in covs])
        h = homogeneity(x, covs)
        chi2.append(h.chi2)
        z.append(h.z)
    chi2, z = np.array(chi2), np.array(z)
    assert h.dof == d * (n - 1)
    assert chi2.mean() == pytest.approx(d * (n - 1), rel=0.05)
    assert z.std(axis=0) == pytest.approx(np.ones((n, d)), abs=0.07)  # each z is N(0, 1)
    assert stats.kstest(stats.chi2.sf(chi2, d * (n - 1)), "uniform").pvalue > 0.01


def test_a_shifted_estimate_is_flagged():
    covs = np.array([np.eye(2) * 0.01] * 6)
    x = np.zeros((6, 2))
    x[3] = [1.0, 0.0]
    h = homogeneity(x, covs)
    assert h.p_value < 1e-6 and np.argmax(np.abs(h.z[:, 0])) == 3 and np.all(np.abs(h.z[:, 1]) < 1e-9)


def test_ellipse_is_the_level_contour():
    cov = np.array([[2.0, 0.6], [0.6, 0.5]])
    pts = ellipse([1.0, 2.0], cov, level=0.9)
    d = pts - [1.0, 2.0]
    m = np.einsum("ni,ij,nj->n", d, np.linalg.inv(cov), d)
    assert m == pytest.approx(np.full(len(pts), stats.chi2.ppf(0.9, 2)))
