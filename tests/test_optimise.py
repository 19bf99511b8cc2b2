"""Tests for freqbrdf.estimate.optimise (forward model, analytic gradient, Adam estimator)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import oracles
from freqbrdf.estimate import light as lt
from freqbrdf.estimate.light_table import TableSize, read_light_table, shadowed_light_table, write_light_table
from freqbrdf.artefacts import Observations
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.estimate.optimise.kernels import KernelModel, LmStep
from freqbrdf.estimate.optimise.model import forward, grid_start, light_terms, loss_and_gradient, model_tables, refit_light
from freqbrdf.estimate.optimise.problem import Problem, atlas_neighbours, build_problem, pack_params, total_variation
from freqbrdf.estimate.optimise.settings import OptimiseSettings, identifiable_roughness
from freqbrdf.estimate.optimise.solve import optimise
from freqbrdf import methods
from freqbrdf.estimate.optimise import kernels
from freqbrdf.sphere import reference, sampling, sh
from freqbrdf.sphere.lobes import ggx_lobe_spectrum

OPTIMISER_METHODS = methods.methods_of("optimise_svbrdf")

LMAX = 8  # degree of the model's light in these tests (the pipeline's default is 20)


# --------------------------------------------------------------------------
# synthetic captures
# --------------------------------------------------------------------------
def local_hemisphere(n: int) -> np.ndarray:
    """Fibonacci points on the local upper hemisphere (z = normal), (n, 3)."""
    p = sampling.fibonacci_hemisphere(n)  # about +Y
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=-1)


def synthetic_scene(n_tex: int, n_views: int, seed: int, drop: float = 0.2, n_lamps: int = 24) -> dict:
    """Observation geometry and light of ``n_tex`` texels with random normals.

    Each texel sees ``n_views`` distant cameras on a Fibonacci upper
    hemisphere about its normal (turned by a random azimuth), a fraction
    ``drop`` of them occluded. The light is a dim sky gradient plus
    ``n_lamps`` coloured von Mises-Fisher lamps (sharpness 50-200, i.e.
    power up to and beyond degree 6) spread evenly over the sphere, so every
    texel's mirror hemisphere holds several lamps: all frequencies are lit.
    Radiance is left at 0 (the tests render it with the forward model).
    ``light`` is the environment's quadrature at degree `LMAX`.
    """
    rng = np.random.default_rng(seed)
    normal = rng.normal(size=(n_tex, 3))
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normal)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    frame = np.stack([tangent, np.cross(normal, tangent), normal], axis=1)  # rows: local axes in world
    phi = rng.uniform(0.0, 2.0 * np.pi, n_tex)
    turn = np.zeros((n_tex, 3, 3))
    turn[:, 0, 0] = turn[:, 1, 1] = np.cos(phi)
    turn[:, 0, 1] = -np.sin(phi)
    turn[:, 1, 0] = np.sin(phi)
    turn[:, 2, 2] = 1.0
    wo = np.einsum("tij,kj->tki", turn, local_hemisphere(n_views))
    weight = wo[..., 2] * (rng.random((n_tex, n_views)) >= drop)
    lamps = sampling.fibonacci_sphere(n_lamps)
    power = rng.uniform(0.5, 2.0, (n_lamps, 3))
    kappa = rng.uniform(50.0, 200.0, n_lamps)

    def light(d: np.ndarray) -> np.ndarray:
        return 0.2 + 0.1 * d[..., 1:2] + np.exp(kappa * (d @ lamps.T - 1.0)) @ power

    env = light(sampling.equirect_directions(128, 256))
    side = int(np.ceil(np.sqrt(n_tex)))
    return with_env({"weight": weight, "wo_local": wo, "frame": frame, "texel": np.arange(n_tex), "resolution": side},
                    env)


def with_env(scene: dict, env: np.ndarray) -> dict:
    """``scene`` lit by the equirect map ``env``: its quadrature and irradiance added."""
    return scene | {"envmap": env, "light": lt.light_quadrature(env, LMAX),
                    "irradiance": lt.irradiance(env, scene["frame"][:, 2])}


def random_params(n_tex: int, seed: int) -> dict[str, np.ndarray]:
    """Well-posed ground truth: roughness in [0.3, 0.8] (alpha 0.09-0.64, resolvable at lmax 6
    with 24 views), base colour in [0.1, 0.9], any metallic."""
    rng = np.random.default_rng(seed)
    return {
        "base_color": rng.uniform(0.1, 0.9, (n_tex, 3)),
        "roughness": rng.uniform(0.3, 0.8, n_tex),
        "metallic": rng.uniform(0.0, 1.0, n_tex),
    }


def observations(scene: dict, radiance: np.ndarray | None = None) -> Observations:
    """The scene's observations, with ``radiance`` (default 0)."""
    b = np.zeros(scene["wo_local"].shape) if radiance is None else radiance
    return Observations.from_arrays(b, scene["weight"], scene["wo_local"], scene["frame"], scene["texel"],
                                    scene["resolution"])


def problem_of(scene: dict, radiance: np.ndarray | None = None, dtype: str = "float64", **kw) -> Problem:
    return build_problem(observations(scene, radiance), scene["irradiance"], dtype, **kw)


def terms(scene: dict, problem: Problem, roughness: np.ndarray, shadowing: bool) -> np.ndarray:
    return light_terms(roughness, problem, shadowing, scene["light"])


def variant(method: str) -> tuple[bool, bool, bool]:
    """(shadowing, masking, prefiltered) of a method in the registry."""
    entry = methods.get_method(method, "optimise_svbrdf")
    return entry.shadowing, entry.masking, entry.prefiltered


# (lobe, view weight, diffuse): the paper's, the GGX lobe alone, the default, and the albedo weight
MODELS = [("gaussian", "paper", "lambert"), ("ggx", "paper", "lambert"), ("ggx", "paper", "principled"),
          ("ggx", "albedo", "principled")]


def tables(model: tuple[str, str, str], method: str) -> tuple[np.ndarray, np.ndarray]:
    """The lobe and view tables `optimise` uses for ``method`` with ``model``."""
    lobe, weight, diffuse = model
    return model_tables(OptimiseSettings.paper(lobe=lobe, view_weight=weight, diffuse=diffuse), method, LMAX)


def render(scene: dict, params: dict, method: str, model: tuple[str, str, str] = MODELS[0]) -> np.ndarray:
    """Noise-free observations of ``params`` by the model of ``method`` itself."""
    shadowing, masking, _ = variant(method)
    problem = problem_of(scene)
    light = terms(scene, problem, params["roughness"], shadowing)
    return forward(pack_params(params, problem.n_texels), problem, light, KernelModel(masking, *tables(model, method)))


def run(
    scene: dict, radiance: np.ndarray, method: str, init: dict | None = None, **settings: object
) -> tuple[dict, np.ndarray]:
    fit = optimise(observations(scene, radiance), scene["irradiance"], scene["light"], init, method,
                   settings=OptimiseSettings.paper(**settings))
    return fit.params, fit.loss_curve


@pytest.fixture(scope="module")
def small() -> dict:
    """18 texels scattered over a 5 x 5 atlas (so TV has holes), 10 views, random radiance."""
    rng = np.random.default_rng(0)
    scene = synthetic_scene(18, 10, seed=3, drop=0.3)
    scene["texel"] = np.sort(rng.choice(25, 18, replace=False))
    scene["resolution"] = 5
    scene["radiance"] = rng.uniform(0.0, 1.5, scene["wo_local"].shape)
    return scene


# --------------------------------------------------------------------------
# BRDF terms
# --------------------------------------------------------------------------
def test_methods_map_to_shadowing_and_masking() -> None:
    assert {m: variant(m) for m in OPTIMISER_METHODS} == {
        "freq": (True, True, False),
        "freq_paper": (True, True, True),
        "freq_noshadow": (False, True, False),
        "freq_nomask": (True, False, False),
        "rh2001": (False, False, False),
    }


def test_atlas_neighbours_and_total_variation_by_hand() -> None:
    # 3 x 3 atlas, texels at flat 0, 1, 2, 4, 7 (a T shape): pairs 0-1, 1-2 (horizontal), 1-4, 4-7 (vertical)
    texel = np.array([0, 1, 2, 4, 7])
    nb = atlas_neighbours(texel, 3)
    assert {tuple(texel[p]) for p in nb} == {(0, 1), (1, 2), (1, 4), (4, 7)}
    x = np.array([[0.0, 1.0], [1.0, 1.0], [3.0, 1.0], [0.0, 0.5], [0.0, 1.0]])
    tv, grad = total_variation(x, nb)
    # |0-1| + |1-3| + |1-0| + |0-0| + |1-1|...: channel 0 gives 1 + 2 + 1 + 0, channel 1 gives 0 + 0 + 0.5 + 0.5
    assert tv == pytest.approx((4.0 + 1.0) / 4)
    # texel at flat 4 (row 3): channel 1 below both neighbours; channel 0 equals its lower neighbour (sign 0)
    np.testing.assert_allclose(grad[3], [-1.0 / 4, -2.0 / 4])
    assert total_variation(x, np.zeros((0, 2), int))[0] == 0.0


# --------------------------------------------------------------------------
# light terms and forward model
# --------------------------------------------------------------------------
def dense_shadowed_light(env: np.ndarray, normal: np.ndarray, alpha: np.ndarray, lmax: int) -> np.ndarray:
    """Independent reference: SH of G1(n . w) L(w) over each upper hemisphere, by the map's own pixels."""
    h, w = env.shape[:2]
    d = sampling.equirect_directions(h, w).reshape(-1, 3)
    power = (env * sampling.equirect_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    cos = normal @ d.T
    g = np.where(cos > 0, 2 / (1 + np.sqrt(1 + alpha[:, None] ** 2 * (1 - cos**2) / np.where(cos > 0, cos, 1) ** 2)), 0)
    return np.einsum("tq,qc,qi->tic", g, power, sh.real_sh(d, lmax))


def test_light_terms_are_the_sh_filter_of_the_shadowed_environment(small: dict) -> None:
    """sum_l exp(-(alpha l)^2) P_l at each observation equals the lobe-filtered, shadowed light at the
    world mirror direction, with Lg integrated independently over the map's pixels."""
    problem = problem_of(small)
    rough = np.linspace(0.2, 0.9, 18)
    alpha = rough**2
    light = terms(small, problem, rough, True)
    lg = dense_shadowed_light(small["envmap"], small["frame"][:, 2], alpha, LMAX)
    mirror = np.einsum("tji,tkj->tki", small["frame"], small["wo_local"] * [-1, -1, 1])
    filt = np.exp(-((alpha[:, None] * sh.sh_degrees(LMAX)) ** 2))
    spec_ref = np.einsum("tkn,tn,tnc->tkc", sh.real_sh(mirror, LMAX), filt, lg)
    obs = small["weight"] > 0
    t_idx = np.nonzero(obs)[0]
    spec = np.einsum("nl,nlc->nc", np.exp(-((alpha[t_idx, None] * np.arange(LMAX + 1)) ** 2)), light)
    # the pixels are a 1.4-degree quadrature of the lamps, the model's nodes carry them band-limited
    # (degree 48): they differ near the horizon, where G1 couples the light's high degrees to low ones
    scale = np.abs(spec_ref[obs]).mean()
    err = spec - spec_ref[obs]
    assert np.sqrt(np.mean(err**2)) < 0.01 * scale
    assert np.abs(err).max() < 0.04 * scale


def test_unshadowed_light_terms_are_the_environment_sh_at_the_mirror_direction(small: dict) -> None:
    """Without shadowing the light is the whole environment's SH (Ramamoorthi and Hanrahan 2001)."""
    problem = problem_of(small)
    light = terms(small, problem, np.zeros(18), False)
    coeffs = sh.project_equirect(small["envmap"], LMAX)
    mirror = np.einsum("tji,tkj->tki", small["frame"], small["wo_local"] * [-1, -1, 1])
    expected = sh.eval_sh(coeffs, mirror)[small["weight"] > 0]
    np.testing.assert_allclose(light.sum(axis=1), expected, rtol=1e-5, atol=1e-6 * np.abs(expected).max())


@pytest.mark.parametrize("lobe", ["gaussian", "ggx"])
@pytest.mark.parametrize("method", list(OPTIMISER_METHODS))
def test_forward_matches_a_direct_evaluation_of_the_model(small: dict, method: str, lobe: str) -> None:
    """B = (1 - m) base E / pi + F G1m sum_lm f_l(alpha) Lg_lm Y_lm(w_r), written out independently
    (f_l: the Gaussian exp(-(alpha l)^2), or GGX's spectrum computed at each alpha, not interpolated)."""
    shadowing, masking, _ = variant(method)
    params = random_params(18, seed=4)
    params["roughness"][:3] = [0.0, 0.02, 1.0]  # the alpha clamp and the extremes
    base, m = params["base_color"], params["metallic"][:, None, None]
    alpha = np.maximum(params["roughness"] ** 2, 1e-3)[:, None]
    wo, w = small["wo_local"], small["weight"]
    cos = wo[..., 2]
    tan2 = (1 - cos**2) / cos**2
    g1 = 2 / (1 + np.sqrt(1 + alpha**2 * tan2))
    mirror = np.einsum("tji,tkj->tki", small["frame"], wo * [-1, -1, 1])
    if shadowing:
        lg = lt.shadowed_light(small["light"], small["frame"][:, 2], alpha[:, 0]).astype(np.float64)
    else:
        lg = np.broadcast_to(sh.project_equirect(small["envmap"], LMAX), (18, sh.n_coeffs(LMAX), 3))
    if lobe == "gaussian":
        filt = np.exp(-((alpha * sh.sh_degrees(LMAX)) ** 2))
    else:
        filt = ggx_lobe_spectrum(alpha[:, 0], LMAX)[0][:, sh.sh_degrees(LMAX)]
    spec = np.einsum("tkn,tn,tnc->tkc", sh.real_sh(mirror, LMAX), filt, lg)
    r0 = 0.04 * (1 - m) + m * base[:, None, :]
    fresnel = r0 + (1 - r0) * (1 - cos[..., None]) ** 5
    expected = (1 - m) * base[:, None, :] * small["irradiance"][:, None, :] / np.pi + fresnel * (
        g1[..., None] if masking else 1.0
    ) * spec
    expected[w == 0] = 0.0
    # float32 light terms
    np.testing.assert_allclose(render(small, params, method, (lobe, "paper", "lambert")), expected, rtol=1e-5,
                               atol=1e-6 * np.abs(expected).max())


@pytest.mark.parametrize("method", list(OPTIMISER_METHODS))
def test_rough_dielectric_under_constant_light(method: str) -> None:
    """metallic 0, roughness 1, constant light L0 (E = pi L0): B = base L0 + F G1m Spec, Spec = L0 unshadowed."""
    shadowing, masking, _ = variant(method)
    l0 = np.array([0.7, 1.0, 1.3])
    scene = with_env(synthetic_scene(6, 24, seed=1), np.broadcast_to(l0, (128, 256, 3)).copy())
    # quadrature of the clamped cosine on a 64-row copy of the map (see tests/test_light.py)
    np.testing.assert_allclose(scene["irradiance"], np.broadcast_to(np.pi * l0, (6, 3)), rtol=5e-3)
    scene["irradiance"] = np.broadcast_to(np.pi * l0, (6, 3)).copy()
    problem = problem_of(scene)
    base = np.random.default_rng(2).uniform(0.1, 0.9, (6, 3))
    params = {"base_color": base, "roughness": np.ones(6), "metallic": np.zeros(6)}
    light = terms(scene, problem, params["roughness"], shadowing)
    b = forward(pack_params(params, 6), problem, light, KernelModel(masking))
    cos = scene["wo_local"][..., 2]
    fresnel = oracles.schlick_fresnel(0.04, cos)[..., None]
    g1 = reference.smith_g1(cos, 1.0)[..., None]
    obs = scene["weight"] > 0
    if not shadowing:
        # a constant has only a DC term: Spec = L0 for any alpha
        np.testing.assert_allclose(light[:, 0], np.broadcast_to(l0, (problem.n_pairs, 3)), rtol=1e-6)
        np.testing.assert_allclose(light[:, 1:], 0.0, atol=1e-3)  # pixel quadrature of the map at degree 48
        expected = base[:, None, :] * l0 + fresnel * (g1 if masking else 1.0) * l0
        np.testing.assert_allclose(b[obs], expected[obs], rtol=1e-5)  # float32 light terms
    else:
        # shadowing and the horizon dim the light: the specular part lies between 0 and the unshadowed one
        spec = b - base[:, None, :] * l0
        upper = fresnel * (g1 if masking else 1.0) * l0
        assert np.all(spec[obs] > 0)
        assert np.all(spec[obs] < upper[obs])
        assert np.mean(spec[obs] / upper[obs]) < 0.7
    assert np.all(b[~obs] == 0.0)


def test_variants_differ_only_where_they_should() -> None:
    scene = synthetic_scene(30, 24, seed=2)
    params = random_params(30, seed=3)
    problem = problem_of(scene)
    x = pack_params(params, 30)
    kd = (1 - params["metallic"])[:, None] * params["base_color"]
    diffuse = (kd * scene["irradiance"] / np.pi)[:, None, :]
    obs = scene["weight"] > 0
    spec = {m: render(scene, params, m) - diffuse for m in OPTIMISER_METHODS}
    g1 = reference.smith_g1(scene["wo_local"][..., 2], params["roughness"][:, None] ** 2)[..., None]
    # masking multiplies the specular term by G1(theta_o) and nothing else
    np.testing.assert_allclose(spec["freq_noshadow"][obs], (g1 * spec["rh2001"])[obs], rtol=1e-10, atol=1e-13)
    np.testing.assert_allclose(spec["freq"][obs], (g1 * spec["freq_nomask"])[obs], rtol=1e-10, atol=1e-13)
    # shadowing changes the fitted light, hence only the specular term; without it the light ignores roughness
    assert not np.allclose(spec["freq"][obs], spec["freq_noshadow"][obs], rtol=1e-3)
    l1 = terms(scene, problem, np.full(30, 0.2), False)
    l2 = terms(scene, problem, np.full(30, 0.9), False)
    np.testing.assert_array_equal(l1, l2)
    # the model is the diffuse term plus a positive specular term
    assert all(np.all(s[obs] > 0) for s in spec.values())
    assert np.all(forward(x, problem, terms(scene, problem, params["roughness"], True), KernelModel(True))[~obs] == 0)


# --------------------------------------------------------------------------
# gradient
# --------------------------------------------------------------------------
def central_differences(loss, x: np.ndarray, h: float = 1e-6) -> np.ndarray:
    """Central differences of the scalar ``loss`` at every entry of ``x``."""
    fd = np.zeros_like(x)
    for index in np.ndindex(x.shape):
        e = np.zeros_like(x)
        e[index] = h
        fd[index] = (loss(x + e) - loss(x - e)) / (2 * h)
    return fd


@pytest.mark.parametrize("model", MODELS)
@pytest.mark.parametrize("method", list(OPTIMISER_METHODS))
def test_gradient_matches_central_differences(small: dict, method: str, model: tuple[str, str, str]) -> None:
    shadowing, masking, _ = variant(method)
    table, view = tables(model, method)
    problem = problem_of(small, small["radiance"])
    rng = np.random.default_rng(7)
    x = rng.uniform(0.1, 0.9, (18, 5))  # roughness >= 0.1: away from the alpha clamp
    light = terms(small, problem, x[:, 3], shadowing)
    tv_weight = 0.05  # large enough that TV is a sizeable part of every gradient

    def loss(xx: np.ndarray) -> float:
        return loss_and_gradient(xx, problem, light, KernelModel(masking, table, view), tv_weight)[0]

    _, grad = loss_and_gradient(x, problem, light, KernelModel(masking, table, view), tv_weight)
    fd = central_differences(loss, x)
    for name, cols in (("base", slice(0, 3)), ("roughness", slice(3, 4)), ("metallic", slice(4, 5))):
        rel = np.linalg.norm(fd[:, cols] - grad[:, cols]) / np.linalg.norm(grad[:, cols])
        assert rel < 1e-6, f"{method} {name}: relative error {rel:.2e}"
    # the TV part is the TV gradient
    _, grad0 = loss_and_gradient(x, problem, light, KernelModel(masking, table, view), 0.0)
    np.testing.assert_allclose(grad - grad0, tv_weight * total_variation(x, problem.neighbours)[1], atol=1e-15)


def test_every_observed_pair_weighs_the_same_in_the_data_term(small: dict) -> None:
    """The loss without TV is the plain mean of |B - B_obs| over observed pairs and channels: no
    cos(theta_o) sample weight, the setting of the paper's Table 4 ablation (section 5.5.1), whatever
    the observations' weights (cos theta_o, kept for the SH fits) say."""
    x = np.random.default_rng(9).uniform(0.1, 0.9, (18, 5))
    params = {"base_color": x[:, :3], "roughness": x[:, 3], "metallic": x[:, 4]}
    observed = small["weight"] > 0
    assert np.ptp(small["weight"][observed]) > 0.3  # the weights vary: a weighted mean would differ
    problem = problem_of(small, small["radiance"])
    loss, _ = loss_and_gradient(x, problem, terms(small, problem, x[:, 3], True), KernelModel(True), 0.0)
    plain = np.abs(render(small, params, "freq", ("gaussian", "paper", "lambert")) - small["radiance"])[observed].mean()
    assert loss == pytest.approx(plain, rel=1e-9)


def test_float32_loss_and_gradient_match_float64(small: dict) -> None:
    p64 = problem_of(small, small["radiance"], "float64")
    p32 = problem_of(small, small["radiance"], "float32")
    x = np.random.default_rng(8).uniform(0.1, 0.9, (18, 5))
    l64, g64 = loss_and_gradient(x, p64, terms(small, p64, x[:, 3], True), KernelModel(True))
    l32, g32 = loss_and_gradient(x, p32, terms(small, p32, x[:, 3], True), KernelModel(True))
    assert l32 == pytest.approx(l64, rel=1e-5)
    np.testing.assert_allclose(g32, g64, rtol=1e-3, atol=1e-4 * np.abs(g64).max())


def test_threads_do_not_change_results() -> None:
    scene = synthetic_scene(300, 10, seed=31)  # several blocks of texels per thread
    params = random_params(300, seed=32)
    x = pack_params(params, 300)
    problem = problem_of(scene, render(scene, params, "freq") * 1.1, "float32")
    light = terms(scene, problem, x[:, 3], True)
    a = loss_and_gradient(x, problem, light, KernelModel(True), workers=1)
    b = loss_and_gradient(x, problem, light, KernelModel(True), workers=2)
    assert a[0] == b[0]
    np.testing.assert_array_equal(a[1], b[1])
    start = grid_start(problem, light, KernelModel(True), np.linspace(0, 1, 5), np.linspace(0, 1, 3), workers=1)
    np.testing.assert_array_equal(start, grid_start(problem, light, KernelModel(True), np.linspace(0, 1, 5), np.linspace(0, 1, 3), workers=2))
    np.testing.assert_array_equal(light, light_terms(x[:, 3], problem, True, scene["light"], workers=2))
    obs = observations(scene, render(scene, params, "freq") * 1.1)
    lm = [optimise(obs, scene["irradiance"], scene["light"], method="freq",
                      settings=OptimiseSettings.paper(solver="lm", sweeps=4, sweep_refit_every=2, workers=w))
          for w in (1, 2)]
    for k in TEXTURES:
        np.testing.assert_array_equal(lm[0].params[k], lm[1].params[k])


# --------------------------------------------------------------------------
# optimisation
# --------------------------------------------------------------------------
@pytest.fixture(scope="module")
def capture() -> tuple[dict, dict]:
    """200 texels, 24 views, lamps of all frequencies, and well-posed ground truth."""
    return synthetic_scene(200, 24, seed=0), random_params(200, seed=1)


@pytest.mark.parametrize("method, model", [("freq", MODELS[0]), ("rh2001", MODELS[0]), ("freq", MODELS[2])])
@pytest.mark.parametrize("solver", ["adam", "lm"])
def test_self_consistency_recovers_the_parameters(capture: tuple[dict, dict], method: str,
                                                  model: tuple[str, str, str], solver: str) -> None:
    """Noise-free observations of the model itself are fitted back from the grid start.

    Adam: same refit schedule as `optimise` (every 50 iterations) and float32, but
    300 iterations instead of 150 and no TV: from the 0.5 start the light
    terms of ``freq`` are shadowed with the wrong alpha until the refits
    catch up (a fixed-point iteration), and TV would bias independent
    random texels. With 150 iterations the roughness MSE of ``freq`` is
    about 5e-4, with 300 about 1.5e-5. LM: at most 30 sweeps, refits every 4
    (``freq`` about 4e-6 in 21 sweeps; ``rh2001``, which needs no refit, 2e-15 in 6).

    ``freq_noshadow`` recovers as well as ``rh2001``. ``freq_nomask`` is left
    out: the truth is a fixed point of it (started there it stays), but from
    0.5 about 2% of the texels settle on another self-consistent pair of
    roughness and shadowed light (roughness MSE 2e-3 even after 1000
    iterations).
    """
    scene, truth = capture
    radiance = render(scene, truth, method, model)
    schedule = {"iterations": 300, "refit_every": 50} if solver == "adam" else {"sweeps": 30, "sweep_refit_every": 4}
    lobe, weight, diffuse = model
    est, curve = run(scene, radiance, method, solver=solver, tv_weight=0.0, lobe=lobe, view_weight=weight,
                     diffuse=diffuse, **schedule)
    mse = {k: float(np.mean((est[k] - truth[k]) ** 2)) for k in TEXTURES}
    assert all(v < 1e-4 for v in mse.values()), mse
    assert curve[-1] < 0.5 * curve[0]
    if solver == "lm" and method == "rh2001":  # no refit: the exact minimiser, far below Adam's noise floor
        assert all(v < 1e-12 for v in mse.values()), mse


def test_optimisation_decreases_the_loss_and_respects_bounds(capture: tuple[dict, dict]) -> None:
    scene, truth = capture
    radiance = render(scene, truth, "freq")
    # from 0.5, a large step drives texels to the bounds
    est, curve = run(scene, radiance, "freq", iterations=150, lr=0.1, grid_start=False)
    x = pack_params(est, 200)  # raises if outside [0, 1]
    assert ((x == 0.0) | (x == 1.0)).any()
    assert curve.shape == (151,)  # the start of every step, then the end
    # falls until it reaches the step's noise floor (refits included), then stays there
    windows = curve[:150].reshape(6, 25).mean(axis=1)
    assert np.all(windows[:2] > windows[1:3])
    assert windows[-1] < 1.1 * windows[2:].min()
    assert curve[-1] < 0.1 * curve[0]


def test_adam_returns_its_best_iterate_so_it_never_ends_above_its_start(capture: tuple[dict, dict]) -> None:
    """Started at the noise-free optimum with a large step, Adam can only wander off it: the
    estimate must be the start itself, bit for bit, and the curve shows the wander. ``rh2001``
    needs no refit, so every value of its curve is the same objective."""
    scene, truth = capture
    radiance = render(scene, truth, "rh2001")
    est, curve = run(scene, radiance, "rh2001", init=truth, iterations=20, lr=0.05, tv_weight=0.0)
    assert curve.shape == (21,)
    assert int(np.argmin(curve)) == 0 and curve[-1] > 10 * curve[0]  # it did wander
    for key in truth:
        np.testing.assert_array_equal(est[key], np.asarray(truth[key], dtype=np.float64))
    # from 0.5 the best iterate is the last one, and the curve's last value is its objective
    est, curve = run(scene, radiance, "rh2001", iterations=20, lr=0.05, tv_weight=0.0, grid_start=False)
    assert int(np.argmin(curve)) == 20
    assert not np.allclose(est["roughness"], 0.5)


def test_lm_sweep_is_block_coordinate_descent(small: dict) -> None:
    """Each half sweep (one checkerboard colour) reports every texel's own objective as an independent
    sum computes it, and never raises the total objective (the one Adam minimises)."""
    problem = problem_of(small, small["radiance"])
    rng = np.random.default_rng(13)
    x = rng.uniform(0.1, 0.9, (problem.n_texels, 5))
    light = terms(small, problem, x[:, 3], True)
    xp = x[problem.perm].copy()
    tv_weight, n_edges = 0.05, problem.neighbours.shape[0]
    lam = np.full(problem.n_texels, 1e-2)
    colours = problem.colours
    assert sum(c.shape[0] for c in colours) == problem.n_texels
    edges = np.argsort(problem.perm)[problem.neighbours]  # internal order
    np.testing.assert_array_equal(problem.tv_edges, edges)
    for c in colours:  # no edge joins two texels of one colour
        inside = np.isin(edges, c).all(axis=1)
        assert not inside.any()
    first = previous = loss_and_gradient(x, problem, light, KernelModel(True), tv_weight)[0]
    for _ in range(3):
        for texels in colours:
            data, _ = kernels.l1_loss_gradient(np.ascontiguousarray(xp[: problem.n_observed]), light,
                                               problem.pair_data, KernelModel(True))
            expected = np.zeros(problem.n_texels)
            expected[: problem.n_observed] = data / (3.0 * problem.n_pairs)
            diff = np.abs(xp[edges[:, 0]] - xp[edges[:, 1]]).sum(axis=1) * tv_weight / n_edges
            np.add.at(expected, edges[:, 0], diff)
            np.add.at(expected, edges[:, 1], diff)
            cost = kernels.lm_sweep(xp, texels, light, problem.pair_data, KernelModel(True), (problem.nb_start, problem.nb), LmStep(1.0 / (3.0 * problem.n_pairs), tv_weight / n_edges, np.zeros(5), np.ones(5), 1e-2, 1e-2, 4), lam)
            np.testing.assert_allclose(cost, expected[texels], rtol=1e-9)
            x = np.empty_like(xp)
            x[problem.perm] = xp
            assert ((x >= 0) & (x <= 1)).all()
            total = loss_and_gradient(x, problem, light, KernelModel(True), tv_weight)[0]
            assert total <= previous * (1 + 1e-12)
            previous = total
    assert previous < 0.8 * first


def test_self_consistency_with_the_albedo_weight(capture: tuple[dict, dict]) -> None:
    """The albedo weight (`freqbrdf.sphere.lobes.view_table`) recovered by LM, the light refitted for every
    texel that moved (``refit_tolerance`` 0): metallic MSE 5e-6. With the default tolerance 0.02
    the light of the texels that moved less stays shadowed at their old roughness, which the
    albedo's stronger dependence of rough metals on alpha turns into a metallic MSE of 1.7e-4
    (Adam 2.6e-4; the paper's weight stays below 1e-4 either way)."""
    scene, truth = capture
    radiance = render(scene, truth, "freq", MODELS[3])
    est, _ = run(scene, radiance, "freq", solver="lm", sweeps=30, sweep_refit_every=4, refit_tolerance=0.0,
                 tv_weight=0.0, lobe="ggx", view_weight="albedo", diffuse="principled")
    mse = {k: float(np.mean((est[k] - truth[k]) ** 2)) for k in TEXTURES}
    assert all(v < 2e-5 for v in mse.values()), mse


@pytest.mark.parametrize("model", MODELS)
def test_lm_converges_quadratically_from_near_the_truth(capture: tuple[dict, dict], model: tuple[str, str, str]) -> None:
    """Damped Gauss-Newton on noise-free observations: from 1e-3 off each sweep divides the error by a
    growing factor (the paper's model: median 4e-12 after four sweeps, 4e-16 after six, the worst
    texel 3e-11; the albedo weight, slowest: 7e-9 after four, 1e-13 after six, the worst 7e-6),
    which needs the exact Jacobian of the model (with a wrong entry a step is rejected or the error
    shrinks linearly)."""
    scene, truth = capture
    truth = {"base_color": np.clip(truth["base_color"], 0.05, 0.95), "roughness": truth["roughness"],
             "metallic": np.clip(truth["metallic"], 0.05, 0.95)}
    x_true = pack_params(truth, 200)
    problem = problem_of(scene)
    light = terms(scene, problem, truth["roughness"], True)  # held fixed, as between refits
    table, view = tables(model, "freq")
    problem = problem_of(scene, forward(x_true, problem, light, KernelModel(True, table, view)))
    rng = np.random.default_rng(14)
    xp = (x_true + 1e-3 * rng.choice([-1.0, 1.0], x_true.shape))[problem.perm]
    lam = np.full(200, 1e-2)
    for _ in range(6):
        for texels in problem.colours:
            kernels.lm_sweep(xp, texels, light, problem.pair_data, KernelModel(True, lobe=table, view=view), (problem.nb_start, problem.nb), LmStep(1.0 / (3.0 * problem.n_pairs), 0.0, np.zeros(5), np.ones(5), 1e-2, 1e-2, 4), lam)
    error = np.abs(xp - x_true[problem.perm]).max(axis=1)
    assert np.median(error) < 1e-10 and error.max() < 1e-5


@pytest.mark.parametrize("kw", [{"iterations": 20, "refit_every": 7}, {"solver": "lm", "sweeps": 6, "sweep_refit_every": 2}])
def test_optimise_is_deterministic(small: dict, kw: dict) -> None:
    a = run(small, small["radiance"], "freq", **kw)
    b = run(small, small["radiance"], "freq", **kw)
    c = run(small, small["radiance"], "freq", workers=2, **kw)
    for other in (b, c):
        for k in TEXTURES:
            np.testing.assert_array_equal(a[0][k], other[0][k])
        np.testing.assert_array_equal(a[1], other[1])


def test_a_table_read_from_disk_gives_the_estimate_of_one_fitted_inside(small: dict, tmp_path) -> None:
    """Rule light_table's table, written and read back, changes no bit of the estimate, and the
    estimate uses it (a table altered on disk changes the estimate); a table of another size
    than the settings' is refused."""
    size = TableSize(rows=6, rank=4)
    settings = OptimiseSettings.paper(iterations=20, refit_every=7, light_table=size)
    write_light_table(tmp_path / "t", shadowed_light_table(small["light"], size.rows, size.rank))
    table = read_light_table(tmp_path / "t", small["light"], size)
    obs = observations(small, small["radiance"])
    inside = optimise(obs, small["irradiance"], small["light"], None, "freq", settings=settings)
    read = optimise(obs, small["irradiance"], small["light"], None, "freq", settings=settings, table=table)
    for k in TEXTURES:
        np.testing.assert_array_equal(inside.params[k], read.params[k])
    np.testing.assert_array_equal(inside.loss_curve, read.loss_curve)
    altered = dataclasses.replace(table, coefficients=2.0 * table.coefficients)
    doubled = optimise(obs, small["irradiance"], small["light"], None, "freq", settings=settings, table=altered)
    assert not np.array_equal(doubled.loss_curve, read.loss_curve)
    other = OptimiseSettings.paper(iterations=2, light_table=TableSize(rows=8, rank=4))
    with pytest.raises(ValueError, match="asks rows 8"):
        optimise(obs, small["irradiance"], small["light"], None, "freq", settings=other, table=table)


@pytest.mark.parametrize("schedule", [{"iterations": 60}, {"solver": "lm", "sweeps": 10}])
def test_tv_smooths_a_noisy_field_and_fills_unobserved_texels(schedule: dict) -> None:
    # 12 x 12 atlas, constant material; the texels of a 4 x 4 block are never observed
    scene = synthetic_scene(144, 24, seed=4)
    grid = np.arange(144).reshape(12, 12)
    hidden = np.zeros(144, bool)
    hidden[grid[4:8, 4:8].ravel()] = True
    scene["weight"][hidden] = 0.0
    truth = {
        "base_color": np.tile([0.6, 0.4, 0.3], (144, 1)),
        "roughness": np.full(144, 0.5),
        "metallic": np.full(144, 0.3),
    }
    radiance = render(scene, truth, "freq")
    rng = np.random.default_rng(6)
    init = {k: np.clip(v + rng.normal(0.0, 0.15, v.shape), 0.0, 1.0) for k, v in truth.items()}
    nb = atlas_neighbours(scene["texel"], 12)

    def tv(p: dict) -> float:
        return total_variation(pack_params(p, 144), nb)[0]

    plain, _ = run(scene, radiance, "freq", init=init, tv_weight=0.0, **schedule)
    smooth, _ = run(scene, radiance, "freq", init=init, tv_weight=0.05, **schedule)
    for k in TEXTURES:  # without TV nothing moves the unobserved texels
        np.testing.assert_array_equal(plain[k][hidden], init[k][hidden])
    assert tv(smooth) < 0.5 * tv(plain)
    assert tv(smooth) < 0.5 * tv(init)
    # the hidden block is pulled toward its neighbours, i.e. toward the truth
    err = {name: np.mean((pack_params(p, 144)[hidden] - pack_params(truth, 144)[hidden]) ** 2)
           for name, p in (("init", init), ("smooth", smooth))}
    assert err["smooth"] < 0.5 * err["init"]


@pytest.mark.parametrize("schedule", [{"iterations": 150}, {"solver": "lm", "sweeps": 20}])
def test_roughness_leaves_the_alpha_clamp(schedule: dict) -> None:
    """A texel started below sqrt(ALPHA_MIN), where alpha is constant, still finds its roughness."""
    scene = synthetic_scene(20, 24, seed=8)
    truth = random_params(20, seed=9)
    radiance = render(scene, truth, "rh2001")
    init = dict(truth, roughness=np.zeros(20))
    est, _ = run(scene, radiance, "rh2001", init=init, tv_weight=0.0, **schedule)
    assert np.mean((est["roughness"] - truth["roughness"]) ** 2) < 1e-3


# --------------------------------------------------------------------------
# validation
# --------------------------------------------------------------------------
def test_bad_inputs_are_named(small: dict) -> None:
    def call(**over: object) -> None:
        names = ("radiance", "weight", "wo_local", "frame", "irradiance", "texel", "resolution", "light")
        args = {k: small[k] for k in names}
        args.update(over)
        obs = Observations.from_arrays(*(args[k] for k in ("radiance", "weight", "wo_local", "frame", "texel",
                                                            "resolution")))
        optimise(obs, args["irradiance"], args["light"], init=args.get("init"), method=args.get("method", "freq"),
                    settings=OptimiseSettings.paper(iterations=1))

    with pytest.raises(ValueError, match="method must be one of .* got 'frq'"):
        call(method="frq")
    bad = small["radiance"].copy()
    t, k = np.argwhere(small["weight"] > 0)[0]
    bad[t, k, 1] = np.nan
    with pytest.raises(ValueError, match=f"radiance must be finite where weight > 0, .* at texel {t}, view {k}"):
        call(radiance=bad)
    w = small["weight"].copy()
    w[0, 0] = -0.5
    with pytest.raises(ValueError, match="weight must be >= 0, got -0.5 at texel 0, view 0"):
        call(weight=w)
    with pytest.raises(ValueError, match="no observed pair"):
        call(weight=np.zeros_like(w))
    with pytest.raises(ValueError, match=r"irradiance must have shape \(18, 3\)"):
        call(irradiance=small["irradiance"][:5])
    with pytest.raises(ValueError, match="texel indices must be in \\[0, 25\\)"):
        call(texel=small["texel"] + 100)
    init = {"base_color": np.full((18, 3), 0.5), "roughness": np.full(18, 1.5), "metallic": np.zeros(18)}
    with pytest.raises(ValueError, match="roughness must be in \\[0, 1\\], got 1.5"):
        call(init=init)
    with pytest.raises(ValueError, match="lacks \\['metallic'\\]"):
        call(init={"base_color": init["base_color"], "roughness": np.zeros(18)})
    with pytest.raises(ValueError, match="lr must be a finite number > 0, got -1"):
        OptimiseSettings.paper(lr=-1)
    with pytest.raises(ValueError, match=r"frame must have shape \(18, 3, 3\)"):
        call(frame=small["frame"][:5])
    with pytest.raises(ValueError, match="min_roughness must be in \\[0, 1\\), got 1.0"):
        OptimiseSettings.paper(min_roughness=1.0)
    with pytest.raises(ValueError, match="solver must be one of \\('adam', 'lm'\\), got 'newton'"):
        OptimiseSettings.paper(solver="newton")
    with pytest.raises(ValueError, match="irls_floor must be a finite number > 0, got 0"):
        OptimiseSettings.paper(irls_floor=0)


@pytest.mark.parametrize("schedule", [{"iterations": 60, "lr": 0.05}, {"solver": "lm", "sweeps": 10}])
def test_min_roughness_bounds_the_fit_from_below(small: dict, schedule: dict) -> None:
    # Radiance of a mirror-like material: unbounded, the fit drives roughness towards 0.
    truth = {"base_color": np.full((18, 3), 0.8), "roughness": np.full(18, 0.05), "metallic": np.ones(18)}
    radiance = render(small, truth, "freq")
    free, _ = run(small, radiance, "freq", **schedule)
    held, _ = run(small, radiance, "freq", min_roughness=0.3, **schedule)
    assert free["roughness"].min() < 0.3
    assert held["roughness"].min() == pytest.approx(0.3) and held["roughness"].max() <= 1.0
    # The bound is a lower limit only: texels that are truly rough stay where the data put them.
    rough = dict(truth, roughness=np.full(18, 0.7), metallic=np.zeros(18))
    fitted, _ = run(small, render(small, rough, "freq"), "freq", min_roughness=0.3, **schedule)
    assert np.all(fitted["roughness"] > 0.4)


def test_identifiable_roughness_is_where_the_lobe_fits_below_the_degree() -> None:
    """alpha (l* + 1) = sqrt(ln 20): the lobe keeps 5% of a point light's weight above l*."""
    r = identifiable_roughness(20)
    assert r == pytest.approx(np.sqrt(np.sqrt(np.log(20.0)) / 21.0), rel=1e-12)
    assert np.exp(-((r**2 * 21) ** 2)) == pytest.approx(0.05, rel=1e-9)
    assert identifiable_roughness(6) > identifiable_roughness(16) > r
    with pytest.raises(ValueError, match="tail must be in"):
        identifiable_roughness(20, tail=1.0)
    # GGX's sharp peak keeps more above l*: 5% of its weight there at a larger roughness
    r_ggx = identifiable_roughness(20, lobe="ggx")
    f = ggx_lobe_spectrum(np.array([r_ggx**2, (r_ggx - 0.01) ** 2]), 400)[0] * (2 * np.arange(401) + 1)
    share = f[:, 21:].sum(axis=1) / f.sum(axis=1)
    assert r_ggx > r + 0.05 and share[0] < 0.05 < share[1]


def test_partial_refit_matches_a_full_fit_of_the_moved_texels(small: dict) -> None:
    problem = problem_of(small)
    r1 = np.linspace(0.2, 0.9, 18)
    r2 = r1.copy()
    moved = np.array([1, 5, 6, 11])
    r2[problem.observed[moved]] += 0.05
    flat = terms(small, problem, r1, True)
    refit_light(flat, r2, problem, small["light"], moved, workers=1)
    np.testing.assert_allclose(flat, terms(small, problem, r2, True), rtol=1e-5, atol=1e-6)


FRESH_OR_CACHED = """
import hashlib, json, sys
import numpy as np
import yaml
from freqbrdf.estimate.optimise.model import estimate_light
from freqbrdf.estimate.optimise.settings import OptimiseSettings
from freqbrdf.estimate.optimise.solve import optimise
from freqbrdf.methods import methods_of
from freqbrdf.studies.recovery_capture import capture_observations, oracle_capture

env = np.random.default_rng(3).uniform(0.05, 1.0, (32, 64, 3))
env[6:8, 20:22] = 400.0  # a point source
capture, _ = oracle_capture(env, 7)
obs = capture_observations(capture)
config = yaml.safe_load(open(sys.argv[1]))["optimise"]
out = {}
for solver, steps in (("adam", {"iterations": 20}), ("lm", {"sweeps": 3})):
    for method in methods_of("optimise_svbrdf"):
        light, e = estimate_light(env, obs, method, 10, config["point_sources"])
        settings = OptimiseSettings.from_config(config | {"solver": solver, "lmax": 10} | steps, workers=2)
        fit = optimise(obs, e, light, method=method, settings=settings)
        params, curve = fit.params, fit.loss_curve
        data = b"".join(np.ascontiguousarray(params[k]).tobytes() for k in sorted(params)) + curve.tobytes()
        out[f"{method}/{solver}"] = hashlib.sha1(data).hexdigest()
print(json.dumps(out))
"""


def test_every_method_gives_the_same_bits_whether_its_kernels_were_compiled_or_loaded(tmp_path) -> None:
    """A job that compiles the kernels and one that loads them from numba's cache compute the same
    estimate, bit for bit, for every method and both solvers (issue 32: with fast-math reassociation
    they did not, so a fresh run's numbers depended on which of its jobs compiled first)."""
    import json
    import os
    import subprocess
    import sys
    from pathlib import Path

    repo = Path(__file__).resolve().parents[1]
    env = os.environ | {"NUMBA_CACHE_DIR": str(tmp_path / "numba"), "PYTHONPATH": str(repo / "workflow")}
    runs = []
    for _ in range(2):  # the first compiles every kernel into the empty cache, the second loads them
        done = subprocess.run([sys.executable, "-c", FRESH_OR_CACHED, str(repo / "config" / "config.yaml")],
                              capture_output=True, text=True, env=env, timeout=600)
        assert done.returncode == 0, done.stderr[-3000:]
        runs.append(json.loads(done.stdout.strip().splitlines()[-1]))
    assert any((tmp_path / "numba").rglob("*.nbc"))  # the second run had a cache to load
    assert len(runs[0]) == 2 * len(OPTIMISER_METHODS)
    assert runs[0] == runs[1]
