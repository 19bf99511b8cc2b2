"""The objective on pairs laid out in SIMD lanes (freqbrdf.estimate.optimise.lanes) against the
pair-major kernel it replaces in the solver's loop (itself tested against a direct evaluation of
the model and central differences in test_optimise.py and test_point_sources.py)."""

from __future__ import annotations

import numpy as np
import pytest

from freqbrdf.estimate.optimise import kernels, lanes
from freqbrdf.sphere.lobes import lobe_table, view_table

LMAX = 8


def random_pairs(n_texels: int, n_sources: int, seed: int, min_pairs: int = 1
                 ) -> tuple[kernels.PairData, tuple | None, np.ndarray]:
    """Texels of ``min_pairs``-15 pairs in random order, random observations, light terms and
    point-source geometry (a third of the pair-sources below a horizon)."""
    rng = np.random.default_rng(seed)
    counts = rng.integers(min_pairs, 16, n_texels)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    n = int(start[-1])
    pairs = kernels.PairData(start, rng.uniform(0.0, 2.0, (n, 3)), rng.uniform(0.0, 0.3, n),
                             rng.uniform(0.0, 3.0, n), rng.uniform(0.1, 1.0, (n_texels, 3)))
    terms = rng.normal(0.3, 0.2, (n, LMAX + 1, 3)) / (1 + np.arange(LMAX + 1))[None, :, None]
    point = None
    if n_sources:
        geometry = np.stack([rng.uniform(0.0, 1.0, (n, n_sources)), rng.uniform(0.0, 0.2, (n, n_sources)),
                             rng.uniform(0.25, 2.0, (n, n_sources))], axis=-1)
        geometry[..., 2][rng.random((n, n_sources)) < 0.3] = 0.0
        src = np.concatenate([rng.uniform(0.0, 2.0, (n_texels, n_sources, 1)),
                              rng.uniform(0.0, 5.0, (n_texels, n_sources, 3))], axis=-1)
        point = (geometry, src)
    return pairs, point, terms


MODELS = {
    "paper": dict(lobe=None, view=None),
    "ggx, principled": dict(lobe=lobe_table("ggx", LMAX), view=view_table("paper", "principled", "ggx", LMAX)),
    "ggx, lambert": dict(lobe=lobe_table("ggx", LMAX), view=view_table("paper", "lambert", "ggx", LMAX)),
}


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("masking", [True, False])
@pytest.mark.parametrize("n_sources", [0, 3])
@pytest.mark.parametrize("width", [8, 5])
def test_lanes_give_the_pair_major_loss_and_gradient(name: str, masking: bool, n_sources: int, width: int) -> None:
    n_texels = 53  # a last group part-filled at either width
    pairs, point, terms = random_pairs(n_texels, n_sources, seed=n_sources + width)
    model = kernels.KernelModel(masking, point=point, **MODELS[name])
    x = np.random.default_rng(9).uniform(0.0, 1.0, (n_texels, 5))
    x[:3, 3] = [0.0, 0.01, 1.0]  # roughness at and near the alpha clamp, and at its top
    layout = lanes.pair_lanes(pairs, model, width)
    loss, grad = lanes.l1_loss_gradient_lanes(x, lanes.lane_terms(terms, layout), layout)
    expected_loss, expected_grad = kernels.l1_loss_gradient(x, terms, pairs, model)
    np.testing.assert_allclose(loss, expected_loss, rtol=1e-12)
    np.testing.assert_allclose(grad, expected_grad, rtol=1e-10, atol=1e-12 * np.abs(expected_grad).max())


def test_the_layout_holds_every_pair_once_in_its_texels_lanes() -> None:
    pairs, point, terms = random_pairs(21, 2, seed=4)
    layout = lanes.pair_lanes(pairs, kernels.KernelModel(True, point=point), 8)
    assert layout.pair.shape[1] == 8 and layout.slot_start.shape == (4,)  # 21 texels: 3 groups
    held = layout.pair[layout.pair >= 0]
    np.testing.assert_array_equal(np.sort(held), np.arange(pairs.start[-1]))
    texel = np.searchsorted(pairs.start, layout.pair, side="right") - 1
    group = np.searchsorted(layout.slot_start, np.arange(layout.pair.shape[0]), side="right") - 1
    position = group[:, None] * 8 + np.arange(8)[None, :]
    assert np.all(texel[layout.pair >= 0] == layout.order[position[layout.pair >= 0]])
    counts = np.diff(pairs.start)  # grouped by pair count: no more slots than the sorted counts need
    assert layout.pair.shape[0] == np.sort(counts)[::-1][::8].sum() and np.all(np.diff(counts[layout.order]) <= 0)
    np.testing.assert_array_equal(layout.valid, layout.pair >= 0)
    assert np.all(layout.radiance.transpose(0, 2, 1)[layout.pair < 0] == 0.0)
    np.testing.assert_array_equal(layout.geometry.transpose(0, 3, 1, 2)[layout.pair >= 0], point[0][held])
    lane = lanes.lane_terms(terms, layout)
    np.testing.assert_array_equal(lane.transpose(0, 3, 1, 2)[layout.pair >= 0], terms[held])
    assert layout.bounds[0] == 0 and layout.bounds[-1] == 3 and np.all(np.diff(layout.bounds) > 0)


def test_lane_terms_names_a_bad_shape() -> None:
    pairs, _, terms = random_pairs(10, 0, seed=1)
    layout = lanes.pair_lanes(pairs, kernels.KernelModel(True), 8)
    with pytest.raises(ValueError, match=r"terms must be \(N, L, 3\)"):
        lanes.lane_terms(terms[:5], layout)
    with pytest.raises(ValueError, match="terms must be lane_terms of these lanes"):
        lanes.l1_loss_gradient_lanes(np.zeros((10, 5)), terms, layout)


def test_the_diffuse_factors_are_exact_at_their_rank_and_the_albedo_weights_are_left_out() -> None:
    """The principled diffuse factor is of rank 3: its interpolant is a sum of 3 products exactly
    (Lambert's is no table at all); the albedo weights' specular parts are not read by the lanes."""
    view = view_table("paper", "principled", "ggx", LMAX)
    alpha, mu = lanes.view_factors(view)
    assert alpha.shape == (view.shape[0], 2, 3) and mu.shape == (3, view.shape[3])
    np.testing.assert_allclose(np.einsum("ahr,rm->ahm", alpha, mu), view[:, :, 0], rtol=0, atol=1e-12)
    assert lanes.supports(kernels.KernelModel(True, view=view))
    albedo = kernels.KernelModel(True, lobe=lobe_table("ggx", LMAX),
                                 view=view_table("albedo", "principled", "ggx", LMAX))
    assert lanes.supports(kernels.KernelModel(True)) and not lanes.supports(albedo)
    pairs, _, _ = random_pairs(10, 0, seed=1)
    with pytest.raises(ValueError, match="not view_weight albedo"):
        lanes.pair_lanes(pairs, albedo)


def test_float32_terms_give_the_float64_loss_and_gradient_within_their_rounding() -> None:
    pairs, point, terms = random_pairs(53, 3, seed=6)
    model = kernels.KernelModel(True, point=point, **MODELS["ggx, principled"])
    x = np.random.default_rng(2).uniform(0.0, 1.0, (53, 5))
    single = kernels.PairData(pairs.start, pairs.radiance.astype(np.float32), pairs.schlick.astype(np.float32),
                              pairs.tan2.astype(np.float32), pairs.irradiance_pi)
    point32 = (point[0].astype(np.float32), point[1])
    model32 = kernels.KernelModel(True, point=point32, **MODELS["ggx, principled"])
    layout = lanes.pair_lanes(single, model32)
    loss, grad = lanes.l1_loss_gradient_lanes(x, lanes.lane_terms(terms.astype(np.float32), layout), layout)
    expected_loss, expected_grad = kernels.l1_loss_gradient(x, terms, pairs, model)
    np.testing.assert_allclose(loss, expected_loss, rtol=1e-5)
    # a residual within rounding of 0 may flip its sign: compare the gradient as a whole
    assert np.abs(grad - expected_grad).max() <= 1e-3 * np.abs(expected_grad).max()


def _scene_model(dtype: str, **settings: object) -> tuple:
    from test_optimise import observations, synthetic_scene

    from freqbrdf.estimate.optimise.model import ForwardModel
    from freqbrdf.estimate.optimise.problem import build_problem
    from freqbrdf.estimate.optimise.settings import OptimiseSettings

    scene = synthetic_scene(120, 16, seed=4)
    radiance = np.random.default_rng(5).uniform(0.0, 1.5, scene["wo_local"].shape)
    settings = OptimiseSettings.paper(lobe="ggx", diffuse="principled", dtype=dtype, **settings)
    problem = build_problem(observations(scene, radiance), scene["irradiance"], dtype)
    return ForwardModel.of(problem, scene["light"], "freq", settings), settings


@pytest.mark.parametrize("solver", ["adam", "lm"])
def test_the_solvers_read_the_lanes_and_get_the_pair_major_descent(solver: str) -> None:
    """`ForwardModel.of` lays the pairs out for the default model and both solvers evaluate the objective
    from them, refits included; on a float64 problem the descent is the pair-major one's to rounding."""
    import dataclasses

    from freqbrdf.estimate.optimise.solve import _descend, _descend_lm

    model, settings = _scene_model("float64", iterations=60, refit_every=20, sweeps=8, sweep_refit_every=3)
    assert model.lane_pairs is not None
    descend = _descend if solver == "adam" else _descend_lm
    start = np.full((model.problem.n_texels, 5), 0.5)
    x, curve, _ = descend(start, model, settings)
    x_ref, curve_ref, _ = descend(start, dataclasses.replace(model, lane_pairs=None), settings)
    np.testing.assert_allclose(curve, curve_ref, rtol=1e-9)
    np.testing.assert_allclose(x, x_ref, atol=1e-9)


def test_the_lane_copy_follows_every_refit() -> None:
    from freqbrdf.estimate.optimise.solve import _RefittedTerms

    model, settings = _scene_model("float32")
    xp = np.full((model.problem.n_texels, 5), 0.5)
    light = _RefittedTerms(xp, model, settings)
    xp[::3, 3] = 0.9  # a third of the texels move
    assert light.refit(xp) > 0
    np.testing.assert_array_equal(light.lane, lanes.lane_terms(light.terms, model.lane_pairs))


def test_the_lanes_refuse_another_model_and_a_factor_of_high_rank() -> None:
    from freqbrdf.estimate.optimise.model import _objective

    model, _ = _scene_model("float64")
    terms = model.light_terms(np.full(model.problem.n_texels, 0.5), 1)
    lane = model.lane_terms(terms)
    other = kernels.KernelModel(False, model.kernel.lobe, model.kernel.view, model.kernel.point)
    with pytest.raises(ValueError, match="the lanes of another model"):
        _objective(np.full((model.problem.n_texels, 5), 0.5), model.problem, terms, other, 0.0,
                   (model.lane_pairs, lane))
    noise = np.random.default_rng(0).uniform(0.5, 1.0, (64, 2, 1, 65))  # a diffuse factor of full rank
    assert lanes.view_factors(noise) is None and not lanes.supports(kernels.KernelModel(True, view=noise))


def test_the_lanes_results_do_not_depend_on_the_threads() -> None:
    import numba

    from freqbrdf.util.threads import set_threads

    pairs, point, terms = random_pairs(300, 3, seed=8)
    model = kernels.KernelModel(True, point=point, **MODELS["ggx, principled"])
    layout = lanes.pair_lanes(pairs, model, 8)  # many blocks
    lane = lanes.lane_terms(terms, layout)
    x = np.random.default_rng(3).uniform(0.0, 1.0, (300, 5))
    results, before = [], numba.get_num_threads()
    for threads in (1, 2):
        set_threads(threads)
        results.append((*lanes.l1_loss_gradient_lanes(x, lane, layout),
                        lanes.grid_search_lanes(lane, layout, np.linspace(0, 1, 5), np.linspace(0, 1, 3))))
    numba.set_num_threads(before)
    for one, two in zip(*results):
        np.testing.assert_array_equal(one, two)


@pytest.mark.parametrize("name", list(MODELS))
@pytest.mark.parametrize("n_sources", [0, 3])
@pytest.mark.parametrize("masking", [True, False])
def test_the_grid_start_from_the_lanes_is_the_pair_major_one(name: str, n_sources: int, masking: bool) -> None:
    # 3 pairs at least: with one, several grid points fit a texel's 3 channels exactly, a tie that rounding breaks
    pairs, point, terms = random_pairs(53, n_sources, seed=11 + n_sources, min_pairs=3)
    model = kernels.KernelModel(masking, point=point, **MODELS[name])
    layout = lanes.pair_lanes(pairs, model)
    roughness, metallic = np.linspace(0.0, 1.0, 7), np.linspace(0.0, 1.0, 5)
    got = lanes.grid_search_lanes(lanes.lane_terms(terms, layout), layout, roughness, metallic)
    expected = kernels.grid_search(terms, pairs, model, roughness, metallic)
    np.testing.assert_allclose(got, expected, rtol=1e-10, atol=1e-12)

