"""Tests for freqbrdf.studies.view_selection: the expected entropy of views not yet taken."""

import numpy as np
import pytest

from freqbrdf.sphere.sh import power_spectrum, real_sh
from freqbrdf.sphere.sampling import fibonacci_hemisphere
from freqbrdf.estimate.shfit import fit_sh, mirror_directions
from freqbrdf.estimate.spectrum import grid_entropy, spectrum_objective, spectrum_search
from freqbrdf.studies.view_selection import (
    SelectionModel,
    _degree_sums,
    _fit,
    _posterior,
    _spectra_with,
    farthest_views,
    greedy_selection,
    rank_views,
)
from freqbrdf.studies.candidates import CandidateViews
from freqbrdf.studies.expected_entropy import expected_entropy
from synthetic import random_unit

SH = {"lmax": 4, "regulariser": "exp", "lambda": 1e-3, "penalise_dc": False}
SPECTRUM = {"n_ks": 4, "n_alpha": 4, "sigma": 0.01, "combine": "min", "normalise": "light"}


def scene(n_tex=12, n_views=10, seed=0, known=True):
    """Texels with random frames seen by distant cameras on a hemisphere, under a few lamps."""
    rng = np.random.default_rng(seed)
    frame = np.linalg.qr(rng.normal(size=(n_tex, 3, 3)))[0].transpose(0, 2, 1)  # rows: local axes
    cameras = fibonacci_hemisphere(n_views)
    wo_local = np.einsum("tij,kj->tki", frame, cameras)
    weight = np.clip(wo_local[..., 2], 0.0, None)
    world = np.einsum("tji,tkj->tki", frame, mirror_directions(wo_local))
    lamps = random_unit((3,), rng)  # (3 lamps, xyz)
    incoming = 0.2 + np.exp((world @ lamps.T - 1.0) / 0.3) @ rng.uniform(0.5, 2.0, (3, 3))
    ks = rng.uniform(0.2, 1.0, (n_tex, 1, 1))
    radiance = 0.3 * rng.uniform(size=(n_tex, 1, 3)) + ks * incoming
    return CandidateViews(weight, wo_local, incoming, tuple(f"{k:02d}" for k in range(n_views)),
                          radiance * (weight > 0)[..., None], np.full(n_views, known))


def model(posterior_min_views=2, sh=SH):
    return SelectionModel.from_config(sh, SPECTRUM, a_prime=0.2, posterior_min_views=posterior_min_views)


@pytest.mark.parametrize("penalise_dc", [False, True])
def test_one_more_sample_updates_the_fit_exactly(penalise_dc):
    sh = {**SH, "penalise_dc": penalise_dc}
    m = model(sh=sh)
    views = scene(n_views=8)
    y = real_sh(mirror_directions(views.wo_local), 4)
    chosen, extra = [0, 2, 3, 5], [1, 4, 6, 7]
    inverse, coeffs, seen = _fit(y[:, chosen], views.weight[:, chosen], views.incoming[:, chosen], m.regulariser,
                                 m.lam)
    spectra = _spectra_with(inverse, coeffs, y[:, extra], views.weight[:, extra], views.incoming[:, extra], 4)
    for j, view in enumerate(extra):
        keep = chosen + [view]
        direct = fit_sh(mirror_directions(views.wo_local[:, keep]), views.incoming[:, keep], views.weight[:, keep],
                        4, "exp", 1e-3, penalise_dc=penalise_dc)
        ok = seen | penalise_dc
        np.testing.assert_allclose(spectra[ok, j], power_spectrum(direct)[ok], rtol=1e-7, atol=1e-12)


def test_kernel_matches_its_reference_and_a_delta_posterior_gives_that_hypothesis_entropy():
    rng = np.random.default_rng(1)
    m = model()
    filters = m.filters  # (G, lmax)
    n_grid = len(filters)
    s = rng.uniform(0.0, 0.3, (40, 4)) * np.exp(-0.5 * np.arange(4))
    posterior = rng.dirichlet(np.full(n_grid, 0.3), size=40)
    posterior[:n_grid] = np.eye(n_grid)  # delta posteriors at every hypothesis
    posterior[-1] = 1.0 / n_grid
    sparse = posterior[n_grid : n_grid + 10] * (rng.random((10, n_grid)) < 0.3)  # most hypotheses ruled out
    posterior[n_grid : n_grid + 10] = sparse / sparse.sum(axis=1, keepdims=True)
    rows = np.arange(40)
    compiled = expected_entropy(s**2, posterior, rows, filters, 0.01)
    np.testing.assert_allclose(compiled, expected_entropy(s**2, posterior, rows, filters, 0.01, compiled=False),
                               atol=1e-7)
    # With all mass on hypothesis i, the search of the noise-free spectra S_B = m_i S_L finds H_i.
    for i in range(n_grid):
        b = (filters[i] * s[i])[None, :, None]
        objective = spectrum_objective(b, s[i][None, :, None], m.ks, m.alpha)
        assert compiled[i] == pytest.approx(grid_entropy(objective, 0.01)[0, 0], abs=1e-5)
    assert np.all((compiled >= 0) & (compiled <= 1))


def test_a_view_that_sees_no_texel_decreases_nothing():
    views = scene()
    hidden = views.weight.copy()
    hidden[:, 7] = 0.0
    views = CandidateViews(hidden, views.wo_local, views.incoming, views.names, views.radiance, views.known)
    ranking = rank_views(model(), views, chosen=[0, 1, 2, 3])
    assert ranking.decrease[7] == 0.0
    assert ranking.decrease[[0, 1, 2, 3]].tolist() == [0.0] * 4  # chosen already
    assert ranking.decrease.max() > 0.0


def test_expected_entropy_with_a_view_is_that_of_the_set_with_it():
    # Planning (unknown images): the entropy expected with view j added, by the rank-one
    # update, is the current expected entropy of the set with j taken (a fresh fit).
    views = scene(known=False)
    views = CandidateViews(views.weight, views.wo_local, views.incoming, views.names, views.radiance,
                           np.arange(10) < 4)
    m = model()
    ranking = rank_views(m, views, chosen=[0, 1, 2, 3])
    brute = [rank_views(m, views, chosen=[0, 1, 2, 3, j]).current for j in range(4, 10)]
    np.testing.assert_allclose(ranking.expected[4:], brute, atol=1e-9)
    picks, rankings = greedy_selection(m, views, 2, chosen=[0, 1, 2, 3])
    assert picks[0] == 4 + int(np.argmin(brute)) and len(rankings) == 3
    assert rankings[1].current == pytest.approx(ranking.expected[picks[0]])


def test_greedy_from_nothing_starts_with_the_widest_view_and_never_repeats():
    views = scene(n_views=8)
    picks, rankings = greedy_selection(model(), views, 8)
    assert rankings[0].current == 1.0 and np.all(rankings[0].decrease == 0.0)  # one sample: a constant
    assert picks[0] == int(np.argmax(views.weight.sum(axis=0)))
    assert sorted(picks) == list(range(8)) and rankings[-1].current < 1.0
    # each step re-evaluates only the texels the last pick sees: the same as ranking afresh
    for i in (1, 3, 8):
        again = rank_views(model(), views, picks[:i], chunk=5)
        assert again.current == pytest.approx(rankings[i].current, abs=1e-12)
        np.testing.assert_allclose(again.expected, rankings[i].expected, atol=1e-12)


def test_known_views_inform_the_posterior():
    # The same views with images known (posterior from data) and unknown (uniform).
    informed, blind = scene(), scene(known=False)
    a = rank_views(model(), informed, chosen=[0, 1, 2, 3, 4])
    b = rank_views(model(), blind, chosen=[0, 1, 2, 3, 4])
    assert a.current != b.current
    assert rank_views(model(posterior_min_views=99), informed, chosen=[0, 1, 2, 3, 4]).current == b.current


def test_farthest_views_spread_out():
    d = np.array([[0.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.9, 0.1, 0.0], [-1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    np.testing.assert_array_equal(farthest_views(d, 3), [0, 1, 3])  # zenith, then opposite horizons
    assert len(farthest_views(d, 9)) == 5


def test_model_refuses_what_it_does_not_mirror():
    with pytest.raises(ValueError, match="sh.regulariser exp or constant, got 'none'"):
        model(sh={**SH, "regulariser": "none"})
    with pytest.raises(ValueError, match="spectrum.normalise: light, got 'reference'"):
        SelectionModel.from_config(SH, {**SPECTRUM, "normalise": "reference"}, 0.2, 2)


def test_posterior_is_the_likelihood_of_the_spectrum_search():
    views, m = scene(n_tex=30), model(posterior_min_views=1)
    keep = [0, 2, 4, 5, 7, 9]
    d = mirror_directions(views.wo_local[:, keep])
    w = views.weight[:, keep]
    coeffs = fit_sh(d, np.concatenate([views.radiance, views.incoming], axis=2)[:, keep], w, 4, "exp", 1e-3,
                    penalise_dc=False)
    s_b, s_l = power_spectrum(coeffs[..., :3]), power_spectrum(coeffs[..., 3:])
    search = spectrum_search(s_b, s_l, m.ks, m.alpha, sigma=0.01)
    y = real_sh(d, 4)
    _, mine, seen = _fit(y, w, np.concatenate([views.incoming, views.radiance], axis=2)[:, keep], m.regulariser,
                         m.lam)
    p = _posterior(m, _degree_sums(mine[:, None] ** 2, 4)[:, 0], seen, (w > 0).sum(axis=1))  # (T, C, G)
    np.testing.assert_array_equal(p.argmax(axis=2), search.ks_index * 4 + search.alpha_index)
    entropy = -(p * np.log(np.maximum(p, 1e-300))).sum(axis=2) / np.log(16)
    np.testing.assert_allclose(entropy, search.entropy_rgb, atol=1e-5)


_FRESH_OR_CACHED = """
import hashlib, sys
import numpy as np
from freqbrdf.studies.expected_entropy import expected_entropy
rng = np.random.default_rng(4)
filters = rng.uniform(0.0, 1.0, (64, 6))
s2 = (rng.uniform(0.0, 0.3, (300, 6)) * np.exp(-0.5 * np.arange(6))) ** 2
posterior = rng.dirichlet(np.full(64, 0.3), size=300)
print(hashlib.sha1(expected_entropy(s2, posterior, np.arange(300), filters, 0.01).tobytes()).hexdigest())
"""


def test_the_kernel_gives_the_same_bits_whether_compiled_or_loaded_from_the_cache(tmp_path):
    """As the estimators' kernels (tests/test_optimise.py): view selection ranks candidates by these
    values, so a job that compiled the kernel and one that loaded it must agree bit for bit."""
    import os
    import subprocess
    import sys
    from pathlib import Path

    env = os.environ | {"NUMBA_CACHE_DIR": str(tmp_path / "numba"),
                        "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "workflow")}
    digests = []
    for _ in range(2):  # the first compiles into the empty cache, the second loads
        done = subprocess.run([sys.executable, "-c", _FRESH_OR_CACHED], capture_output=True, text=True, env=env,
                              timeout=300)
        assert done.returncode == 0, done.stderr[-3000:]
        digests.append(done.stdout.strip().splitlines()[-1])
    assert any((tmp_path / "numba").rglob("*.nbc"))
    assert digests[0] == digests[1]
