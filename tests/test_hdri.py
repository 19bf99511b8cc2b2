"""Captured HDR light: the package's maps, their integrity, and the clean-up of their ringing."""

import shutil

import numpy as np
import pytest
from PIL import Image

from freqbrdf.scene import assets, hdri
from freqbrdf.sphere.sampling import equirect_solid_angles
from freqbrdf.sphere.sh import project_equirect
from synthetic import fake_package


@pytest.fixture(scope="module")
def package(tmp_path_factory):
    """The package's tarball, fetched as rule fetch_asset_package fetches it (npm's cache keeps it local)."""
    return assets.fetch_package(tmp_path_factory.mktemp("resources"))


def power(env):
    return float((np.asarray(env, np.float64) * equirect_solid_angles(*env.shape[:2])[:, None, None]).sum())


def test_the_twelve_maps_decode_as_ringing_hdr_equirect_maps(package):
    peaks = []
    for name in hdri.MAPS:
        env = hdri.read_map(package, name)
        assert env.shape == (256, 512, 3) and env.dtype == np.float32 and np.isfinite(env).all()
        assert (env < 0).any()  # the artefact this module cleans
        peaks.append(env.max() / (power(env) / (4 * np.pi)))
    # HDR: suns and lamps hundreds to tens of thousands of times the mean (measured 8 to 3e4)
    assert min(peaks) > 3 and sum(p > 100 for p in peaks) >= 6 and max(peaks) > 1e4


def test_a_map_outside_the_twelve_is_refused_naming_them(package):
    with pytest.raises(ValueError, match=r"'moon' is not one of the maps the project uses: studio, sunset") as info:
        hdri.read_map(package, "moon")
    assert "\n" not in str(info.value)


def test_a_changed_tarball_is_refused_and_a_missing_npm_is_named(package, tmp_path):
    changed = tmp_path / assets.TARBALL
    changed.write_bytes(package.read_bytes() + b"\0")
    with pytest.raises(RuntimeError, match=r"pmndrs-assets-1\.7\.0\.tgz: not @pmndrs/assets@1\.7\.0"):
        assets.fetch_package(tmp_path, npm="no-such-npm")
    with pytest.raises(RuntimeError, match=r"^no-such-npm: not found; .*@pmndrs/assets@1\.7\.0"):
        assets.fetch_package(tmp_path / "empty", npm="no-such-npm")
    shutil.copy(package, changed)
    assert assets.fetch_package(tmp_path, npm="no-such-npm") == changed  # present and intact: npm not needed


def ring(height=32, seed=0):
    """A smooth map plus two rings of alternating sign around bright texels, each ring's sum positive."""
    rng = np.random.default_rng(seed)
    env = 1.0 + 0.2 * rng.random((height, 2 * height, 3))
    for i, j, peak in ((8, 10, 500.0), (20, 40, 80.0)):
        env[i, j] += peak
        for di, dj, f in ((0, 1, -0.15), (0, -1, -0.15), (1, 0, -0.15), (-1, 0, -0.15), (0, 2, 0.05), (2, 0, 0.05)):
            env[i + di, j + dj] += f * peak
    return env


def test_cleaning_removes_negatives_keeps_the_power_and_leaves_far_texels_alone():
    env = ring()
    assert (env < 0).any()
    cleaned, cleaning = hdri.clean_envmap(env, radius=2)
    assert cleaned.min() >= 0 and cleaning.negative == int((env < 0).any(axis=2).sum()) and cleaning.regions == 2
    assert power(cleaned) == pytest.approx(power(env), rel=1e-6) and abs(cleaning.energy_change) < 1e-9
    far = np.ones(env.shape[:2], bool)
    far[8 - 4:8 + 5, 10 - 4:10 + 5] = far[20 - 4:20 + 5, 40 - 4:40 + 5] = False
    assert np.array_equal(cleaned[far], env[far].astype(np.float32))
    assert bool(cleaning) and not hdri.clean_envmap(np.abs(env))[1]


def test_a_region_whose_ringing_sums_below_zero_turns_black_and_the_gain_is_reported():
    env = np.ones((16, 32, 3))
    env[8, 8] = -40.0
    cleaned, cleaning = hdri.clean_envmap(env, radius=1)
    assert np.all(cleaned[7:10, 7:10] == 0) and cleaned[0, 0, 0] == 1
    assert cleaning.energy_change == pytest.approx(power(cleaned) / power(env) - 1)
    assert "1 negative and 0 non-finite texels cleaned (1 regions" in cleaning.describe()


def test_nonfinite_texels_take_their_neighbours_mean_and_a_mostly_invalid_map_is_refused():
    env = np.full((16, 32, 3), 2.0)
    env[5, 5] = np.nan
    env[5, 6, 1] = np.inf
    cleaned, cleaning = hdri.clean_envmap(env)
    assert cleaning.nonfinite == 2 and np.all(cleaned == 2.0)
    bad = np.full((16, 32, 3), -1.0)
    bad[:, :8] = 1.0
    with pytest.raises(ValueError, match=r"^my\.exr: 384 of 512 texels are negative or non-finite \(more than 10%\)"):
        hdri.clean_envmap(bad, source="my.exr")


def test_cleaning_recovers_a_lanczos_resampled_sun_where_clamping_does_not():
    """Oracle: a sun on a smooth map, area-averaged (truth) or Lanczos-resampled (ringing) from 4x."""
    height = 64
    fine = np.ones((4 * height, 8 * height, 3)) + np.linspace(0, 1, 8 * height)[None, :, None]
    fine[80:83, 198:201] += 3e4 * 16 / 9 * 1.5

    def down(method):
        return np.stack([np.asarray(Image.fromarray(fine[..., c].astype(np.float32), "F").resize(
            (2 * height, height), method)) for c in range(3)], axis=-1).astype(np.float64)

    truth, ringing = down(Image.BOX), down(Image.LANCZOS)
    assert (ringing < 0).any()
    reference = project_equirect(truth.astype(np.float32), 12)

    def error(env):
        return np.linalg.norm(project_equirect(np.asarray(env, np.float32), 12) - reference) / np.linalg.norm(reference)

    # measured: ringing 0.040, cleaned 0.052, clamped 0.289
    cleaned = hdri.clean_envmap(ringing)[0]
    assert error(cleaned) < 1.5 * error(ringing) and error(cleaned) < error(np.maximum(ringing, 0)) / 4


def test_downsampling_averages_blocks_by_solid_angle():
    rng = np.random.default_rng(1)
    env = rng.random((64, 128, 3))
    small = hdri.downsample(env, 16)
    assert small.shape == (16, 32, 3)
    assert power(small) == pytest.approx(power(env), rel=2e-2)
    assert np.allclose(hdri.downsample(np.full((64, 128, 3), 3.0), 8), 3.0)
    with pytest.raises(ValueError, match=r"envmaps\.height 24 must divide the map's 64 rows"):
        hdri.downsample(env, 24)


def test_the_config_allows_exactly_the_twelve_maps_and_names_a_wrong_one(repo):
    import yaml

    from freqbrdf.config import ConfigError, check_config

    schema_file = repo / "workflow" / "schemas" / "config.schema.yaml"
    schema = yaml.safe_load(schema_file.read_text())
    branches = schema["properties"]["envs"]["additionalProperties"]["allOf"]
    hdri_branch = next(b["then"] for b in branches if b["if"]["properties"]["kind"]["const"] == "hdri")
    assert tuple(hdri_branch["properties"]["map"]["enum"]) == hdri.MAPS
    config = yaml.safe_load((repo / "config" / "config.yaml").read_text())
    config["envs"]["outdoor"] = {"kind": "hdri", "map": "sky", "rotation_deg": 90.0}
    check_config(config, schema_file)
    config["envs"]["outdoor"]["map"] = "moon"
    with pytest.raises(ConfigError, match=r"config key envs\.outdoor\.map: 'moon' is not one of \['studio'"):
        check_config(config, schema_file)


def test_the_decoder_returns_a_known_map_exactly(tmp_path):
    import OpenEXR

    rng = np.random.default_rng(4)
    known = (rng.random((8, 16, 3)) * 100 - 5).astype(np.float16)  # half floats, as the package stores them
    OpenEXR.File({"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}, {"RGB": known}).write(
        str(tmp_path / "map.exr"))
    fake_package(tmp_path / "fake.tgz", {"package/hdri/sky.exr.js": (tmp_path / "map.exr").read_bytes()})
    decoded = hdri.read_map(tmp_path / "fake.tgz", "sky")
    assert decoded.dtype == np.float32 and np.array_equal(decoded, known.astype(np.float32))
    with pytest.raises(ValueError, match=r"fake\.tgz: no member package/hdri/city\.exr\.js"):
        hdri.read_map(tmp_path / "fake.tgz", "city")
