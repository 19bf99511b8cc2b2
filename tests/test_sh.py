"""Tests for freqbrdf.sphere.sh (real spherical harmonics) and freqbrdf.sphere.sampling (equirect quadrature, Fibonacci points)."""

from __future__ import annotations

import re

import numpy as np
import pytest
from scipy.special import sph_harm_y
from scipy.spatial.transform import Rotation

from freqbrdf.sphere import sampling, sh

LMAX = 8
K = (LMAX + 1) ** 2


def random_unit(n: int, seed: int) -> np.ndarray:
    rng = np.random.default_rng(seed)
    d = rng.normal(size=(n, 3))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def scipy_real_sh(l: int, m: int, theta: np.ndarray, phi: np.ndarray) -> np.ndarray:
    """Our real SH (no Condon-Shortley phase) from scipy's complex SH.

    scipy's sph_harm_y(l, m, theta, phi) = (-1)^m N_l^m P_l^m(cos theta) e^{i m phi}
    with P_l^m free of the (-1)^m phase, so for m > 0
    Y_l,m = sqrt(2) (-1)^m Re[sph_harm_y(l, m)], Y_l,-m = sqrt(2) (-1)^m Im[sph_harm_y(l, m)].
    """
    s = sph_harm_y(l, abs(m), theta, phi)
    if m == 0:
        return s.real
    cs = (-1.0) ** abs(m)
    return np.sqrt(2.0) * cs * (s.real if m > 0 else s.imag)


# --------------------------------------------------------------------------
# basis definition
# --------------------------------------------------------------------------
def test_real_sh_matches_scipy():
    d = random_unit(300, seed=0)
    # include the poles and the equator explicitly
    d = np.concatenate([d, [[0, 1, 0], [0, -1, 0], [1, 0, 0], [0, 0, -1]]])
    theta = np.arccos(np.clip(d[:, 1], -1, 1))
    phi = np.arctan2(d[:, 0], -d[:, 2])
    y = sh.real_sh(d, LMAX)
    assert y.shape == (d.shape[0], K)
    assert y.dtype == np.float64
    for l in range(LMAX + 1):
        for m in range(-l, l + 1):
            ref = scipy_real_sh(l, m, theta, phi)
            err = np.max(np.abs(y[:, sh.sh_index(l, m)] - ref))
            assert err < 1e-10, (l, m, err)


def test_real_sh_low_order_closed_forms():
    d = random_unit(50, seed=1)
    x, yy, z = d.T
    y = sh.real_sh(d, 1)
    k = np.sqrt(3.0 / (4.0 * np.pi))
    np.testing.assert_allclose(y[:, 0], 1.0 / np.sqrt(4.0 * np.pi), rtol=0, atol=1e-15)
    np.testing.assert_allclose(y[:, 1], k * x, rtol=0, atol=1e-14)  # (1, -1)
    np.testing.assert_allclose(y[:, 2], k * yy, rtol=0, atol=1e-14)  # (1, 0)
    np.testing.assert_allclose(y[:, 3], -k * z, rtol=0, atol=1e-14)  # (1, 1)


def test_real_sh_batch_shape_normalisation_and_lmax_prefix():
    d = random_unit(24, seed=2).reshape(2, 3, 4, 3)
    y = sh.real_sh(d, LMAX)
    assert y.shape == (2, 3, 4, K)
    np.testing.assert_allclose(y.reshape(-1, K), sh.real_sh(d.reshape(-1, 3), LMAX), atol=0)
    # non-unit vectors are normalised
    np.testing.assert_allclose(sh.real_sh(3.5 * d, LMAX), y, rtol=0, atol=1e-13)
    # a lower lmax is a prefix of the higher-lmax basis
    np.testing.assert_allclose(sh.real_sh(d, 3), y[..., :16], rtol=0, atol=1e-14)
    # many directions (spanning several internal blocks) agree with a single-block evaluation
    big = random_unit(70000, seed=3)
    yb = sh.real_sh(big, LMAX)
    pieces = np.concatenate([sh.real_sh(big[i:i + 1000], LMAX) for i in range(0, len(big), 1000)])
    np.testing.assert_allclose(yb, pieces, rtol=0, atol=1e-14)
    np.testing.assert_allclose(yb[:, 2], np.sqrt(3.0 / (4.0 * np.pi)) * big[:, 1], rtol=0, atol=1e-14)


def test_sh_index_and_degrees():
    flat = [sh.sh_index(l, m) for l in range(LMAX + 1) for m in range(-l, l + 1)]
    assert flat == list(range(K))
    assert sh.sh_index(3, -2) == 10
    deg = sh.sh_degrees(LMAX)
    assert deg.shape == (K,)
    assert all(deg[sh.sh_index(l, m)] == l for l in range(LMAX + 1) for m in range(-l, l + 1))
    with pytest.raises(ValueError):
        sh.sh_index(1, 2)


def test_angle_conversions():
    rng = np.random.default_rng(4)
    theta = rng.uniform(0, np.pi, 100)
    phi = rng.uniform(-np.pi, np.pi, 100)
    d = sh.angles_to_directions(theta, phi)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-15)
    np.testing.assert_allclose(
        d, np.stack([np.sin(theta) * np.sin(phi), np.cos(theta), -np.sin(theta) * np.cos(phi)], -1)
    )
    t2, p2 = sh.directions_to_angles(d)
    np.testing.assert_allclose(t2, theta, atol=1e-12)
    np.testing.assert_allclose(p2, phi, atol=1e-12)
    # axes: +Y pole, -Z is phi=0, +X is phi=pi/2, +Z is phi=+pi (not -pi)
    t, p = sh.directions_to_angles(np.array([[0, 1.0, 0], [0, 0, -1.0], [1.0, 0, 0], [0, 0, 1.0]]))
    np.testing.assert_allclose(t, [0, np.pi / 2, np.pi / 2, np.pi / 2], atol=1e-15)
    np.testing.assert_allclose(p, [0, 0, np.pi / 2, np.pi], atol=1e-15)
    _, p = sh.directions_to_angles(np.array([-0.0, 0.0, 1.0]))
    assert p == np.pi


# --------------------------------------------------------------------------
# orthonormality
# --------------------------------------------------------------------------
def test_orthonormal_equirect_quadrature():
    h, w = 512, 1024
    y = sh.real_sh(sampling.equirect_directions(h, w), LMAX).reshape(-1, K)
    wts = np.repeat(sampling.equirect_solid_angles(h, w), w)
    gram = (y * wts[:, None]).T @ y
    assert np.max(np.abs(gram - np.eye(K))) < 1e-3


def test_orthonormal_gauss_legendre_quadrature():
    n_t, n_p = LMAX + 4, 2 * LMAX + 4
    t, wt = np.polynomial.legendre.leggauss(n_t)
    phi = 2.0 * np.pi * np.arange(n_p) / n_p
    theta = np.arccos(t)
    d = sh.angles_to_directions(theta[:, None], phi[None, :]).reshape(-1, 3)
    wts = np.repeat(wt * 2.0 * np.pi / n_p, n_p)
    y = sh.real_sh(d, LMAX)
    gram = (y * wts[:, None]).T @ y
    assert np.max(np.abs(gram - np.eye(K))) < 1e-10


# --------------------------------------------------------------------------
# equirect grid
# --------------------------------------------------------------------------
@pytest.mark.parametrize("h, w", [(2, 1), (3, 4), (64, 128), (257, 512), (1000, 2000)])
def test_equirect_solid_angles(h, w):
    sa = sampling.equirect_solid_angles(h, w)
    assert sa.shape == (h,)
    assert np.all(sa > 0)
    assert abs(w * sa.sum() - 4.0 * np.pi) < 1e-12
    # explicit band formula: trapezoidal grid, half bands at the poles
    dth = np.pi / (h - 1)
    th = np.pi * np.arange(h) / (h - 1)
    a = np.clip(th - dth / 2, 0, np.pi)
    b = np.clip(th + dth / 2, 0, np.pi)
    np.testing.assert_allclose(sa, 2 * np.pi / w * (np.cos(a) - np.cos(b)), rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(sa[0], 2 * np.pi / w * (1 - np.cos(dth / 2)), rtol=1e-12)
    np.testing.assert_allclose(sa[0], sa[-1], rtol=1e-12)


def test_equirect_directions():
    h, w = 9, 16
    d = sampling.equirect_directions(h, w)
    assert d.shape == (h, w, 3)
    np.testing.assert_array_equal(d[0], np.tile([0.0, 1.0, 0.0], (w, 1)))
    np.testing.assert_array_equal(d[-1], np.tile([0.0, -1.0, 0.0], (w, 1)))
    th = np.pi * np.arange(h) / (h - 1)
    ph = 2 * np.pi * (np.arange(w) + 0.5) / w
    ref = np.stack(
        [
            np.sin(th)[:, None] * np.sin(ph)[None, :],
            np.broadcast_to(np.cos(th)[:, None], (h, w)),
            -np.sin(th)[:, None] * np.cos(ph)[None, :],
        ],
        axis=-1,
    )
    np.testing.assert_allclose(d, ref, rtol=0, atol=1e-15)
    np.testing.assert_allclose(np.linalg.norm(d, axis=-1), 1.0, atol=1e-15)
    # column 0 is half a pixel from phi=0 (-Z) towards +X
    _, p = sh.directions_to_angles(d[h // 2])
    np.testing.assert_allclose(p[: w // 2], ph[: w // 2], atol=1e-14)


# --------------------------------------------------------------------------
# projection
# --------------------------------------------------------------------------
def test_project_equirect_recovers_coefficients():
    h, w = 512, 1024
    rng = np.random.default_rng(5)
    coeffs = rng.normal(size=(K, 3))
    img = sh.eval_sh(coeffs, sampling.equirect_directions(h, w))
    assert img.shape == (h, w, 3)
    rec = sh.project_equirect(img, LMAX)
    assert rec.shape == (K, 3)
    assert np.max(np.abs(rec - coeffs)) < 1e-3
    rec1 = sh.project_equirect(img[..., 1], LMAX)
    assert rec1.shape == (K,)
    np.testing.assert_allclose(rec1, rec[:, 1], rtol=0, atol=1e-12)


def test_constant_map():
    c = sh.project_equirect(np.ones((256, 512)), LMAX)
    assert abs(c[0] - np.sqrt(4 * np.pi)) < 1e-12
    spec = sh.power_spectrum(c[:, None])[:, 0]
    assert spec.shape == (LMAX + 1,)
    assert abs(spec[0] - 4 * np.pi) < 1e-11
    assert np.all(spec[1:] < 1e-7)


def test_eval_sh_shapes_and_values():
    rng = np.random.default_rng(6)
    d = random_unit(40, seed=7).reshape(5, 8, 3)
    c1 = rng.normal(size=K)
    c3 = rng.normal(size=(K, 3))
    y = sh.real_sh(d, LMAX)
    f1 = sh.eval_sh(c1, d)
    f3 = sh.eval_sh(c3, d)
    assert f1.shape == (5, 8) and f3.shape == (5, 8, 3)
    np.testing.assert_allclose(f1, y @ c1, rtol=1e-13, atol=1e-13)
    np.testing.assert_allclose(f3, y @ c3, rtol=1e-13, atol=1e-13)


def test_equirect_factors_multiply_to_real_sh_on_the_grid():
    h, w, lmax = 9, 14, 5
    polar, azimuthal = sh.equirect_factors(h, w, lmax)
    y = sh.real_sh(sampling.equirect_directions(h, w), lmax)  # (h, w, n)
    for l in range(lmax + 1):
        for m in range(-l, l + 1):
            np.testing.assert_allclose(polar[:, None, m + lmax, l] * azimuthal[None, :, m + lmax],
                                       y[..., sh.sh_index(l, m)], rtol=0, atol=1e-13)
    assert np.all(polar[:, 0, :lmax] == 0.0)  # l < |m| is absent


def direct_projection(img: np.ndarray, lmax: int) -> np.ndarray:
    """``sum_pixels Y_i(d_p) f(d_p) dOmega_p``, every pixel and coefficient at once: the definition."""
    h, w = img.shape[:2]
    y = sh.real_sh(sampling.equirect_directions(h, w), lmax).reshape(h * w, -1)
    omega = np.repeat(sampling.equirect_solid_angles(h, w), w)
    return y.T @ (img.reshape(h * w, -1) * omega[:, None])


@pytest.mark.parametrize("h, w", [(64, 128), (33, 20)])
def test_project_equirect_is_the_quadrature_sum(h, w):
    img = np.random.default_rng(9).gamma(0.5, size=(h, w, 3))
    direct = direct_projection(img, LMAX)
    np.testing.assert_allclose(sh.project_equirect(img, LMAX), direct, rtol=0, atol=1e-12 * np.abs(direct).max())


def test_eval_rings_is_eval_sh_on_the_rings():
    rng = np.random.default_rng(10)
    theta, phi = rng.uniform(0.0, np.pi, 7), rng.uniform(-np.pi, np.pi, 11)
    coeffs = rng.normal(size=(K, 2))
    direct = sh.eval_sh(coeffs, sh.angles_to_directions(theta[:, None], phi[None, :]))
    np.testing.assert_allclose(sh.eval_rings(coeffs, theta, phi), direct, rtol=0, atol=1e-12)


@pytest.mark.parametrize("h, w", [(64, 128), (33, 20)])
def test_filter_equirect_equals_projection_then_evaluation(h, w):
    """The separable filter against the direct sums over every pixel and coefficient."""
    rng = np.random.default_rng(8)
    img = rng.gamma(0.5, size=(h, w, 3))  # rough: energy up to the grid's limit
    gains = np.exp(-((0.3 * np.arange(LMAX + 1)) ** 2))
    direct = sh.eval_sh(direct_projection(img, LMAX) * gains[sh.sh_degrees(LMAX)][:, None],
                        sampling.equirect_directions(h, w))
    np.testing.assert_allclose(sh.filter_equirect(img, gains), direct, rtol=0, atol=1e-12 * np.abs(direct).max())


# --------------------------------------------------------------------------
# power spectrum
# --------------------------------------------------------------------------
def test_power_spectrum_definition_and_axis():
    rng = np.random.default_rng(8)
    c = rng.normal(size=(2, K, 3))  # (batch, coefficient, channel)
    s = sh.power_spectrum(c)
    assert s.shape == (2, LMAX + 1, 3)
    ref = np.array([[[np.sum(c[t, l * l:(l + 1) ** 2, ch] ** 2) for ch in range(3)] for l in range(LMAX + 1)]
                    for t in range(2)])
    np.testing.assert_allclose(s, ref, rtol=1e-14)
    np.testing.assert_allclose(sh.power_spectrum(c, lmax=4), ref[:, :5], rtol=1e-14)


def test_power_spectrum_rotation_invariant():
    rng = np.random.default_rng(9)
    coeffs = rng.normal(size=K)
    rot = Rotation.random(random_state=10).as_matrix()
    pts = sampling.fibonacci_sphere(4000)
    # g(d) = f(R^T d); with row vectors R^T d == d @ R
    g = sh.eval_sh(coeffs, pts @ rot)
    fitted, *_ = np.linalg.lstsq(sh.real_sh(pts, LMAX), g, rcond=None)
    # the rotation really changes the coefficients ...
    assert np.max(np.abs(fitted - coeffs)) > 0.1
    # ... but not the per-degree power
    np.testing.assert_allclose(
        sh.power_spectrum(fitted[:, None]), sh.power_spectrum(coeffs[:, None]), rtol=0, atol=1e-8
    )


# --------------------------------------------------------------------------
# Fibonacci sets
# --------------------------------------------------------------------------
def test_fibonacci_sphere():
    n = 5000
    p = sampling.fibonacci_sphere(n)
    assert p.shape == (n, 3)
    np.testing.assert_allclose(np.linalg.norm(p, axis=-1), 1.0, atol=1e-14)
    assert np.all(np.abs(p.mean(axis=0)) < 1e-3)
    # uniform on the sphere: E[y^2] = E[x^2] = E[z^2] = 1/3
    np.testing.assert_allclose((p**2).mean(axis=0), 1.0 / 3.0, atol=2e-3)
    assert len(np.unique(np.round(p, 12), axis=0)) == n


def test_fibonacci_hemisphere():
    n = 3000
    p = sampling.fibonacci_hemisphere(n)
    assert p.shape == (n, 3)
    assert np.all(p[:, 1] > 0)
    np.testing.assert_allclose(np.linalg.norm(p, axis=-1), 1.0, atol=1e-14)
    # uniform on the hemisphere: y ~ U(0, 1)
    assert abs(p[:, 1].mean() - 0.5) < 1e-3
    assert abs((p[:, 1] ** 2).mean() - 1.0 / 3.0) < 1e-3
    assert np.all(np.abs(p[:, [0, 2]].mean(axis=0)) < 2e-3)
    assert np.all(np.abs((p[:, [0, 2]] ** 2).mean(axis=0) - 1.0 / 3.0) < 2e-3)


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------
def test_bad_inputs_raise():
    with pytest.raises(ValueError, match=re.escape("(5, 2)")):
        sh.real_sh(np.zeros((5, 2)), 3)
    with pytest.raises(ValueError, match=re.escape("(4, 3, 4)")):
        sh.real_sh(np.zeros((4, 3, 4)), 3)
    with pytest.raises(ValueError, match=re.escape("(7, 2)")):
        sh.eval_sh(np.zeros(16), np.zeros((7, 2)))
    with pytest.raises(ValueError, match=re.escape("(10,)")):
        sh.eval_sh(np.zeros(10), np.zeros((7, 3)))
    with pytest.raises(ValueError, match=re.escape("(32,)")):
        sh.project_equirect(np.zeros(32), 2)
    with pytest.raises(ValueError, match=re.escape("(10, 2)")):
        sh.power_spectrum(np.zeros((10, 2)))
    with pytest.raises(ValueError, match=re.escape("(9, 2)")):
        sh.power_spectrum(np.zeros((9, 2)), lmax=3)
    with pytest.raises(ValueError, match=re.escape("(9,)")):
        sh.power_spectrum(np.zeros(9))
    with pytest.raises(ValueError):
        sh.real_sh(np.zeros((5, 3)), -1)
    with pytest.raises(TypeError):
        sh.real_sh(np.zeros((5, 3)), 2.0)
    with pytest.raises(ValueError):
        sampling.equirect_solid_angles(1, 8)
