"""Tests for freqbrdf.lobes: GGX's zonal SH spectrum and the table the compiled model reads."""

from __future__ import annotations

import numpy as np
import pytest

from freqbrdf import kernels
from freqbrdf.brdf import ALPHA_MIN
from freqbrdf.lobes import LOBE_NODES, ggx_lobe_spectrum, lobe_table


def ggx_spectrum_by_angles(alpha: float, lmax: int, n: int = 200_000) -> np.ndarray:
    """Independent oracle: Funk-Hecke integral of the normal-view GGX lobe ``D(h) / 4`` over the
    light direction's angle theta to the mirror direction (``theta_h = theta / 2``), midpoint rule."""
    theta = (np.arange(n) + 0.5) * np.pi / n
    ch = np.cos(theta / 2)
    d = alpha**2 / (np.pi * (ch**2 * (alpha**2 - 1) + 1) ** 2)
    weight = 2 * np.pi * d / 4 * np.sin(theta) * np.pi / n
    return np.array([weight @ np.polynomial.legendre.Legendre.basis(l)(np.cos(theta)) for l in range(lmax + 1)])


@pytest.mark.parametrize("alpha", [0.05, 0.3, 0.8])
def test_ggx_spectrum_matches_the_integral_over_angles(alpha: float) -> None:
    f, _ = ggx_lobe_spectrum(np.array([alpha]), 12)
    np.testing.assert_allclose(f[0], ggx_spectrum_by_angles(alpha, 12), atol=2e-5)
    assert f[0, 0] == 1.0  # the lobe conserves the light's power


def test_ggx_spectrum_derivative_and_limits() -> None:
    alpha = np.array([0.02, 0.2, 0.6])
    f, df = ggx_lobe_spectrum(alpha, 10)
    h = 1e-6
    fd = (ggx_lobe_spectrum(alpha + h, 10)[0] - ggx_lobe_spectrum(alpha - h, 10)[0]) / (2 * h)
    np.testing.assert_allclose(df, fd, atol=1e-6)
    # a narrow lobe passes every degree; GGX's long tails take more of the low degrees than the Gaussian
    assert ggx_lobe_spectrum(np.array([1e-3]), 10)[0].min() > 0.99
    assert f[2, 1] < np.exp(-(0.6**2)) - 0.3
    with pytest.raises(ValueError, match="alpha must be in \\(0, 1\\], got 0.0"):
        ggx_lobe_spectrum(np.array([0.3, 0.0]), 4)


def test_kernels_interpolate_the_table_between_its_nodes() -> None:
    """The model's f_l and df/dalpha at alphas between the nodes (the Hermite interpolant of
    `lobe_table`) against the spectrum computed there, through the model's radiance and gradient:
    one pair per texel, its light a single degree so that B = F sum_l f_l light_l picks f_l out."""
    lmax = 8
    table = lobe_table("ggx", lmax)
    assert table.shape == (LOBE_NODES, 2, lmax + 1)
    alpha = np.exp(np.random.default_rng(0).uniform(np.log(ALPHA_MIN), 0.0, 40))
    n = alpha.size * (lmax + 1)
    x = np.zeros((n, 5))
    x[:, 3] = np.sqrt(np.repeat(alpha, lmax + 1))
    light = np.zeros((n, lmax + 1, 3))
    light[np.arange(n), np.tile(np.arange(lmax + 1), alpha.size), :] = 1.0
    model = np.empty((n, 3))
    _, grad = kernels.l1_loss_gradient(x, np.arange(n + 1), light, np.full((n, 3), -1.0), np.zeros(n), np.zeros(n),
                                       np.zeros((n, 3)), False, ALPHA_MIN, 1.0, model, table)
    f, df = ggx_lobe_spectrum(alpha, lmax)
    np.testing.assert_allclose(model[:, 0], f.ravel(), atol=1e-6)  # F = 1 (r0 1), no diffuse
    # dL/dr = 3 sign(B - B_obs) df/dalpha 2 r, all signs +1
    np.testing.assert_allclose(grad[:, 3] / (6.0 * x[:, 3]), df.ravel(), atol=1e-4, rtol=1e-3)


def test_gaussian_table_is_the_closed_form_and_bad_names_are_named() -> None:
    assert lobe_table("gaussian", 6).shape == (0, 2, 7)
    with pytest.raises(ValueError, match="lobe must be one of \\('gaussian', 'ggx'\\), got 'phong'"):
        lobe_table("phong", 6)
    with pytest.raises(ValueError, match="lobe must be a lobe_table of degree >= 8, got shape \\(256, 2, 5\\)"):
        kernels.l1_loss_gradient(np.zeros((1, 5)), np.array([0, 1]), np.zeros((1, 9, 3)), np.zeros((1, 3)),
                                 np.zeros(1), np.zeros(1), np.zeros((1, 3)), False, ALPHA_MIN, 0.04, None,
                                 lobe_table("ggx", 4))
