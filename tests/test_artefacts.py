"""Tests for freqbrdf.artefacts: every artefact round-trips, and readers name what is wrong."""

from __future__ import annotations

import numpy as np
import pytest

from freqbrdf import artefacts as af
from freqbrdf.util.io import read_json, write_exr, write_json
from freqbrdf.artefacts import SurfaceTexels


def surface_texels(n: int, resolution: int = 8) -> SurfaceTexels:
    rng = np.random.default_rng(0)
    frame = np.linalg.qr(rng.normal(size=(n, 3, 3)))[0]
    return SurfaceTexels(resolution, rng.permutation(resolution * resolution)[:n], rng.normal(size=(n, 3)),
                         frame[:, 2], frame[:, 0], frame[:, 1], rng.random(n) < 0.2)


def random_svbrdf(resolution: int, seed: int = 0) -> af.Svbrdf:
    rng = np.random.default_rng(seed)
    return af.Svbrdf(rng.random((resolution, resolution, 3), np.float32), rng.random((resolution, resolution), np.float32),
                     rng.random((resolution, resolution), np.float32))


def test_observations_round_trip_in_chunks(tmp_path):
    texels = surface_texels(10)
    rng = np.random.default_rng(1)
    chunks = [{"radiance": rng.random((n, 4, 3)), "weight": rng.random((n, 4)) * (rng.random((n, 4)) > 0.5),
               "wo_local": rng.normal(size=(n, 4, 3)), "incoming": rng.random((n, 4, 3))} for n in (6, 4)]
    writer = af.ObservationsWriter(tmp_path, texels, ["a", "b", "c", "d"])
    writer.write(0, chunks[0])
    writer.write(6, chunks[1])
    counts = writer.views_per_texel()
    writer.close({"band_limit": {"rule": "paper", "a_prime": 0.5}, "poses": "gt"})
    obs = af.read_observations(tmp_path)
    for name in ("radiance", "weight", "wo_local", "incoming"):
        np.testing.assert_array_equal(getattr(obs, name), np.concatenate([c[name] for c in chunks]).astype(np.float32))
    np.testing.assert_array_equal(obs.texels.texel, texels.texel)
    np.testing.assert_array_equal(obs.texels.dilated, texels.dilated)
    assert obs.texels.resolution == 8 and obs.a_prime == 0.5 and obs.meta["views"] == ["a", "b", "c", "d"]
    np.testing.assert_array_equal(obs.observed, counts > 0)
    # rows of the frame are the local axes: it takes the normal to +z
    np.testing.assert_allclose(np.einsum("tij,tj->ti", obs.frame, texels.normal), np.tile([0.0, 0.0, 1.0], (10, 1)),
                               atol=1e-12)


def test_observations_reader_names_the_bad_file(tmp_path):
    texels = surface_texels(3)
    writer = af.ObservationsWriter(tmp_path, texels, ["a", "b"])
    writer.close({"band_limit": {"a_prime": 0.5}})
    np.save(tmp_path / "weight.npy", np.zeros((3, 5), np.float32))
    with pytest.raises(ValueError, match=r"weight.npy: shape \(3, 5\), expected \(3, 2\)"):
        af.read_observations(tmp_path)
    meta = read_json(tmp_path / "views.json")
    write_json(tmp_path / "views.json", meta | {"format": "freqbrdf-observations/0"})
    with pytest.raises(ValueError, match=r"views.json: format is 'freqbrdf-observations/0'"):
        af.read_observations(tmp_path)


def test_sh_fit_round_trip_and_format_check(tmp_path):
    rng = np.random.default_rng(2)
    fit = af.ShFit(rng.random((5, 9, 3)), rng.random((5, 9, 3)), rng.random(5), rng.random((5, 3, 3)),
                   rng.random((5, 3, 3)), {"a_prime": 0.2, "settings": {"lmax": 2}})
    af.write_sh_fit(tmp_path, fit)
    back = af.read_sh_fit(tmp_path)
    np.testing.assert_array_equal(back.coeffs_incoming, fit.coeffs_incoming.astype(np.float32))
    assert back.a_prime == 0.2 and back.meta["settings"] == {"lmax": 2}
    np.save(tmp_path / "unit_dc.npy", np.zeros(4, np.float32))
    with pytest.raises(ValueError, match="disagree in the number of texels"):
        af.read_sh_fit(tmp_path)
    write_json(tmp_path / "fit.json", {"format": "other"})
    with pytest.raises(ValueError, match="fit.json: format is 'other'"):
        af.read_sh_fit(tmp_path)


def test_svbrdf_round_trip_with_previews(tmp_path):
    svbrdf = random_svbrdf(8)
    af.write_svbrdf(tmp_path, svbrdf)
    back = af.read_svbrdf(tmp_path)
    assert list(back) == list(af.TEXTURES) and back.resolution == 8
    for name in af.TEXTURES:
        np.testing.assert_array_equal(back[name], svbrdf[name])
        assert (tmp_path / f"{name}.png").is_file()
    # the same files named one by one
    back = af.read_svbrdf({name: tmp_path / f"{name}.exr" for name in af.TEXTURES})
    np.testing.assert_array_equal(back.metallic, svbrdf.metallic)


def test_svbrdf_files_are_checked_naming_the_bad_file(tmp_path):
    af.write_svbrdf(tmp_path, random_svbrdf(8))
    write_exr(tmp_path / "metallic.exr", np.zeros((4, 8)))
    with pytest.raises(ValueError, match=r"metallic.exr: metallic texture is \(4, 8\), but base_color is \(8, 8\)"):
        af.read_svbrdf(tmp_path)
    write_exr(tmp_path / "metallic.exr", np.zeros((8, 8, 3)))
    with pytest.raises(ValueError, match="metallic.exr: metallic texture has 3 channels, expected 1"):
        af.read_svbrdf(tmp_path)
    write_exr(tmp_path / "metallic.exr", np.full((8, 8), 1.5))
    with pytest.raises(ValueError, match=r"metallic.exr: metallic values span \[1.5, 1.5\]"):
        af.read_svbrdf(tmp_path)
    (tmp_path / "metallic.exr").unlink()
    with pytest.raises(Exception, match="metallic.exr"):
        af.read_svbrdf(tmp_path)
    with pytest.raises(ValueError, match=r"roughness must have shape \(8, 8\)"):
        af.Svbrdf(np.zeros((8, 8, 3)), np.zeros((4, 4)), np.zeros((8, 8)))


def test_svbrdf_from_and_at_texels_are_inverse_on_known_texels():
    texel = np.array([3, 10, 17, 60])
    values = {"base_color": np.array([[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9], [1.0, 0.0, 0.5]]),
              "roughness": np.array([0.1, 0.5, 1.4, 0.2]), "metallic": np.array([0.0, 1.0, 0.5, -0.2])}
    known = np.array([True, True, True, False])
    svbrdf = af.Svbrdf.from_texels(8, texel, values, known)
    back = svbrdf.at_texels(texel)
    np.testing.assert_allclose(back["base_color"][:3], values["base_color"][:3], rtol=1e-6)
    np.testing.assert_allclose(back["roughness"][:3], [0.1, 0.5, 1.0], rtol=1e-6)  # clipped to [0, 1]
    np.testing.assert_allclose(back["metallic"][3], back["metallic"][2])  # unknown: its nearest known texel (17)


def test_entropy_round_trip(tmp_path):
    texels = surface_texels(5, resolution=4)
    entropy = np.linspace(0.0, 0.8, 5)
    written = af.write_entropy(tmp_path, texels, entropy, entropy > 0.5)
    back = af.read_entropy(tmp_path)
    np.testing.assert_allclose(back.texel_entropy, entropy, rtol=1e-6)
    np.testing.assert_array_equal(back.unobserved, entropy > 0.5)
    np.testing.assert_allclose(back.atlas.ravel()[texels.texel], entropy, rtol=1e-6)
    outside = np.setdiff1d(np.arange(16), texels.texel)
    np.testing.assert_array_equal(back.atlas.ravel()[outside], 1.0)
    np.testing.assert_array_equal(written.atlas, back.atlas)


def test_texel_sample_is_seeded_sorted_and_drawn_from_the_candidates():
    candidates = np.arange(0, 100, 3)
    a, b = af.sample_texels(candidates, 10, seed=4), af.sample_texels(candidates, 10, seed=4)
    np.testing.assert_array_equal(a, b)
    assert len(a) == 10 and np.isin(a, candidates).all() and np.all(np.diff(a) > 0)
    assert not np.array_equal(a, af.sample_texels(candidates, 10, seed=5))
    np.testing.assert_array_equal(af.sample_texels(candidates[::-1], 1000, seed=0), candidates)
    with pytest.raises(ValueError, match="no texel to sample"):
        af.sample_texels(np.zeros(0, int), 3, seed=0)
    with pytest.raises(ValueError, match="texels must be"):
        af.sample_texels(candidates, 0, seed=0)
