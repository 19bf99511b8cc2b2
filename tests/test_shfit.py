"""Tests for freqbrdf.estimate.shfit (regularised SH fits of sparse weighted samples, paper Fig. 3)."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from synthetic import filter_coeffs, random_unit, upper_hemisphere
from freqbrdf.sphere import sampling, sh
from freqbrdf.estimate import shfit

LMAX = 6
A_PRIME = 24**-0.5  # band limit of 24 views (paper rule)


# --------------------------------------------------------------------------
# fitting
# --------------------------------------------------------------------------
def test_mirror_directions_reflect_about_the_normal() -> None:
    wo = random_unit((7, 5), np.random.default_rng(11))
    n = np.array([0.0, 0.0, 1.0])
    np.testing.assert_allclose(shfit.mirror_directions(wo), 2 * (wo @ n)[..., None] * n - wo, atol=1e-15)


@pytest.mark.parametrize("regulariser, lam", [("none", 0.0), ("exp", 1e-10), ("constant", 1e-10)])
def test_band_limited_function_is_recovered(regulariser: str, lam: float) -> None:
    rng = np.random.default_rng(0)
    n = sh.n_coeffs(LMAX)
    truth = rng.normal(size=(2, n, 3))
    d = np.broadcast_to(sampling.fibonacci_sphere(300), (2, 300, 3))
    values = np.einsum("tki,tic->tkc", sh.real_sh(d, LMAX), truth)
    fit = shfit.fit_sh(d, values, np.ones((2, 300)), LMAX, regulariser, lam)
    assert fit.shape == (2, n, 3)
    np.testing.assert_allclose(fit, truth, atol=1e-6)


@pytest.mark.parametrize("penalise_dc", [True, False])
@pytest.mark.parametrize("regulariser", ["exp", "constant"])
def test_dual_solver_matches_primal(regulariser: str, penalise_dc: bool) -> None:
    rng = np.random.default_rng(1)
    d = random_unit((50, 24), rng)
    w = rng.random((50, 24)) * (rng.random((50, 24)) > 0.3)
    w[3] = 0.0  # a texel without samples
    f = rng.normal(size=(50, 24, 4))

    def fit(**kw: object) -> np.ndarray:
        return shfit.fit_sh(d, f, w, LMAX, regulariser, 1e-3, penalise_dc=penalise_dc, **kw)

    primal = fit(solver="primal")
    dual = fit(solver="dual", chunk=7)
    np.testing.assert_allclose(dual, primal, rtol=1e-8, atol=1e-8 * np.abs(primal).max())
    assert np.all(dual[3] == 0.0)
    np.testing.assert_array_equal(fit(chunk=9, workers=2), fit(chunk=9))


def test_unpenalised_dc_fits_constants_exactly() -> None:
    # 24 hemisphere samples, 49 coefficients: with the paper's W_00 = 1 the
    # smoothest interpolant of constant data is not constant and leaks power
    # into degrees >= 1; with W_00 = 0 it is the constant itself.
    d = shfit.mirror_directions(upper_hemisphere(24))[None]
    w = d[..., 2] * (np.arange(24) % 5 != 0)
    f = np.full((1, 24, 1), 2.5)
    free = shfit.fit_sh(d, f, w, LMAX, "exp", 1e-3, penalise_dc=False)
    np.testing.assert_allclose(free[0, 0, 0], 2.5 * np.sqrt(4 * np.pi), rtol=1e-10)
    np.testing.assert_allclose(free[0, 1:], 0.0, atol=1e-9)
    paper = shfit.fit_sh(d, f, w, LMAX, "exp", 1e-3)
    assert paper[0, 0, 0] < 0.95 * 2.5 * np.sqrt(4 * np.pi)
    assert sh.power_spectrum(paper)[0, 1:, 0].sum() > 0.01 * sh.power_spectrum(paper)[0, 0, 0]
    np.testing.assert_array_equal(shfit.regulariser_diagonal(2, "exp", penalise_dc=False)[:2], [0.0, np.e])


@pytest.mark.parametrize("regulariser", ["exp", "constant", "none"])
def test_zero_weight_samples_do_not_change_the_fit(regulariser: str) -> None:
    # 40 usable samples for 25 coefficients: well posed even without a regulariser
    rng = np.random.default_rng(2)
    d = random_unit((5, 50), rng)
    f = rng.normal(size=(5, 50, 3))
    w = rng.random((5, 50)) + 0.1
    w[:, 40:] = 0.0
    reference = shfit.fit_sh(d[:, :40], f[:, :40], w[:, :40], 4, regulariser, 1e-3)
    garbage_f = f.copy()
    garbage_f[:, 40:] = rng.normal(size=(5, 10, 3)) * 1e6
    garbage_f[:, 45] = np.nan
    garbage_d = d.copy()
    garbage_d[:, 40:43] = 0.0  # zero-length directions (would make real_sh NaN)
    garbage_d[:, 43] = np.inf
    fit = shfit.fit_sh(garbage_d, garbage_f, w, 4, regulariser, 1e-3)
    assert np.isfinite(fit).all()
    np.testing.assert_allclose(fit, reference, rtol=1e-9, atol=1e-9 * np.abs(reference).max())


def test_weights_act_as_sample_multiplicity() -> None:
    # weight 2 on a sample == the sample taken twice with weight 1; a fit that
    # ignored or squared the weights would differ
    rng = np.random.default_rng(3)
    d = random_unit((1, 20), rng)
    f = rng.normal(size=(1, 20, 1))
    w = np.ones((1, 20))
    w[0, 4] = 2.0
    twice = shfit.fit_sh(
        np.concatenate([d, d[:, 4:5]], axis=1), np.concatenate([f, f[:, 4:5]], axis=1), np.ones((1, 21)), 4, "exp", 1e-2
    )
    weighted = shfit.fit_sh(d, f, w, 4, "exp", 1e-2)
    unweighted = shfit.fit_sh(d, f, np.ones((1, 20)), 4, "exp", 1e-2)
    np.testing.assert_allclose(weighted, twice, rtol=1e-9, atol=1e-12)
    assert np.abs(weighted - unweighted).max() > 1e-3


def test_unobserved_texel_gets_zero_coefficients() -> None:
    rng = np.random.default_rng(4)
    d = np.zeros((3, 8, 3))  # unobserved samples may have no direction at all
    d[1] = random_unit((8,), rng)
    w = np.zeros((3, 8))
    w[1] = 1.0
    f = rng.normal(size=(3, 8, 2))
    for regulariser in shfit.REGULARISERS:
        fit = shfit.fit_sh(d, f, w, 3, regulariser, 1e-3)
        assert np.all(fit[[0, 2]] == 0.0)
        assert np.abs(fit[1]).max() > 0


def test_power_spectra_are_rotation_invariant() -> None:
    rng = np.random.default_rng(5)
    d = random_unit((4, 24), rng)
    d[..., 2] = np.abs(d[..., 2])
    w = d[..., 2] * (rng.random((4, 24)) > 0.2)
    f = rng.random((4, 24, 3))  # arbitrary data: under-determined, regularised
    rotated = Rotation.random(random_state=7).apply(d.reshape(-1, 3)).reshape(d.shape)
    for regulariser in ("exp", "constant"):
        s0 = sh.power_spectrum(shfit.fit_sh(d, f, w, LMAX, regulariser, 1e-3))
        s1 = sh.power_spectrum(shfit.fit_sh(rotated, f, w, LMAX, regulariser, 1e-3))
        assert s0.shape == (4, LMAX + 1, 3)
        np.testing.assert_allclose(s1, s0, rtol=1e-8)
        # a non-invariant quantity does change, so the check has teeth
        c0 = shfit.fit_sh(d, f, w, LMAX, regulariser, 1e-3)
        c1 = shfit.fit_sh(rotated, f, w, LMAX, regulariser, 1e-3)
        assert np.abs(c1[:, 1:] - c0[:, 1:]).max() > 1e-3


def test_spectra_matches_power_per_degree() -> None:
    c = np.zeros((1, 9, 2))
    c[0, 0] = [2.0, 0.0]
    c[0, 1:4, 1] = [1.0, 2.0, 2.0]
    c[0, 4:9, 0] = 1.0
    np.testing.assert_allclose(sh.power_spectrum(c)[0], [[4.0, 0.0], [0.0, 9.0], [5.0, 0.0]])


# --------------------------------------------------------------------------
# paper Fig. 3: regulariser comparison
# --------------------------------------------------------------------------
FIG3_LTRUE = 16


@pytest.fixture(scope="module")
def sphere_quadrature() -> tuple[np.ndarray, np.ndarray]:
    pts = sampling.fibonacci_sphere(20000)
    return pts, sh.real_sh(pts, FIG3_LTRUE)


def lobe_light(rng: np.random.Generator, quadrature: tuple[np.ndarray, np.ndarray]) -> np.ndarray:
    """SH (degree FIG3_LTRUE, beyond the fit's) of a sky gradient plus four soft lights."""
    pts, y = quadrature
    radiance = 0.3 + 0.2 * pts[:, 2]
    for _ in range(4):
        centre = random_unit((), rng)
        radiance = radiance + rng.uniform(0.5, 2.0) * np.exp((pts @ centre - 1.0) / rng.uniform(0.05, 0.2))
    return y.T @ radiance * (4.0 * np.pi / len(pts))


def fig3_errors(
    seed: int, mask: str, quadrature: tuple[np.ndarray, np.ndarray], alpha: float = 0.3
) -> dict[str, float]:
    """Mean |log ratio error| of S_B/S_L over degrees 1..LMAX for the four fitting options."""
    rng = np.random.default_rng(seed)
    c_l = lobe_light(rng, quadrature)
    c_b = filter_coeffs(c_l, alpha)
    d = upper_hemisphere(100)
    w = d[:, 2].copy()  # cos theta weights
    if mask == "random":
        w[rng.choice(100, 12, replace=False)] = 0.0
    else:  # a contiguous patch of 12 samples around a random sample
        w[np.argsort(-(d @ d[rng.integers(100)]))[:12]] = 0.0
    y = sh.real_sh(d, FIG3_LTRUE)
    values = np.stack([y @ c_b, y @ c_l], axis=-1)[None]
    truth = -2.0 * (alpha * np.arange(1, LMAX + 1)) ** 2
    out = {}
    for name in ("exp", "constant", "none", "zero_pad"):
        if name == "zero_pad":
            dd, vv, ww = shfit.zero_pad_lower_hemisphere(d[None], values, w[None], 100)
            coeffs = shfit.fit_sh(dd, vv, ww, LMAX, "none")
        else:
            coeffs = shfit.fit_sh(d[None], values, w[None], LMAX, name, 1e-3)
        s = sh.power_spectrum(coeffs)[0]
        out[name] = float(np.mean(np.abs(np.log(s[1:, 0] / s[1:, 1]) - truth)))
    return out


@pytest.mark.parametrize("mask", ["random", "patch"])
def test_exp_regulariser_recovers_the_filter_best(mask: str, sphere_quadrature) -> None:
    runs = [fig3_errors(seed, mask, sphere_quadrature) for seed in range(5)]
    mean = {k: float(np.mean([r[k] for r in runs])) for k in runs[0]}
    print(f"Fig. 3 ({mask} mask), mean |log(S_B/S_L) error| over l=1..{LMAX}:", mean)
    assert all(mean["exp"] < 0.8 * v for k, v in mean.items() if k != "exp"), mean
    wins = sum(all(r["exp"] < v for k, v in r.items() if k != "exp") for r in runs)
    assert wins >= 4, runs
    assert mean["exp"] < 1.0


def test_zero_pad_appends_lower_hemisphere_zeros() -> None:
    d = upper_hemisphere(5)[None]
    dd, vv, ww = shfit.zero_pad_lower_hemisphere(d, np.ones((1, 5, 2)), np.ones((1, 5)), 7, pad_weight=0.5)
    assert dd.shape == (1, 12, 3) and vv.shape == (1, 12, 2) and ww.shape == (1, 12)
    assert np.all(dd[0, 5:, 2] < 0) and np.all(vv[0, 5:] == 0) and np.all(ww[0, 5:] == 0.5)
    np.testing.assert_allclose(np.linalg.norm(dd, axis=-1), 1.0)


# validation at the boundary
# --------------------------------------------------------------------------
def test_validation_messages_name_the_bad_value() -> None:
    d = np.zeros((2, 3, 3))  # zero directions: only acceptable where weights are 0
    f = np.zeros((2, 3, 1))
    w = np.ones((2, 3))
    with pytest.raises(ValueError, match="'bogus'"):
        shfit.fit_sh(d, f, w, 2, "bogus")
    with pytest.raises(ValueError, match="-0.5"):
        shfit.fit_sh(d, f, np.full((2, 3), -0.5), 2)
    with pytest.raises(ValueError, match=r"\(2, 4, 1\)"):
        shfit.fit_sh(d, np.zeros((2, 4, 1)), w, 2)
    bad = np.zeros((2, 3, 1))
    bad[1, 2, 0] = np.nan
    with pytest.raises(ValueError, match="nan.*texel 1, sample 2"):
        shfit.fit_sh(np.ones((2, 3, 3)), bad, w, 2)
    with pytest.raises(ValueError, match="directions.*texel 0, sample 0"):
        shfit.fit_sh(d, f, w, 2)
    with pytest.raises(ValueError, match="lam"):
        shfit.fit_sh(np.ones((2, 3, 3)), f, w, 2, "exp", 0.0)
    with pytest.raises(ValueError, match="dual"):
        shfit.fit_sh(np.ones((2, 3, 3)), f, w, 2, "none", solver="dual")


def test_spectrum_log_ratio_is_zero_for_the_truth_and_follows_a_filter() -> None:
    rng = np.random.default_rng(12)
    truth = rng.normal(size=(3, sh.n_coeffs(LMAX), 2))
    np.testing.assert_allclose(shfit.spectrum_log_ratio(truth, truth), 0.0, atol=1e-12)
    filtered = filter_coeffs(truth.transpose(1, 0, 2), 0.2).transpose(1, 0, 2)
    ratio = shfit.spectrum_log_ratio(filtered, truth)  # the filter multiplies S(l) by exp(-2 (0.2 l)^2)
    np.testing.assert_allclose(ratio[0, :, 0], -2 * (0.2 * np.arange(1, LMAX + 1)) ** 2, rtol=1e-9)


def test_fit_options_are_the_fits_of_fig3() -> None:
    rng = np.random.default_rng(13)
    d = random_unit((3, 20), rng)
    f, w = rng.normal(size=(3, 20, 2)), rng.random((3, 20))
    for option in ("exp", "constant", "none"):
        np.testing.assert_array_equal(shfit.fit_option(option, d, f, w, 4, 1e-2),
                                      shfit.fit_sh(d, f, w, 4, option, 1e-2, penalise_dc=True))
    padded = shfit.fit_sh(*shfit.zero_pad_lower_hemisphere(d, f, w, 20), 4, "none")
    np.testing.assert_array_equal(shfit.fit_option("zero_pad", d, f, w, 4), padded)
    with pytest.raises(ValueError, match="'ridge'"):
        shfit.fit_option("ridge", d, f, w, 4)
