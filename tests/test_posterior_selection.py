"""Tests for freqbrdf.studies.posterior_selection: views chosen by the error the fit's posterior expects."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from freqbrdf.estimate.optimise.posterior import PRIOR_PRECISION
from freqbrdf.studies.posterior_selection import (
    capture_information,
    greedy_posterior_selection,
    mean_expected_error,
    view_information,
)


def test_view_information_sums_each_pairs_channels_into_its_texel_and_view() -> None:
    rng = np.random.default_rng(0)
    jacobian = rng.normal(size=(4, 3, 5))
    slot, view, s2 = np.array([0, 0, 1, 1]), np.array([0, 2, 2, 2]), np.array([0.5, 2.0])
    info = view_information(jacobian, slot, view, s2, n_views=3)
    assert info.shape == (2, 3, 5, 5)
    np.testing.assert_allclose(info[0, 0], jacobian[0].T @ jacobian[0] / 0.5)
    np.testing.assert_allclose(info[1, 2], (jacobian[2].T @ jacobian[2] + jacobian[3].T @ jacobian[3]) / 2.0)
    assert not info[0, 1].any() and not info[1, 0].any()
    with pytest.raises(ValueError, match="residual variance 0.0 of texel 1"):
        view_information(jacobian, slot, view, np.array([0.5, 0.0]), n_views=3)
    with pytest.raises(ValueError, match="views 0..2 of 2"):
        view_information(jacobian, slot, view, s2, n_views=2)


def test_the_prior_alone_expects_its_own_variance() -> None:
    precision = np.broadcast_to(PRIOR_PRECISION * np.eye(5), (7, 5, 5))
    assert mean_expected_error(precision) == pytest.approx(1.0 / PRIOR_PRECISION)


def test_greedy_selection_takes_the_view_that_informs_what_is_still_unknown() -> None:
    """View 0 constrains the base colour, view 1 roughness and metallic, view 2 the base colour
    again, 10 times more strongly than view 0: from view 0, view 1 lowers the expected error more
    than the stronger view 2 (which only sharpens what is known). From nothing view 1 also goes
    first: roughness and metallic are two of the error's three groups, the base colour one."""
    n_texels = 3
    info = np.zeros((n_texels, 3, 5, 5))
    info[:, 0, :3, :3] = 100.0 * np.eye(3)
    info[:, 1, 3:, 3:] = 100.0 * np.eye(2)
    info[:, 2, :3, :3] = 1000.0 * np.eye(3)
    picks, errors = greedy_posterior_selection(info, 2, chosen=[0])
    assert picks == [1]
    prior = PRIOR_PRECISION
    with_0 = (1 / (prior + 100) + 1 / prior + 1 / prior) / 3
    with_01 = (1 / (prior + 100) + 2 / (prior + 100)) / 3
    np.testing.assert_allclose(errors, [with_0, with_01])
    picks, errors = greedy_posterior_selection(info, 3)
    assert picks == [1, 2, 0]
    np.testing.assert_allclose(errors, [1 / prior, (1 / prior + 2 / (prior + 100)) / 3,
                                        (1 / (prior + 1000) + 2 / (prior + 100)) / 3,
                                        (1 / (prior + 1100) + 2 / (prior + 100)) / 3])
    with pytest.raises(ValueError, match="k = 4 views of 3"):
        greedy_posterior_selection(info, 4)


@pytest.fixture(scope="module")
def recovery_fit(repo):
    """``freq_noshadow`` fitted on every view of the recovery capture (without shadowing the light
    terms do not depend on roughness, so a fit and `capture_information` evaluate the same model)."""
    from freqbrdf.estimate.optimise.model import estimate_light
    from freqbrdf.estimate.optimise.settings import OptimiseSettings
    from freqbrdf.estimate.optimise.solve import optimise
    from freqbrdf.studies.recovery_capture import capture_observations, oracle_capture

    env = np.random.default_rng(3).uniform(0.05, 1.0, (32, 64, 3))
    capture, _ = oracle_capture(env, 7)
    obs = capture_observations(capture)
    config = yaml.safe_load((repo / "config" / "config.yaml").read_text())["optimise"]
    settings = OptimiseSettings.from_config(config | {"lmax": 10, "iterations": 30, "variance_scale": 1.0}, workers=1)
    method = "freq_noshadow"
    light, e = estimate_light(env, obs, method, 10, config["point_sources"])
    return obs, optimise(obs, e, light, method=method, settings=settings), light, e, settings, method


def test_with_every_view_the_information_rebuilds_the_fits_own_posterior(recovery_fit) -> None:
    """Round trip: the information of every view, at the fit's estimate and with every view's
    residuals, summed with the prior, is the precision whose inverse the fit reports as its
    variance (`optimise`'s ``std``, variance scale 1)."""
    from freqbrdf.studies.recovery_capture import N_VIEWS

    obs, fit, light, e, settings, method = recovery_fit
    info = capture_information(obs, range(N_VIEWS), fit.params, light, e, settings, method=method,
                               min_pilot_views=1)
    variance = np.diagonal(np.linalg.inv(PRIOR_PRECISION * np.eye(5) + info.sum(axis=1)), axis1=1, axis2=2)
    std = np.column_stack([fit.std["base_color"], fit.std["roughness"], fit.std["metallic"]])
    seen = obs.observed
    assert seen.sum() > 50
    np.testing.assert_allclose(np.sqrt(variance[seen]), std[seen], rtol=1e-3)


def test_the_views_not_taken_are_never_read(recovery_fit) -> None:
    """Only the pilot views' radiance enters: replacing every other view's with noise changes nothing;
    a pilot that sees no texel is named."""
    from dataclasses import replace

    obs, fit, light, e, settings, method = recovery_fit
    pilot = [0, 3, 7, 12, 18]
    info = capture_information(obs, pilot, fit.params, light, e, settings, method=method)
    noisy = np.random.default_rng(5).uniform(0.0, 10.0, np.shape(obs.radiance))
    noisy[:, pilot] = np.asarray(obs.radiance)[:, pilot]
    np.testing.assert_array_equal(capture_information(replace(obs, radiance=noisy), pilot, fit.params, light, e,
                                                      settings, method=method), info)
    assert np.any(info[:, pilot[0]]) and np.any(info[:, 1])  # geometry alone informs the views not taken
    nothing = replace(obs, weight=np.where(np.arange(np.shape(obs.weight)[1]) == 0, 0.0, obs.weight))
    with pytest.raises(ValueError, match=r"no texel is seen by the pilot views \[0\]"):
        capture_information(nothing, [0], fit.params, light, e, settings, method=method)
