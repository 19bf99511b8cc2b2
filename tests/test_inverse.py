"""Differentiable-rendering baseline (freqbrdf.estimate.mitsuba): tiny optimisations on a known material."""

import copy

import numpy as np
import pytest
import yaml

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.estimate import mitsuba as inv
from freqbrdf.scene.cameras import Cameras, intrinsics, look_at, mitsuba_to_world
from freqbrdf.config import ConfigError, check_config
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.scene.render import capture_scene, mask_scene, principled_bsdf, render_views

SIZE = 24  # pixels per side of the test views
TEXELS = 8  # texels per side of the test textures
FOV = 35.0
# A red, fairly smooth dielectric: far from the 0.5 start in every parameter.
TRUTH = {"base_color": (0.9, 0.15, 0.1), "roughness": 0.3, "metallic": 0.0}


def uniform_textures(base_color, roughness, metallic, size=TEXELS):
    return {
        "base_color": np.broadcast_to(np.asarray(base_color, np.float32), (size, size, 3)).copy(),
        "roughness": np.full((size, size), roughness, np.float32),
        "metallic": np.full((size, size), metallic, np.float32),
    }


def ring_cameras(size=SIZE, cx=None, cy=None):
    """Six views around the sphere (elevation +-40 degrees), so every texel is seen."""
    eyes = [4.0 * np.array([np.cos(el) * np.sin(az), np.sin(el), np.cos(el) * np.cos(az)])
            for el in np.radians([40.0, -40.0]) for az in np.radians([0.0, 120.0, 240.0])]
    K = intrinsics(size, size, FOV)
    K[0, 2] = size / 2 if cx is None else cx
    K[1, 2] = size / 2 if cy is None else cy
    return Cameras(K=np.repeat(K[None], len(eyes), 0), world_to_camera=np.stack([look_at(e) for e in eyes]),
                   width=size, height=size, names=tuple(f"{k:03d}" for k in range(len(eyes))))


def lamps():
    """Dim ambient light and nine small lamps all around, so that every texel
    mirrors some lamp into some view: roughness and metallic are observable."""
    env = np.full((16, 32, 3), 0.2, np.float32)
    for row, col in ((3, 2), (3, 12), (3, 22), (8, 7), (8, 17), (8, 27), (12, 2), (12, 12), (12, 22)):
        env[row : row + 2, col : col + 3] = 5.0
    return env


@pytest.fixture(scope="module")
def capture(mi, tmp_path_factory):
    """Path-traced views of a sphere with the uniform TRUTH material, and their coverage."""
    mesh = tmp_path_factory.mktemp("inverse") / "sphere.ply"
    write_ply(mesh, make_mesh("sphere"))
    cameras = ring_cameras()
    env = lamps()
    frame = dict(width=SIZE, height=SIZE, fov_x_deg=FOV)
    to_world = np.stack([mitsuba_to_world(m) for m in cameras.world_to_camera])
    bsdf = principled_bsdf(mi, **uniform_textures(**TRUTH))
    scene = capture_scene(mi, mesh, bsdf, env, spp=256, max_depth=4, **frame)
    images = np.stack(list(render_views(mi, scene, to_world, seed=1)))
    coverage = np.stack([c[..., 0] for c in render_views(mi, mask_scene(mi, mesh, spp=16, **frame), to_world, seed=1)])
    return {"mesh": mesh, "cameras": cameras, "env": env, "images": images, "coverage": coverage}


def subset(capture, views):
    c = capture["cameras"]
    cameras = Cameras(K=c.K[views], world_to_camera=c.world_to_camera[views], width=c.width, height=c.height,
                      names=tuple(c.names[k] for k in views))
    return cameras, capture["images"][views], capture["coverage"][views]


def run(mi, capture, start, views=(0,), **settings):
    cameras, images, coverage = subset(capture, list(views))
    reports = []
    result = inv.optimise_textures(mi, capture["mesh"], capture["env"], cameras, images, coverage, start,
                                   inv.InverseSettings(max_depth=4, **settings), progress=reports.append)
    return result, reports


def parameter_mse(textures):
    truth = uniform_textures(**TRUTH)
    return {n: float(np.mean((textures[n] - truth[n]) ** 2)) for n in TEXTURES}


def test_two_steps_lower_the_loss_and_change_the_textures(mi, capture):
    start = inv.constant_textures(TEXELS)
    result, reports = run(mi, capture, start, epochs=2, spp=32, lr=0.1)
    assert len(result.loss) == 2 and result.loss[1] < result.loss[0]
    assert [r.epoch for r in reports] == [1, 2] and reports[1].elapsed_s >= reports[0].elapsed_s > 0
    for name in TEXTURES:
        assert result.textures[name].shape == start[name].shape and result.textures[name].dtype == np.float32
    # Adam's first step moves every seen texel by about lr: the red channel up, green and blue down.
    change = result.textures["base_color"] - start["base_color"]
    assert change[..., 0].max() > 0.05 and change[..., 1].min() < -0.05 and change[..., 2].min() < -0.05


@pytest.mark.parametrize("crop", [False, True])
def test_recovers_a_uniform_material_from_the_constant_start(mi, capture, crop):
    start = inv.constant_textures(TEXELS)
    result, reports = run(mi, capture, start, views=range(6), epochs=16, spp=16, lr=0.05, crop=crop)
    before, after = parameter_mse(start), parameter_mse(result.textures)
    # Measured: base colour 0.148 -> 0.002, roughness 0.040 -> 0.019, metallic 0.25 -> 0.008.
    assert after["base_color"] < before["base_color"] / 20
    assert after["metallic"] < before["metallic"] / 5
    assert after["roughness"] < before["roughness"]
    assert np.mean(list(after.values())) < np.mean(list(before.values())) / 5
    assert np.median(result.textures["roughness"]) == pytest.approx(TRUTH["roughness"], abs=0.1)
    assert result.epoch_loss[-1] < 0.6 * result.epoch_loss[0]
    np.testing.assert_allclose([r.loss for r in reports], result.epoch_loss)
    # Every step frees its graph: after the first epoch (kernels compiled) memory stays flat.
    assert reports[-1].resident_mb - reports[1].resident_mb < 10


def test_textures_are_clamped_to_the_unit_interval_after_every_step(mi, capture):
    # A huge learning rate pushes the first step far past the bounds: base colour
    # up past 1 (the red channel), metallic down past 0.
    start = uniform_textures((0.9, 0.9, 0.9), 0.9, 0.1)
    result, _ = run(mi, capture, start, epochs=1, spp=16, lr=0.5)
    for name in TEXTURES:
        assert result.textures[name].min() >= 0.0 and result.textures[name].max() <= 1.0
    assert result.textures["base_color"][..., 0].max() == 1.0
    assert result.textures["metallic"].min() == 0.0


def test_same_seed_same_result_other_seed_other_noise(mi, capture):
    start = inv.constant_textures(TEXELS)
    first, _ = run(mi, capture, start, views=(0, 3), epochs=1, spp=8, lr=0.05, seed=7)
    again, _ = run(mi, capture, start, views=(0, 3), epochs=1, spp=8, lr=0.05, seed=7)
    other, _ = run(mi, capture, start, views=(0, 3), epochs=1, spp=8, lr=0.05, seed=8)
    assert first.views == again.views
    np.testing.assert_allclose(first.loss, again.loss, rtol=1e-5)
    # Two threads sum the texel gradients by atomics in varying order, and Adam
    # magnifies that rounding on texels whose gradient is almost 0 (one thread:
    # bit-identical); a step moves texels by lr = 0.05.
    for name in TEXTURES:
        np.testing.assert_allclose(first.textures[name], again.textures[name], atol=0.01)
    assert not np.allclose(first.loss, other.loss, rtol=1e-4)


def test_view_order_visits_every_view_once_per_epoch():
    orders = [inv.view_order(3, epoch, 10) for epoch in range(3)]
    assert all(sorted(o) == list(range(10)) for o in orders)
    assert not np.array_equal(orders[0], orders[1])
    np.testing.assert_array_equal(orders[2], inv.view_order(3, 2, 10))


def coverage_scene(mi, mesh, cameras, spp):
    """The object's coverage scene seen from the first of ``cameras``, and its parameters."""
    scene = mask_scene(mi, mesh, width=cameras.width, height=cameras.height, fov_x_deg=FOV, spp=spp)
    params = mi.traverse(scene)
    for key, value in inv.sensor_views(mi, cameras)[0].items():
        params[key] = value
    params.update()
    return scene, params


def test_sensor_reproduces_an_off_centre_principal_point(mi, capture):
    # Seen from a camera looking at its centre, the sphere's silhouette is a disc
    # centred on the principal point (cx, cy), wherever K puts it.
    size, cx, cy = 48, 27.0, 20.5
    scene, params = coverage_scene(mi, capture["mesh"], ring_cameras(size, cx, cy), spp=16)
    coverage = np.array(mi.render(scene, params, spp=16))[..., 0]
    rows, cols = np.indices(coverage.shape)
    assert (coverage * (cols + 0.5)).sum() / coverage.sum() == pytest.approx(cx, abs=0.15)
    assert (coverage * (rows + 0.5)).sum() / coverage.sum() == pytest.approx(cy, abs=0.15)
    f = intrinsics(size, size, FOV)[0, 0]
    radius = f * np.tan(np.arcsin(1.0 / 4.0))
    assert coverage.sum() == pytest.approx(np.pi * radius**2, rel=0.03)


def test_crop_windows_are_one_size_and_hold_every_weighted_pixel():
    rng = np.random.default_rng(5)
    weights = np.zeros((6, 40, 50), np.float32)
    for k, (y, x, h, w) in enumerate([(0, 0, 5, 7), (30, 40, 10, 10), (12, 20, 3, 25), (1, 44, 20, 6),
                                      (35, 0, 5, 3), (18, 18, 4, 4)]):
        weights[k, y:y + h, x:x + w] = rng.uniform(0.1, 1.0, (h, w))
    windows = inv.crop_windows(weights)
    assert windows.size == (25, 20)  # the widest box's width, the tallest box's height
    w, h = windows.size
    for k, (x, y) in enumerate(windows.offsets):
        assert 0 <= x <= 50 - w and 0 <= y <= 40 - h
        assert weights[k, y:y + h, x:x + w].sum() == pytest.approx(weights[k].sum())
    assert windows.take(weights).shape == (6, 20, 25)
    weights[2] = 0.0
    with pytest.raises(ValueError, match="view 2 has no pixel"):
        inv.crop_windows(weights)


def test_a_cropped_render_is_the_whole_render_inside_its_window(mi, capture):
    # The object's coverage (0 or 1 away from its silhouette) of an off-centre view, rendered
    # whole and in its window: the same pixels up to the silhouette's sampling noise, and far
    # from them one pixel off.
    size = 48
    scene, params = coverage_scene(mi, capture["mesh"], ring_cameras(size, 28.0, 26.0), spp=256)
    whole = np.array(mi.render(scene, params, seed=1))[..., 0]
    windows = inv.crop_windows(whole[None])
    (x, y), (w, h) = windows.offsets[0], windows.size
    assert x > 0 and y > 0 and w * h < 0.75 * size * size
    for key, value in windows.sensor(mi, 0).items():
        params[key] = value
    params.update()
    cropped = np.array(mi.render(scene, params, seed=2))[..., 0]
    assert cropped.shape == (h, w)
    assert np.abs(cropped - whole[y:y + h, x:x + w]).mean() < 0.01
    assert np.abs(cropped - whole[y + 1:y + 1 + h, x:x + w]).mean() > 0.03


def test_non_square_pixels_are_refused_naming_the_view():
    cameras = ring_cameras()
    K = cameras.K.copy()
    K[2, 1, 1] *= 1.1
    bad = Cameras(K=K, world_to_camera=cameras.world_to_camera, width=SIZE, height=SIZE, names=cameras.names)
    with pytest.raises(ValueError, match=r"view 002: K .* non-square pixels"):
        inv.sensor_intrinsics(bad)


def test_image_loss_and_total_variation_match_their_formulas(mi):
    rng = np.random.default_rng(0)
    image, reference = rng.uniform(0.0, 3.0, (2, 5, 4, 3)).astype(np.float32)
    weight = rng.uniform(0.0, 1.0, (5, 4, 1)).astype(np.float32)
    for kind, distance in (("l1log", np.abs(np.log1p(image) - np.log1p(reference))), ("l2", (image - reference) ** 2),
                           ("l1rel", np.abs(np.log(image + 0.01) - np.log(reference + 0.01)))):
        expected = (weight * distance).sum() / (3 * weight.sum())
        value = inv.image_loss(mi, mi.TensorXf(image), mi.TensorXf(reference), mi.TensorXf(weight), kind)
        assert float(value.array[0]) == pytest.approx(expected, rel=1e-5)
    a, b = rng.uniform(0.0, 1.0, (6, 6, 3)).astype(np.float32), rng.uniform(0.0, 1.0, (6, 6, 1)).astype(np.float32)
    steps = sum(np.abs(np.diff(t, axis=0)).sum() + np.abs(np.diff(t, axis=1)).sum() for t in (a, b))
    value = inv.total_variation(mi, [mi.TensorXf(a), mi.TensorXf(b)])
    assert float(value.array[0]) == pytest.approx(steps / (5 * 6 + 6 * 5), rel=1e-5)


@pytest.mark.parametrize(
    "settings, message",
    [
        ({"epochs": 0}, r"epochs must be >= 1, got 0"),
        ({"spp": 2.5}, r"spp must be an int, got float 2.5"),
        ({"lr": 0.0}, r"lr must be a finite number > 0, got 0.0"),
        ({"loss": "l1"}, r"loss must be one of \('l1log', 'l2', 'l1rel'\), got 'l1'"),
        ({"tv_weight": -1e-3}, r"tv_weight must be a finite number >= 0"),
        ({"max_depth": 0}, r"max_depth must be -1 \(unlimited\) or >= 1, got 0"),
        ({"seed": -1}, r"seed must be >= 0, got -1"),
        ({"views_per_step": 0}, r"views_per_step must be >= 1, got 0"),
        ({"views_per_step": 1.5}, r"views_per_step must be an int, got float 1.5"),
        ({"loss_eps": 0.0}, r"loss_eps must be a finite number > 0, got 0.0"),
        ({"lr_decay": "linear"}, r"lr_decay must be one of \('none', 'cosine'\), got 'linear'"),
        ({"lr": {"base_color": 0.01, "roughness": 0.01, "normal": 0.01}},
         r"lr: unknown keys \['normal'\]; a mapping needs exactly the keys \['base_color', 'roughness', 'metallic'\]"),
        ({"tv_weight": {"base_color": 0.01, "roughness": 0.01}}, r"tv_weight: missing keys \['metallic'\]"),
        ({"tv_weight": {"base_color": 0.01, "roughness": -1, "metallic": 0.0}},
         r"tv_weight\.roughness must be a finite number >= 0, got -1"),
        ({"lr": {"base_color": 0.0, "roughness": 0.0, "metallic": 0.0}}, r"lr: at least one texture's value must be > 0"),
        ({"lr": "fast"}, r"lr must be a finite number > 0 or a mapping of .*, got str 'fast'"),
        ({"stop_window": -1}, r"stop_window must be >= 0, got -1"),
        ({"stop_fall": 1.0}, r"stop_fall must be in \[0, 1\), got 1.0"),
        ({"crop": "yes"}, r"crop must be true or false, got 'yes'"),
    ],
)
def test_bad_settings_give_one_line_naming_the_field(settings, message):
    with pytest.raises((TypeError, ValueError), match=message) as info:
        inv.InverseSettings(**settings)
    assert "\n" not in str(info.value)


def test_bad_start_textures_are_refused():
    good = inv.constant_textures(4)
    with pytest.raises(ValueError, match=r"roughness is \(4, 5\), expected \(4, 4\)"):
        inv.check_textures({**good, "roughness": np.zeros((4, 5))})
    with pytest.raises(ValueError, match=r"metallic values are not finite numbers in \[0, 1\]"):
        inv.check_textures({**good, "metallic": np.full((4, 4), 1.5)})
    with pytest.raises(ValueError, match=r"missing \['base_color'\]"):
        inv.check_textures({"roughness": good["roughness"], "metallic": good["metallic"]})


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda c: c["mitsuba"].update(loss="l1"), r"config key mitsuba\.loss: 'l1' is not one of \['l1log', 'l2', 'l1rel'\]"),
        (lambda c: c["mitsuba"]["finetune"].update(epochs=0), r"config key mitsuba\.finetune\.epochs: 0 is less than"),
        (lambda c: c["mitsuba"].update(spp=8.5), r"config key mitsuba\.spp: 8\.5 is not of type 'integer'"),
        (lambda c: c["mitsuba"].pop("max_depth"), r"config key mitsuba: 'max_depth' is a required property"),
        (lambda c: c["mitsuba"].update(views_per_step=0), r"config key mitsuba\.views_per_step: 0 is less than"),
        (lambda c: c["mitsuba"].update(lr={"base_color": 0.01, "roughness": 0.01, "metalic": 0.01}),
         r"config key mitsuba\.lr: Additional properties are not allowed \('metalic' was unexpected\)"),
        (lambda c: c["mitsuba"].update(tv_weight={"base_color": 0.01, "roughness": -0.1, "metallic": 0.0}),
         r"config key mitsuba\.tv_weight\.roughness: -0\.1 is less than the minimum of 0"),
        (lambda c: c["mitsuba"].update(tv_weight={"base_color": 0.01}), r"config key mitsuba\.tv_weight: .* not have enough"),
        (lambda c: c["mitsuba"].update(lr_decay="step"), r"config key mitsuba\.lr_decay: 'step' is not one of"),
        (lambda c: c.update(methods=["freq", "mitsuba2"]), r"config key methods: \['mitsuba2'\] are not registered methods"),
    ],
)
def test_config_mistakes_in_the_mitsuba_section_name_the_key(repo, edit, message):
    config = yaml.safe_load((repo / "config" / "config.yaml").read_text())
    assert {"mitsuba", "freq+mitsuba"} <= set(config["methods"])
    edit(config)
    with pytest.raises(ConfigError, match=message) as info:
        check_config(copy.deepcopy(config), repo / "workflow" / "schemas" / "config.schema.yaml")
    assert "\n" not in str(info.value)


def test_capture_scene_takes_only_path_or_prb(mi, capture):
    bsdf = principled_bsdf(mi, **inv.constant_textures(TEXELS))
    with pytest.raises(ValueError, match=r"integrator must be 'path' or 'prb', got 'ptracer'"):
        capture_scene(mi, capture["mesh"], bsdf, capture["env"], width=SIZE, height=SIZE, fov_x_deg=FOV, spp=1,
                      max_depth=2, integrator="ptracer")


# ---- the authors' recipe: views per step, l1rel, per-texture lr and TV, cosine decay


@pytest.fixture()
def one_thread(mi):
    """One Dr.Jit thread: texel gradients summed in a fixed order, so runs are bit-identical."""
    import drjit as dr

    before = dr.thread_count()
    dr.set_thread_count(1)
    yield
    dr.set_thread_count(before)


def old_optimise(mi, capture, start, views, epochs, spp, lr, tv_weight, seed, loss="l1log"):
    """The optimiser as it was before views_per_step, l1rel, per-texture rates and lr_decay
    (one view per step, one lr, one TV weight): the oracle of the defaults."""
    import drjit as dr

    cameras, images, coverage = subset(capture, list(views))
    keys = [f"object.bsdf.{name}.data" for name in TEXTURES]
    scene = inv.inverse_scene(mi, capture["mesh"], capture["env"], start, width=SIZE, height=SIZE, spp=spp, max_depth=4)
    params, sensors = mi.traverse(scene), inv.sensor_views(mi, cameras)
    opt = mi.ad.Adam(lr=lr)
    for key in keys:
        opt[key] = params[key]
    params.update(opt)
    losses = []
    for epoch in range(epochs):
        for k in inv.view_order(seed, epoch, len(cameras)):
            for key, value in sensors[k].items():
                params[key] = value
            params.update(opt)
            primal, adjoint = inv.render_seeds(seed, len(losses))
            image = mi.render(scene, params, spp=spp, seed=primal, seed_grad=adjoint)
            value = inv.image_loss(mi, image, mi.TensorXf(images[k]), mi.TensorXf(coverage[k][..., None]), loss)
            if tv_weight > 0:
                value = value + tv_weight * inv.total_variation(mi, [opt[key] for key in keys])
            dr.backward(value)
            opt.step()
            for key in keys:
                opt[key] = dr.clip(opt[key], 0.0, 1.0)
            losses.append(float(value.array[0]))
    return {name: np.array(opt[key]) for name, key in zip(TEXTURES, keys)}, np.asarray(losses)


def test_the_defaults_keep_the_old_optimiser_bit_for_bit(mi, capture, one_thread):
    defaults = inv.InverseSettings()
    assert (defaults.views_per_step, defaults.loss_eps, defaults.lr_decay) == (1, 0.01, "none")
    start = inv.constant_textures(TEXELS)
    for loss, tv_weight in (("l1log", 0.05), ("l2", 0.0)):
        common = dict(epochs=2, spp=4, seed=3, loss=loss, tv_weight=tv_weight)
        textures, losses = old_optimise(mi, capture, start, (0, 2, 4), lr=0.05, **common)
        new, _ = run(mi, capture, start, views=(0, 2, 4), lr=0.05, **common)
        np.testing.assert_array_equal(new.loss, losses)
        for name in TEXTURES:
            np.testing.assert_array_equal(new.textures[name], textures[name].reshape(new.textures[name].shape))
        # One learning rate given per texture, all equal, is the same run.
        same, _ = run(mi, capture, start, views=(0, 2, 4), lr=dict.fromkeys(TEXTURES, 0.05), **common)
        np.testing.assert_array_equal(same.loss, losses)


def test_two_views_per_step_take_half_the_steps_and_lower_the_loss(mi, capture):
    start = inv.constant_textures(TEXELS)
    result, reports = run(mi, capture, start, views=range(4), epochs=4, spp=8, lr=0.05, views_per_step=2)
    assert len(result.loss) == 4 * 2 and [len(v) for v in result.views] == [2] * 8
    assert result.epoch.tolist() == [1, 1, 2, 2, 3, 3, 4, 4]
    for epoch in range(4):  # every view once per epoch, in the epoch's seeded order
        assert list(result.views[2 * epoch] + result.views[2 * epoch + 1]) == list(inv.view_order(0, epoch, 4))
    assert result.epoch_loss[-1] < 0.7 * result.epoch_loss[0]  # measured: 0.50-0.52 over seeds 0-4
    np.testing.assert_allclose(result.epoch_loss, result.loss.reshape(4, 2).mean(axis=1))
    table = inv.step_table(result, ("a", "b", "c", "d"))
    assert table["view"][0] == "+".join("abcd"[k] for k in result.views[0])
    assert table["epoch"].tolist() == result.epoch.tolist() and table["iteration"].tolist() == list(range(8))
    # An odd count: the last step of an epoch takes the view left over.
    odd, _ = run(mi, capture, start, views=range(3), epochs=1, spp=4, lr=0.05, views_per_step=2)
    assert [len(v) for v in odd.views] == [2, 1] and sorted(odd.views[0] + odd.views[1]) == [0, 1, 2]


def test_every_render_of_a_run_has_its_own_seeds():
    seeds = [inv.render_seeds(7, render) for render in range(1000)]
    assert len({primal for primal, _ in seeds}) == 1000 and len({adjoint for _, adjoint in seeds}) == 1000
    assert not {primal for primal, _ in seeds} & {adjoint for _, adjoint in seeds}


def test_l1rel_is_the_log_of_radiance_plus_eps(mi):
    image = np.array([[[0.0, 0.1, 1.0], [-0.2, 0.5, 2.0]]], np.float32)  # negative radiance counts as 0
    reference = np.array([[[0.01, 0.2, 0.5], [0.0, 0.5, 1.0]]], np.float32)
    weight = np.array([[[1.0], [3.0]]], np.float32)
    eps = 0.05
    by_hand = [abs(np.log(eps) - np.log(0.06)) + abs(np.log(0.15) - np.log(0.25)) + abs(np.log(1.05) - np.log(0.55)),
               abs(np.log(eps) - np.log(eps)) + 0.0 + abs(np.log(2.05) - np.log(1.05))]
    expected = (by_hand[0] + 3 * by_hand[1]) / (3 * 4)
    value = inv.image_loss(mi, mi.TensorXf(image), mi.TensorXf(reference), mi.TensorXf(weight), "l1rel", eps)
    assert float(value.array[0]) == pytest.approx(expected, rel=1e-5)


def test_a_texture_with_learning_rate_zero_does_not_move(mi, capture):
    start = inv.constant_textures(TEXELS)
    result, _ = run(mi, capture, start, views=(0, 3), epochs=1, spp=8, tv_weight=0.05,
                    lr={"base_color": 0.1, "roughness": 0.0, "metallic": 0.0})
    np.testing.assert_array_equal(result.textures["roughness"], start["roughness"])
    np.testing.assert_array_equal(result.textures["metallic"], start["metallic"])
    change = result.textures["base_color"] - start["base_color"]
    assert change[..., 0].max() > 0.05 and change[..., 1].min() < -0.05


def test_per_texture_tv_weights_act_on_their_own_channels(mi):
    rng = np.random.default_rng(1)
    textures = {"base_color": rng.uniform(0, 1, (5, 5, 3)), "roughness": rng.uniform(0, 1, (5, 5, 1)),
                "metallic": rng.uniform(0, 1, (5, 5, 1))}
    tensors = {name: mi.TensorXf(t.astype(np.float32)) for name, t in textures.items()}
    weights = {"base_color": 0.5, "roughness": 0.0, "metallic": 2.0}

    def tv(t):
        return (np.abs(np.diff(t, axis=0)).sum() + np.abs(np.diff(t, axis=1)).sum()) / (4 * 5 + 5 * 4)

    expected = sum(w * tv(textures[name]) for name, w in weights.items())
    value = inv.texture_regulariser(mi, tensors, weights)
    assert float(value.array[0]) == pytest.approx(expected, rel=1e-5)
    same = inv.texture_regulariser(mi, tensors, dict.fromkeys(TEXTURES, 0.3))
    assert float(same.array[0]) == pytest.approx(float(inv.texture_regulariser(mi, tensors, 0.3).array[0]), rel=1e-5)
    assert inv.texture_regulariser(mi, tensors, dict.fromkeys(TEXTURES, 0.0)) is None
    assert inv.texture_regulariser(mi, tensors, 0.0) is None


def test_cosine_decay_schedule():
    factors = [inv.lr_factor("cosine", step, 8) for step in range(8)]
    expected = [0.5 * (1 + np.cos(np.pi * step / 8)) for step in range(8)]
    np.testing.assert_allclose(factors, expected, rtol=1e-12)
    assert factors[0] == 1.0 and factors[4] == pytest.approx(0.5) and factors[-1] == pytest.approx(0.0381, abs=1e-4)
    assert [inv.lr_factor("none", step, 8) for step in range(8)] == [1.0] * 8
    settings = inv.InverseSettings(lr={"base_color": 0.02, "roughness": 0.01, "metallic": 0.0}, lr_decay="cosine")
    assert settings.learning_rates(4, 8) == pytest.approx({"base_color": 0.01, "roughness": 0.005, "metallic": 0.0})
    assert inv.InverseSettings(lr=0.02).learning_rates(3, 8) == 0.02
    with pytest.raises(ValueError, match=r"step must be in \[0, 8\), got 8"):
        inv.lr_factor("cosine", 8, 8)


def test_the_optimiser_follows_the_cosine_schedule(mi, capture, monkeypatch):
    import drjit as dr

    rates = []
    set_rate = dr.opt.Adam.set_learning_rate

    def recording(self, value=None, /, **kwargs):
        rates.append(value)
        set_rate(self, value, **kwargs)

    monkeypatch.setattr(dr.opt.Adam, "set_learning_rate", recording)
    start = inv.constant_textures(TEXELS)
    run(mi, capture, start, views=range(4), epochs=2, spp=2, lr=0.04, lr_decay="cosine", views_per_step=2)
    np.testing.assert_allclose(rates, [0.04 * 0.5 * (1 + np.cos(np.pi * s / 4)) for s in range(4)], rtol=1e-12)
    rates.clear()
    run(mi, capture, start, views=(0,), epochs=2, spp=2, lr={"base_color": 0.04, "roughness": 0.02, "metallic": 0.0},
        lr_decay="cosine")
    assert rates == [{"object.bsdf.base_color.data": 0.04, "object.bsdf.roughness.data": 0.02,
                      "object.bsdf.metallic.data": 0.0},
                     {"object.bsdf.base_color.data": pytest.approx(0.02), "object.bsdf.roughness.data": pytest.approx(0.01),
                      "object.bsdf.metallic.data": 0.0}]


def test_a_runs_settings_come_from_the_config_with_finetune_overriding_and_a_seed_per_run(repo):
    from freqbrdf.estimate.mitsuba_settings import InverseSettings, run_settings

    config = yaml.safe_load((repo / "config" / "config.yaml").read_text())
    config["mitsuba"].update(epochs=7, spp=5, finetune={"epochs": 2, "spp": 16})
    base = run_settings(config, "sphere", "studio", "gt", "mitsuba")
    tuned = run_settings(config, "sphere", "studio", "gt", "freq+mitsuba")
    assert "variant" not in base and "finetune" not in base
    assert (base["epochs"], base["spp"]) == (7, 5) and (tuned["epochs"], tuned["spp"]) == (2, 16)
    assert {k: v for k, v in tuned.items() if k not in ("epochs", "spp", "seed")} == {
        k: v for k, v in base.items() if k not in ("epochs", "spp", "seed")}
    seeds = {run_settings(config, o, e, p, m)["seed"] for o in ("sphere", "torus") for e in ("studio", "sunny")
             for p in ("gt", "colmap") for m in ("mitsuba", "freq+mitsuba")}
    assert len(seeds) == 16
    assert run_settings(config, "sphere", "studio", "gt", "mitsuba") == base
    InverseSettings(**base), InverseSettings(**tuned)


def test_the_loss_levels_off_when_a_window_falls_by_less_than_its_share():
    """stop_epoch on a loss that halves each epoch to a floor: windows of 2 epochs compared."""
    loss = np.array([8.0, 4.0, 2.0, 1.0, 1.0, 1.0, 1.0, 1.0])
    # epoch 4: (8 + 4) / 2 = 6 -> (2 + 1) / 2 = 1.5, a 75% fall; epoch 6: 1.5 -> 1.0 (33%);
    # epoch 7: (1 + 1) / 2 -> 1: 0%
    assert inv.stop_epoch(loss, 2, 0.01) == 7
    assert inv.stop_epoch(loss, 2, 0.5) == 6
    assert inv.stop_epoch(loss, 1, 0.01) == 5  # 1.0 -> 1.0
    assert inv.stop_epoch(loss[:6], 2, 0.01) is None  # still falling by its own measure
    assert inv.stop_epoch(np.array([1.0, 1.2, 1.0]), 1, 0.0) == 2  # a rise is no fall


def test_a_run_stops_when_its_training_loss_levels_off_and_else_runs_every_epoch(mi, capture):
    start = inv.constant_textures(TEXELS)
    full, _ = run(mi, capture, start, views=(0, 3), epochs=6, spp=8, lr=0.05, seed=7)
    stopped, reports = run(mi, capture, start, views=(0, 3), epochs=6, spp=8, lr=0.05, seed=7, stop_window=1,
                           stop_fall=0.99)
    # with a fall of 99% demanded, the loss "levels off" at the first comparison: after epoch 2
    assert len(stopped.epoch_loss) == 2 and [r.epoch for r in reports] == [1, 2]
    assert len(full.epoch_loss) == 6  # stop_window 0: every epoch
    np.testing.assert_allclose(stopped.epoch_loss, full.epoch_loss[:2], rtol=1e-5)  # the same run, cut short


def test_coarse_textures_are_block_means_and_need_a_divisible_size():
    textures = {"base_color": np.arange(48, dtype=np.float32).reshape(4, 4, 3) / 48,
                "roughness": np.arange(16, dtype=np.float32).reshape(4, 4) / 16, "metallic": np.zeros((4, 4))}
    coarse = inv.coarse_textures(textures, 1)
    assert coarse["roughness"].shape == (2, 2) and coarse["base_color"].shape == (2, 2, 3)
    assert coarse["roughness"][0, 1] == pytest.approx(np.mean([2, 3, 6, 7]) / 16)
    np.testing.assert_array_equal(inv.coarse_textures(textures, 0)["roughness"], textures["roughness"])
    with pytest.raises(ValueError, match="coarse_levels 3: the textures' 4 texels are not divisible by 8"):
        inv.coarse_textures(textures, 3)
    with pytest.raises(ValueError, match=r"epochs \(2\) must exceed coarse_levels x coarse_epochs \(2 x 1\)"):
        inv.InverseSettings(epochs=2, coarse_levels=2)


def test_coarse_to_fine_doubles_the_textures_on_schedule_and_ends_at_full_resolution(mi, capture):
    """Two levels of two epochs each: epochs 1-2 at R/4, 3-4 at R/2, 5 at R. Evaluated at full size
    whatever the level (a coarse texel repeated over its block), and the run ends at full size."""
    settings = inv.InverseSettings(max_depth=4, epochs=5, spp=8, lr=0.05, seed=7, coarse_levels=2, coarse_epochs=2)
    assert [e for e in range(5) if settings.doubles_before(e)] == [2, 4] and settings.full_resolution_from == 4
    seen = []
    result = inv.optimise_textures(mi, capture["mesh"], capture["env"], *subset(capture, [0, 3]),
                                   inv.constant_textures(TEXELS), settings,
                                   evaluate=lambda tex: seen.append(tex["roughness"].copy()) or {"mse_average": 0.0})

    def blocky(texture, size):
        blocks = texture.reshape(TEXELS // size, size, TEXELS // size, size)
        return bool((blocks == blocks[:, :1, :, :1]).all())

    assert [t.shape for t in seen] == [(TEXELS, TEXELS)] * 6
    assert blocky(seen[2], 4) and not blocky(seen[2], 8)  # after epoch 2: R/4, and it moved
    assert blocky(seen[4], 2) and not blocky(seen[4], 4)  # after epoch 4: R/2
    assert not blocky(seen[5], 2)  # full resolution
    assert result.textures["roughness"].shape == (TEXELS, TEXELS)
