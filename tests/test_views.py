"""Tests for freqbrdf.studies.views: view subsets behave like a capture with fewer views."""

import numpy as np
import pytest

from freqbrdf.artefacts import Observations
from freqbrdf.capture.observations import band_limited_envmap, sample_equirect
from freqbrdf.sphere.sampling import equirect_directions, fibonacci_hemisphere
from freqbrdf.studies.views import view_subset, view_subsets


def test_subsets_are_seeded_sorted_distinct_and_capped():
    subsets = view_subsets(24, [12, 6, 24, 30], seed=3, subsets=3)
    assert list(subsets) == [6, 12, 24]  # 30 is every view, like 24
    assert [len(v) for v in subsets.values()] == [3, 3, 1]  # every view is one subset
    assert all(len(v) == c and (np.diff(v) > 0).all() for c, draws in subsets.items() for v in draws)
    np.testing.assert_array_equal(subsets[24][0], np.arange(24))
    assert len({tuple(v) for v in subsets[6]}) == 3  # distinct draws
    assert len(view_subsets(4, [2], seed=0, subsets=10)[2]) == 6  # as many as there are: 4 choose 2
    np.testing.assert_array_equal(view_subsets(24, [6], seed=3)[6][0], subsets[6][0])  # the seed decides
    assert not np.array_equal(view_subsets(24, [6], seed=4)[6][0], subsets[6][0])
    with pytest.raises(ValueError, match="views count must be >= 1, got 0"):
        view_subsets(24, [0], seed=0)
    with pytest.raises(ValueError, match="evaluate.views_subsets must be >= 1, got 0"):
        view_subsets(24, [6], seed=0, subsets=0)


def test_subset_keeps_its_views_and_redraws_the_light_at_its_band_limit():
    rng = np.random.default_rng(0)
    n_tex, n_views = 5, 8
    frame = np.linalg.qr(rng.normal(size=(n_tex, 3, 3)))[0]
    wo = np.broadcast_to(fibonacci_hemisphere(n_views)[:, [0, 2, 1]], (n_tex, n_views, 3)).copy()
    obs = Observations.from_arrays(rng.random((n_tex, n_views, 3)), rng.random((n_tex, n_views)), wo, frame,
                                   np.arange(n_tex), 4, a_prime=n_views**-0.5)
    env = 0.5 + equirect_directions(32, 64)[..., :1] ** 2
    sub = view_subset(obs, np.array([1, 4, 6]), env, "paper")
    np.testing.assert_array_equal(sub.radiance, obs.radiance[:, [1, 4, 6]])
    np.testing.assert_array_equal(sub.weight, obs.weight[:, [1, 4, 6]])
    assert sub.a_prime == pytest.approx(3**-0.5) and sub.meta["views"] == ["1", "4", "6"]
    # the incoming light is the map at the subset's a', along each pair's world mirror direction
    local = wo[:, [1, 4, 6]] * np.array([-1.0, -1.0, 1.0])
    world = np.einsum("tji,tkj->tki", frame, local)
    np.testing.assert_allclose(sub.incoming, sample_equirect(band_limited_envmap(env, 3**-0.5), world), rtol=1e-5)
