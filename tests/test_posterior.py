"""Tests for freqbrdf.estimate.optimise.posterior: the Laplace posterior of the fitted parameters."""

from __future__ import annotations

import numpy as np
import pytest

from freqbrdf.estimate.optimise.posterior import (PRIOR_PRECISION, expected_error, expected_error_atlas,
                                                  laplace_variance, pair_information, pooled_residual_variance,
                                                  residual_variance, _texel_information)
from freqbrdf.report.metrics import parameter_error_map


def linear_capture(n_texels: int, seed: int, noise: float = 0.01):
    """Texels whose model radiance is linear in their 5 parameters, ``B = A_t x``, with 3-9 views
    each and Gaussian noise of the given standard deviation: the Laplace approximation is then
    the exact posterior (with the prior's Gaussian)."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(3, 10, n_texels)
    start = np.concatenate([[0], np.cumsum(counts)])
    design = rng.normal(size=(int(start[-1]), 3, 5))  # per pair and channel, d B / d x
    slot = np.repeat(np.arange(n_texels), counts)
    truth = rng.uniform(0.2, 0.8, (n_texels, 5))

    def radiance(xp: np.ndarray) -> np.ndarray:
        return np.einsum("ncq,nq->nc", design, xp[slot])

    observed = radiance(truth) + rng.normal(scale=noise, size=(int(start[-1]), 3))
    return radiance, observed, start, design, truth, slot


def test_on_a_linear_model_the_variance_is_the_closed_form_posterior() -> None:
    radiance, observed, start, design, _, slot = linear_capture(40, seed=0)
    # the least-squares estimate of each texel (ignoring the prior, as the fit does)
    estimate = np.stack([np.linalg.lstsq(design[slot == t].reshape(-1, 5), observed[slot == t].ravel(), rcond=None)[0]
                         for t in range(40)])
    variance = laplace_variance(radiance, estimate, observed, start, variance_scale=2.0)
    for t in (0, 17, 39):
        a = design[slot == t].reshape(-1, 5)
        residual = a @ estimate[t] - observed[slot == t].ravel()
        s2 = residual @ residual / (a.shape[0] - 5)
        expected = np.diag(np.linalg.inv(a.T @ a / s2 + PRIOR_PRECISION * np.eye(5)))
        np.testing.assert_allclose(variance[t], 2.0 * expected, rtol=1e-5)


def test_the_90_percent_intervals_cover_the_truth_of_a_linear_model() -> None:
    """With the noise Gaussian and the model right, about 90% of the parameters lie within
    1.645 standard deviations (the residual variance is estimated from few residuals, so a
    little under)."""
    radiance, observed, start, design, truth, slot = linear_capture(3000, seed=1, noise=0.05)
    estimate = np.stack([np.linalg.lstsq(design[slot == t].reshape(-1, 5), observed[slot == t].ravel(), rcond=None)[0]
                         for t in range(3000)])
    variance = laplace_variance(radiance, estimate, observed, start)
    covered = np.abs(estimate - truth) <= 1.645 * np.sqrt(variance)
    assert 0.85 < covered.mean() < 0.92
    assert np.corrcoef(np.abs(estimate - truth).mean(axis=1), np.sqrt(variance).mean(axis=1))[0, 1] > 0.3


def test_a_texel_the_views_do_not_constrain_keeps_the_priors_variance() -> None:
    def flat(xp: np.ndarray) -> np.ndarray:  # radiance that no parameter changes
        return np.ones((6, 3))

    variance = laplace_variance(flat, np.full((2, 5), 0.5), np.ones((6, 3)) + 0.1, np.array([0, 3, 6]))
    np.testing.assert_allclose(variance, 1.0 / PRIOR_PRECISION)
    with pytest.raises(ValueError, match="variance_scale must be a finite number > 0, got 0"):
        laplace_variance(flat, np.full((2, 5), 0.5), np.ones((6, 3)), np.array([0, 3, 6]), variance_scale=0)


def test_the_expected_error_averages_as_the_error_map_does() -> None:
    """For errors of exactly one standard deviation, the expected error is the error map."""
    rng = np.random.default_rng(2)
    variance = rng.uniform(0.0, 0.05, (16, 5))
    truth = {"base_color": np.zeros((4, 4, 3)), "roughness": np.zeros((4, 4)), "metallic": np.zeros((4, 4))}
    std = np.sqrt(variance)
    estimate = {"base_color": std[:, :3].reshape(4, 4, 3), "roughness": std[:, 3].reshape(4, 4),
                "metallic": std[:, 4].reshape(4, 4)}
    np.testing.assert_allclose(expected_error(variance), parameter_error_map(truth, estimate).ravel())


def test_the_expected_error_atlas_is_the_mean_variance_of_the_three_parameter_groups() -> None:
    """Base colour's channel variances averaged, then averaged with roughness's and metallic's
    (as the parameter error map averages squared errors): an analytic value per texel."""
    std = {"base_color": np.stack([np.full((2, 3), 0.1), np.full((2, 3), 0.2), np.full((2, 3), 0.3)], axis=-1),
           "roughness": np.full((2, 3), 0.4), "metallic": np.arange(6.0).reshape(2, 3) / 10}
    expected = ((0.01 + 0.04 + 0.09) / 3 + 0.16 + std["metallic"] ** 2) / 3
    np.testing.assert_allclose(expected_error_atlas(std), expected)


def test_the_residual_variance_divides_by_the_degrees_of_freedom_left() -> None:
    """Two pairs of texel 0 (6 residuals, 1 degree of freedom left by 5 parameters), one of texel 2
    (none left: counted as 1), none of texel 1 (no residual: the floor)."""
    residual = np.array([[1.0, 2.0, 0.0], [0.0, 0.0, 2.0], [3.0, 0.0, 0.0]])
    s2 = residual_variance(residual, np.array([0, 0, 2]), 3)
    np.testing.assert_allclose(s2, [9.0, 1e-12, 9.0])


def test_the_pooled_variance_spends_five_degrees_of_freedom_per_texel_with_a_pair() -> None:
    """Texel 0 with 3 pairs (9 residuals, 4 left), texel 2 with 1 (3 residuals, -2 left): 2 in
    all for a squared sum of 14 + 9 + 4 + 9 = 36; no pair raises."""
    residual = np.array([[1.0, 2.0, 3.0], [0.0, 0.0, 3.0], [2.0, 0.0, 0.0], [3.0, 0.0, 0.0]])
    assert pooled_residual_variance(residual, np.array([0, 0, 0, 2])) == pytest.approx(36.0 / 2.0)
    with pytest.raises(ValueError, match="no pair"):
        pooled_residual_variance(np.empty((0, 3)), np.empty(0, dtype=int))


def test_pair_information_is_the_jacobians_gram_matrix_summed_over_channels() -> None:
    """Against the explicit sum of outer products, and symmetric positive semi-definite."""
    jacobian = np.random.default_rng(3).normal(size=(4, 3, 5))
    info = pair_information(jacobian)
    expected = np.stack([sum(np.outer(j[c], j[c]) for c in range(3)) for j in jacobian])
    np.testing.assert_allclose(info, expected, rtol=1e-12)
    assert np.all(np.linalg.eigvalsh(info) > -1e-12)


def test_texel_information_in_blocks_is_the_whole_sum() -> None:
    rng = np.random.default_rng(0)
    start = np.concatenate([[0], np.cumsum(rng.integers(1, 12, 1000))])
    jacobian = rng.normal(size=(start[-1], 3, 5))
    whole = np.add.reduceat(pair_information(jacobian), start[:-1])
    np.testing.assert_array_equal(_texel_information(jacobian, start, block=33), whole)
