"""glTF export (freqbrdf.export.gltf), .hdr environments (freqbrdf.export.rgbe) and the viewer page (freqbrdf.export.viewer)."""

from __future__ import annotations

import io
import json
import os
import re
import struct
import subprocess
import sys

import numpy as np
import pytest

from freqbrdf.artefacts import read_svbrdf, write_svbrdf
from freqbrdf.scene.cameras import Cameras, hemisphere_rig, intrinsics
from freqbrdf.util.colour import to_srgb
from freqbrdf.scene.envmaps import studio
from freqbrdf.export.gltf import (GltfMaterial, encode_png, glb_bytes, material_images, quantise, read_glb, srgb_to_linear,
                           write_glb)
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import read_ply, write_ply
from freqbrdf.scene.render import relit_views
from freqbrdf.export.rgbe import decode_rgbe, encode_rgbe, hdr_bytes, read_hdr, write_hdr
from freqbrdf.scene.textures import svbrdf_textures
from freqbrdf.export.viewer import Panel, overlay_image, posterior_overlay, viewer_html

HALF_STEP = 0.5 / 255.0


@pytest.fixture(scope="module")
def textures():
    return svbrdf_textures(32, seed=3, cells=6)


@pytest.fixture(scope="module")
def sphere(tmp_path_factory):
    """The sphere as the pipeline stores it (float32 PLY)."""
    path = tmp_path_factory.mktemp("mesh") / "mesh.ply"
    write_ply(path, make_mesh("sphere"))
    return read_ply(path)


def glb_chunks(data: bytes) -> tuple[dict, bytes]:
    """Independent oracle: the JSON and binary chunks of a .glb, by the container layout of the glTF spec."""
    magic, version, length = struct.unpack("<4sII", data[:12])
    assert (magic, version, length) == (b"glTF", 2, len(data))
    json_length, json_type = struct.unpack("<I4s", data[12:20])
    assert json_type == b"JSON"
    document = json.loads(data[20 : 20 + json_length])
    bin_length, bin_type = struct.unpack("<I4s", data[20 + json_length : 28 + json_length])
    assert bin_type == b"BIN\0"
    return document, data[28 + json_length : 28 + json_length + bin_length]


def oracle_image(document: dict, blob: bytes, texture_index: int) -> np.ndarray:
    from PIL import Image

    image = document["images"][document["textures"][texture_index]["source"]]
    view = document["bufferViews"][image["bufferView"]]
    png = blob[view.get("byteOffset", 0) : view.get("byteOffset", 0) + view["byteLength"]]
    return np.asarray(Image.open(io.BytesIO(png)))


def test_srgb_decoding_inverts_the_encoding():
    x = np.linspace(0.0, 1.0, 1001)
    assert np.abs(srgb_to_linear(to_srgb(x)) - x).max() < 1e-12
    assert srgb_to_linear(0.5) == pytest.approx(0.21404, abs=1e-5)  # sRGB 0.5 is linear 0.214
    assert list(quantise(np.array([0.0, HALF_STEP * 0.99, 1.0, 2.0]))) == [0, 0, 255, 255]


def test_glb_holds_the_exr_textures_within_8_bit_quantisation(tmp_path, textures, sphere):
    write_svbrdf(tmp_path / "estimate", textures)
    svbrdf = read_svbrdf(tmp_path / "estimate")
    write_glb(tmp_path / "freq.glb", sphere, [GltfMaterial.from_textures("freq", svbrdf)])
    document, blob = glb_chunks((tmp_path / "freq.glb").read_bytes())

    # Read back by the oracle: the material's two textures, as glTF defines them.
    pbr = document["materials"][0]["pbrMetallicRoughness"]
    base = oracle_image(document, blob, pbr["baseColorTexture"]["index"])
    packed = oracle_image(document, blob, pbr["metallicRoughnessTexture"]["index"])
    assert base.dtype == np.uint8 and base.shape == (32, 32, 3) and packed.shape == (32, 32, 3)
    # base colour is sRGB-encoded: within half a step of the encoded EXR value
    assert np.abs(base / 255.0 - to_srgb(svbrdf.base_color)).max() <= HALF_STEP + 1e-9
    # so after decoding, within the linear width of half an sRGB step
    slope = np.gradient(srgb_to_linear(np.linspace(0, 1, 256)), 1 / 255)
    assert np.all(np.abs(srgb_to_linear(base / 255.0) - svbrdf.base_color) <= HALF_STEP * slope.max() + 1e-9)
    # roughness in G, metallic in B, linear; R unused (occlusion 1)
    assert np.abs(packed[..., 1] / 255.0 - svbrdf.roughness).max() <= HALF_STEP + 1e-9
    assert np.abs(packed[..., 2] / 255.0 - svbrdf.metallic).max() <= HALF_STEP + 1e-9
    assert np.all(packed[..., 0] == 255)
    # the textures vary: this is not a test of constants
    assert base.std() > 10 and packed[..., 1].std() > 10 and packed[..., 2].std() > 10

    # Geometry: float32 attributes equal to the PLY's, indices equal
    primitive = document["meshes"][document["nodes"][0]["mesh"]]["primitives"][0]
    accessor = document["accessors"][primitive["attributes"]["POSITION"]]
    view = document["bufferViews"][accessor["bufferView"]]
    positions = np.frombuffer(blob, "<f4", accessor["count"] * 3, view.get("byteOffset", 0)).reshape(-1, 3)
    assert np.array_equal(positions, sphere.vertices.astype(np.float32))
    assert accessor["min"] == pytest.approx(sphere.vertices.min(axis=0)) and accessor["max"] == pytest.approx(
        sphere.vertices.max(axis=0))

    # freqbrdf's own reader finds the same
    scene = read_glb(tmp_path / "freq.glb")
    assert [m.name for m in scene.materials] == ["freq"]
    for field in ("vertices", "normals", "uvs", "faces"):
        assert np.array_equal(getattr(scene.mesh, field), getattr(sphere, field)), field
    decoded = scene.materials[0].textures()
    assert np.allclose(decoded["base_color"], srgb_to_linear(base / 255.0), atol=1e-6)
    assert np.abs(decoded["roughness"] - svbrdf.roughness).max() <= HALF_STEP + 1e-6
    assert np.abs(decoded["metallic"] - svbrdf.metallic).max() <= HALF_STEP + 1e-6


def test_several_materials_share_one_geometry(textures, sphere, tmp_path):
    a = GltfMaterial.from_textures("truth", textures)
    b = GltfMaterial.from_textures("freq", {**textures, "roughness": 1.0 - textures["roughness"]})
    one, two = glb_bytes(sphere, [a]), glb_bytes(sphere, [a, b])
    assert len(two) - len(one) < len(b.base_color_png) + len(b.metallic_roughness_png) + 2000  # no second mesh (700 kB)
    document, _ = glb_chunks(two)
    assert [n["name"] for n in document["nodes"]] == ["truth", "freq"]
    (tmp_path / "two.glb").write_bytes(two)
    scene = read_glb(tmp_path / "two.glb")
    assert np.abs(scene.material("freq").textures()["roughness"] - (1.0 - textures["roughness"])).max() <= HALF_STEP + 1e-6
    with pytest.raises(ValueError, match="unique"):
        glb_bytes(sphere, [a, a])


def test_bad_inputs_fail_naming_the_file_or_value(tmp_path, textures):
    bad = tmp_path / "bad.glb"
    bad.write_bytes(b"PLY not a glb at all")
    with pytest.raises(ValueError, match=r"bad\.glb: not a binary glTF 2\.0 file"):
        read_glb(bad)
    with pytest.raises(ValueError, match=r"missing\.glb: cannot read"):
        read_glb(tmp_path / "missing.glb")
    good = glb_bytes(make_mesh("sphere"), [GltfMaterial.from_textures("x", textures)])
    (tmp_path / "index.glb").write_bytes(good.replace(b'"source":1', b'"source":7', 1))  # no image 7
    with pytest.raises(ValueError, match=r"index\.glb: malformed glTF document \(IndexError"):
        read_glb(tmp_path / "index.glb")
    with pytest.raises(ValueError, match="roughness texture is"):
        material_images({**textures, "roughness": textures["roughness"][:16]})
    with pytest.raises(ValueError, match=r"material 'x' baseColorTexture: not a readable PNG"):
        GltfMaterial("x", b"nope", encode_png(np.zeros((2, 2, 3), np.uint8))).textures()


def test_rgbe_keeps_each_pixel_within_its_shared_exponent_precision(tmp_path):
    rng = np.random.default_rng(0)
    image = rng.lognormal(0.0, 3.0, (6, 300, 3))  # 300 wide: several literal runs per scanline
    image[0, 0] = 0.0
    image[1, 1] = [1e5, 1e-3, 3.0]  # a sun beside dark channels
    write_hdr(tmp_path / "env.hdr", image)
    back = read_hdr(tmp_path / "env.hdr")
    peak = image.max(axis=2, keepdims=True)
    assert back.shape == image.shape
    assert np.all(np.abs(back - image) <= peak * (0.5 / 128) + 1e-30)  # half a mantissa step of the largest channel
    assert np.all(back[0, 0] == 0.0)
    assert (tmp_path / "env.hdr").read_bytes().startswith(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 6 +X 300\n")
    # rounding up to a mantissa of 256 moves to the next exponent instead of overflowing
    assert list(encode_rgbe(np.full((1, 1, 3), 255.9 / 256))[0, 0]) == [128, 128, 128, 129]
    assert decode_rgbe(encode_rgbe(np.full((1, 1, 3), 255.9 / 256)))[0, 0, 0] == 1.0


def test_hdr_errors_name_the_problem(tmp_path):
    with pytest.raises(ValueError, match="width 4 outside"):
        hdr_bytes(np.ones((2, 4, 3)))
    with pytest.raises(ValueError, match="non-negative"):
        hdr_bytes(-np.ones((2, 8, 3)))
    path = tmp_path / "cut.hdr"
    path.write_bytes(hdr_bytes(np.ones((4, 16, 3)))[:-10])
    with pytest.raises(ValueError, match=r"cut\.hdr: truncated"):
        read_hdr(path)


def test_viewer_page_inlines_everything(textures, sphere):
    materials = [GltfMaterial.from_textures("truth", textures), GltfMaterial.from_textures("freq", textures)]
    panels = [Panel("truth", "Ground truth", None), Panel("freq", "Ours </script> & co", "freq")]
    envs = {"studio": hdr_bytes(studio(16, seed=1))}
    overlays = {"entropy": overlay_image(np.full((32, 32), 0.5)), "freq": posterior_overlay(np.full((32, 32), 0.01))}
    html = viewer_html("sphere <studio>", sphere, materials, panels, envs, overlays, [0, 1, 4], 35.0)
    # nothing to fetch: three inline scripts (data, three.js, viewer), no module, no link
    assert re.findall(r"<script[^>]*>", html) == ['<script type="application/json" id="freqbrdf-data">', "<script>", "<script>"]
    assert "<link" not in html
    assert html.lower().count("</script") == 3  # the three inline scripts' own ends
    data = json.loads(html.split('id="freqbrdf-data">', 1)[1].split("</script>", 1)[0])
    assert data["panels"][1]["label"] == "Ours </script> & co" and list(data["envs"]) == ["studio"]
    assert [p["uncertainty"] for p in data["panels"]] == [None, "freq"] and sorted(data["overlays"]) == ["entropy", "freq"]
    assert "<title>sphere &lt;studio></title>" in html
    with pytest.raises(ValueError, match="disagree"):
        viewer_html("x", sphere, materials[:1], panels, envs, overlays, [0, 1, 4], 35.0)
    with pytest.raises(ValueError, match=r"overlays \['freq'\] are missing"):
        viewer_html("x", sphere, materials, panels, envs, {"entropy": overlays["entropy"]}, [0, 1, 4], 35.0)
    overlay = overlay_image(np.array([[0.0, 1.0]]))
    assert overlay[0, 0, 2] > overlay[0, 0, 0] and overlay[0, 1, 0] > overlay[0, 1, 2]  # Turbo: blue certain, red not
    # the posterior's expected squared error as RMS error: 0.25 (squared: 0.0625) and above is full red
    np.testing.assert_array_equal(posterior_overlay(np.array([[0.0, 0.0625, 4.0]])), overlay_image(np.array([[0.0, 1.0, 1.0]])))
    np.testing.assert_array_equal(posterior_overlay(np.array([[0.01]])), overlay_image(np.array([[0.4]])))


def test_the_viewer_opens_under_the_captures_own_light():
    from freqbrdf.export.viewer import capture_light_first

    envs = {"sky": b"1", "lobby": b"2", "city": b"3"}
    assert list(capture_light_first(envs, "lobby")) == ["lobby", "sky", "city"]
    assert capture_light_first(envs, "lobby")["lobby"] == b"2"
    assert list(capture_light_first(envs, "sky")) == ["sky", "lobby", "city"]
    assert list(capture_light_first(envs, "forest")) == ["sky", "lobby", "city"]  # a real capture's own light


def test_the_viewer_credits_each_third_party_asset_once_with_its_licence(textures, sphere):
    from freqbrdf.export.viewer import asset_credits

    records = [{"object": "bunny", "credit": "the bunny <Stanford>", "licence": "Stanford terms"},
               {"env": "sky", "credit": "Poly Haven", "licence": "CC0-1.0"},
               {"env": "studio", "licence": "generated by FreqBRDF"},
               {"env": "sunset", "credit": "Poly Haven", "licence": "CC0-1.0"}]
    credits = asset_credits(records)
    assert credits == ["the bunny <Stanford> (Stanford terms)", "Poly Haven (CC0-1.0)"]
    materials = [GltfMaterial.from_textures("truth", textures)]
    html = viewer_html("x", sphere, materials, [Panel("truth", "Truth", None)], {"s": hdr_bytes(studio(16, seed=1))},
                       {"entropy": overlay_image(np.zeros((4, 4)))}, [0, 1, 4], 35.0, credits=credits)
    footer = html.split("<footer>", 1)[1].split("</footer>", 1)[0]
    assert "<br>the bunny &lt;Stanford> (Stanford terms)<br>Poly Haven (CC0-1.0)" in footer


def psnr(a: np.ndarray, b: np.ndarray, peak: float) -> float:
    return float(10.0 * np.log10(peak**2 / np.mean((a - b) ** 2)))


def test_ground_truth_glb_rendered_back_matches_the_capture(mi, tmp_path, textures, sphere):
    """The issue's "done when": the ground truth's .glb, its textures read back and rendered with Mitsuba
    from a training view, matches the capture rendered from the EXR textures within their quantisation.
    Both renders use one seed (as rule relight does), so Monte Carlo noise cancels and only the
    8-bit textures differ. A material stored without sRGB encoding (read by glTF rules as sRGB)
    must fail the same bound: the test sees the encoding."""
    size, fov = 48, 35.0
    mesh_path = tmp_path / "mesh.ply"
    write_ply(mesh_path, sphere)
    env = studio(16, seed=1).astype(np.float32)
    w2c = hemisphere_rig(4, 4.0)[:1]
    cameras = Cameras(K=intrinsics(size, size, fov)[None], world_to_camera=w2c, width=size, height=size, names=("000",))

    def render(mesh, texture_set):
        write_ply(tmp_path / "render.ply", mesh)
        return next(relit_views(mi, tmp_path / "render.ply", texture_set, env, cameras, fov_x_deg=fov, spp=16,
                                max_depth=4, seed=7))

    capture = render(sphere, textures)
    write_glb(tmp_path / "truth.glb", sphere, [GltfMaterial.from_textures("truth", textures)])
    scene = read_glb(tmp_path / "truth.glb")
    back = render(scene.mesh, scene.material("truth").textures())
    base_linear, packed = quantise(textures["base_color"]), material_images(textures)[1]
    wrong = GltfMaterial("wrong", encode_png(base_linear), encode_png(packed)).textures()
    unencoded = render(scene.mesh, wrong)

    peak = float(capture.max())
    good, bad = psnr(back, capture, peak), psnr(unencoded, capture, peak)
    print(f"render-back PSNR {good:.1f} dB; without sRGB encoding {bad:.1f} dB")
    assert good > 40.0
    assert bad < 30.0
    # per pixel: no worse than a relative error of the coarsest sRGB step at mid grey (~1.5 %) plus a little
    lit = capture.mean(axis=2) > 0.02 * peak
    rel = np.abs(back - capture)[lit] / np.maximum(capture[lit], 1e-3)
    assert np.percentile(rel, 99) < 0.03


# --------------------------------------------------------------------------
# the viewer in a browser
# --------------------------------------------------------------------------
def viewer_screenshots(repo, page, out, shots):
    """bench/viewer_screenshot.py on ``page``, one screenshot per ``name: options``: its JSON result."""
    command = [sys.executable, str(repo / "bench" / "viewer_screenshot.py"), str(page), "--out", str(out), "--size", "900x500"]
    command += [f"--shot={name}={options}" for name, options in shots.items()]
    run = subprocess.run(command, capture_output=True, text=True, timeout=300)
    if run.returncode == 2 and not os.environ.get("CI"):
        pytest.skip(f"no Chromium for the viewer screenshot ({run.stderr.strip()})")
    assert run.returncode == 0, run.stdout[-2000:] + run.stderr[-3000:]
    return json.loads(run.stdout.strip().splitlines()[-1])


def panel_pixels(image: np.ndarray, panel: dict) -> np.ndarray:
    """The RGB pixels of one panel's drawing area (inset by 2 px from its border)."""
    top, left = int(np.ceil(panel["top"])) + 2, int(np.ceil(panel["left"])) + 2
    bottom, right = int(panel["top"] + panel["height"]) - 2, int(panel["left"] + panel["width"]) - 2
    return image[top:bottom, left:right, :3].astype(np.int64)


def test_viewer_draws_every_model_lit_like_the_capture(repo, mi, tmp_path, textures, sphere):
    """Headless Chromium opens the page, waits until the models have loaded, and the screenshot shows:
    the object in every panel (not the background colour), the ground-truth panel lit as Mitsuba lights
    the capture from the same view (so the environment's orientation and the camera are right: the
    same map turned a quarter round correlates worse), and the overlay's layers (the method's own
    uncertainty, the entropy) and the environment selector changing the picture."""
    from freqbrdf.util.io import read_png
    from freqbrdf.export.viewer import BACKGROUND

    size, fov = 64, 35.0
    env = studio(32, seed=1).astype(np.float32)
    w2c = hemisphere_rig(4, 4.0)[:1]
    cameras = Cameras(K=intrinsics(size, size, fov)[None], world_to_camera=w2c, width=size, height=size, names=("000",))
    write_ply(tmp_path / "mesh.ply", sphere)

    def render(envmap):
        return next(relit_views(mi, tmp_path / "mesh.ply", textures, envmap, cameras, fov_x_deg=fov, spp=32,
                                max_depth=4, seed=1))

    capture, turned = render(env), render(np.roll(env, env.shape[1] // 4, axis=1))
    other = {**textures, "base_color": textures["base_color"][..., ::-1], "roughness": 1.0 - textures["roughness"]}
    materials = [GltfMaterial.from_textures("truth", textures), GltfMaterial.from_textures("freq", other)]
    panels = [Panel("truth", "Ground truth", None), Panel("freq", "Ours", "freq")]
    envs = {"studio": hdr_bytes(env), "dark": hdr_bytes(env * 0.05)}
    # the entropy a gradient across the atlas, the method's own map uniformly red (blue where the entropy is 0)
    overlays = {"entropy": overlay_image(np.tile(np.linspace(0.0, 1.0, 32), (32, 1))),
                "freq": posterior_overlay(np.ones((32, 32)))}
    page = tmp_path / "viewer.html"
    page.write_text(viewer_html("test", sphere, materials, panels, envs, overlays, cameras.centres[0], fov), encoding="utf-8")

    result = viewer_screenshots(repo, page, tmp_path / "shots",
                                {"plain": "rotate=0", "entropy": "rotate=0&overlay=entropy",
                                 "uncertainty": "rotate=0&overlay=uncertainty", "dark": "rotate=0&env=dark"})
    assert result["status"] == "ready" and result["message"] == "2 models loaded", result
    assert [p["name"] for p in result["panels"]] == ["truth", "freq"]
    shots = {name: [panel_pixels(read_png(path), p) for p in result["panels"]] for name, path in result["shots"].items()}

    background = np.array([int(BACKGROUND[i : i + 2], 16) for i in (1, 3, 5)])
    for k, pixels in enumerate(shots["plain"]):
        drawn = np.abs(pixels - background).max(axis=2) > 8
        # the unit sphere at distance 4 in a 35 degree field of view: a disc of radius 0.41 panel widths, 53 %
        print(f"panel {k}: {drawn.mean():.3f} of the pixels drawn, object mean {pixels[drawn].mean():.1f}")
        assert 0.45 < drawn.mean() < 0.62, f"panel {k}: {drawn.mean():.3f} of its pixels differ from the background"
        assert pixels[drawn].std() > 10, f"panel {k}: the object is flat"
    assert np.abs(shots["plain"][0] - shots["plain"][1]).mean() > 5  # different materials look different

    # Ground truth against the capture: same view, resampled to the capture's size.
    from scipy.stats import spearmanr
    from skimage.transform import resize

    truth = resize(shots["plain"][0].astype(float).mean(axis=2), (size, size), anti_aliasing=True)
    inside = resize(np.abs(shots["plain"][0] - background).max(axis=2) > 8, (size, size)) > 0.99
    # rank correlation: the page tone-maps, the capture is linear radiance
    corr = {name: spearmanr(truth[inside], image.mean(axis=2)[inside]).statistic
            for name, image in (("capture", capture), ("turned", turned))}
    print("rank correlation with the capture:", corr)
    assert corr["capture"] > 0.75 and corr["capture"] > corr["turned"] + 0.2

    # Each layer changes the method's panel only, each in its own way; the darker environment darkens both.
    for layer in ("entropy", "uncertainty"):
        assert np.abs(shots[layer][0] - shots["plain"][0]).mean() < 1.0
        assert np.abs(shots[layer][1] - shots["plain"][1]).mean() > 10
    assert np.abs(shots["uncertainty"][1] - shots["entropy"][1]).mean() > 10
    red = shots["uncertainty"][1][..., 0] - shots["uncertainty"][1][..., 2]
    assert np.median(red[np.abs(shots["plain"][1] - background).max(axis=2) > 8]) > 0  # the red map shows
    for k in range(2):
        assert shots["dark"][k].mean() < shots["plain"][k].mean() - 10
