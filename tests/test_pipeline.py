"""End to end: the whole DAG on the tiny preset, caching, and failures that leave nothing behind."""

import re
import subprocess
import sys

import numpy as np
import pytest

from freqbrdf.cameras import cameras_from_json, project
from freqbrdf.io import read_exr, read_json, read_png
from freqbrdf.meshes import read_ply


def snakemake(repo, workdir, *args, extra_config=(), check=True):
    # --configfile takes several values, so it goes last, after any targets.
    configs = [str(repo / "config" / "tiny.yaml"), *map(str, extra_config)]
    command = [sys.executable, "-m", "snakemake", "-s", str(repo / "Snakefile"), "-d", str(workdir), "--cores", "2",
               *args, "--configfile", *configs]
    run = subprocess.run(command, capture_output=True, text=True, timeout=900)
    if check and run.returncode != 0:
        raise AssertionError(f"snakemake {' '.join(args)} failed:\n{run.stderr[-4000:]}")
    return run


def planned_jobs(output: str) -> dict[str, int]:
    table = output.split("Job stats:")[1].split("total")[0]
    return {m.group(1): int(m.group(2)) for m in re.finditer(r"^(\w+)\s+(\d+)$", table, re.M)}


@pytest.fixture(scope="module")
def run(repo, tmp_path_factory):
    workdir = tmp_path_factory.mktemp("pipeline")
    snakemake(repo, workdir)
    return workdir


def test_every_output_is_written(run):
    base = run / "results"
    mesh = read_ply(base / "objects/sphere/mesh.ply")
    assert len(mesh.faces) > 1000
    for name in ("base_color", "roughness", "metallic"):
        texture = read_exr(base / f"objects/sphere/{name}.exr")
        assert texture.shape[:2] == (32, 32) and 0.0 <= texture.min() and texture.max() <= 1.0
        assert (base / f"objects/sphere/{name}.png").is_file()
    for env in ("studio", "museum", "sunny", "overcast"):
        assert read_exr(base / f"envs/{env}.exr").shape == (32, 64, 3)
        assert (base / f"envs/{env}_spectrum.png").is_file()
        assert (base / f"captures/sphere/{env}/test/cameras.json").is_file()
    assert (base / "envs/spectra.png").is_file()
    assert not (base / "captures/sphere/sunny/train").exists()  # not a capture env in the tiny preset
    for split in ("train", "test"):
        bench = (base / f"benchmarks/render_capture/sphere_studio_{split}.tsv").read_text().splitlines()
        assert bench[0].startswith("s\th:m:s\tmax_rss") and float(bench[1].split("\t")[0]) > 0


def test_capture_images_masks_and_cameras_agree(run):
    capture = run / "results/captures/sphere/studio/train"
    cameras = cameras_from_json(read_json(capture / "cameras.json"))
    assert len(cameras) == 4 and (cameras.width, cameras.height) == (32, 32)
    for k, name in enumerate(cameras.names):
        image = read_exr(capture / f"images/{name}.exr")
        coverage = read_png(capture / f"masks/{name}.png")
        assert image.shape == (32, 32, 3) and image.min() >= 0.0
        pixels, _ = project(np.zeros((1, 3)), cameras.K[k], cameras.world_to_camera[k])
        px, py = pixels[0]
        assert coverage[int(py), int(px)] == 255  # the object's centre is covered
        assert coverage[0, 0] == 0 and coverage[-1, -1] == 0  # corners show the environment
        assert 0.05 < (coverage > 127).mean() < 0.6


def test_second_run_has_nothing_to_do(repo, run):
    assert "Nothing to be done" in snakemake(repo, run, "-n").stdout


def test_changing_one_env_reruns_only_what_depends_on_it(repo, run, tmp_path):
    changed = tmp_path / "changed.yaml"
    changed.write_text("envs:\n  overcast: {kind: overcast, ground_albedo: 0.4}\n")
    plan = snakemake(repo, run, "-n", extra_config=[changed])
    jobs = planned_jobs(plan.stdout)
    assert jobs == {"build_env": 1, "env_spectrum": 1, "env_spectra": 1, "render_capture": 1, "all": 1}
    assert "results/captures/sphere/overcast/test" in plan.stdout


def test_a_corrupt_environment_fails_naming_the_file_and_leaves_no_output(repo, run):
    env = run / "results/envs/museum.exr"
    good = env.read_bytes()
    try:
        env.write_bytes(b"garbage")  # newer than the captures: their render must rerun
        failed = snakemake(repo, run, "results/captures/sphere/museum/test", check=False)
        assert failed.returncode != 0
        assert "museum.exr: not a readable OpenEXR file" in failed.stderr
        capture_dir = run / "results/captures/sphere/museum"
        assert not (capture_dir / "test").exists() and not (capture_dir / ".test.partial").exists()
    finally:
        env.write_bytes(good)


def test_observations_follow_the_documented_layout(run):
    obs = run / "results/observations/sphere/studio/gt"
    meta = read_json(obs / "views.json")
    texels = np.load(obs / "texels.npz")
    n_tex, n_views = len(texels["texel"]), len(meta["views"])
    assert n_views == 4 and n_tex == meta["texels"] > 0.9 * 32 * 32
    assert np.load(obs / "radiance.npy").shape == (n_tex, n_views, 3)
    weight = np.load(obs / "weight.npy")
    assert weight.shape == (n_tex, n_views) and weight.dtype == np.float32
    assert np.load(obs / "wo_local.npy").shape == np.load(obs / "incoming.npy").shape == (n_tex, n_views, 3)
    # tiny 32 px views: the object spans ~12 px, so edge-free footprints are few
    assert meta["observed_pairs"] == int((weight > 0).sum()) > n_tex // 4
    assert (obs / "coverage.png").is_file()


def test_exported_and_reimported_capture_gives_the_same_observations(run):
    # tiny.yaml exports sphere/studio to the NeRF/Stanford-ORB layout and imports it back as sphere_copy.
    export = run / "results/exports/sphere/studio"
    assert (export / "transforms_train.json").is_file() and (export / "train_mask/0000.png").is_file()
    native = run / "results/observations/sphere/studio/gt"
    imported = run / "results/observations/sphere_copy/studio_copy/gt"
    for name in ("radiance", "weight", "wo_local", "incoming"):
        np.testing.assert_allclose(np.load(imported / f"{name}.npy"), np.load(native / f"{name}.npy"), rtol=1e-5, atol=1e-6)
    np.testing.assert_array_equal(np.load(imported / "texels.npz")["texel"], np.load(native / "texels.npz")["texel"])


def test_frequency_stage_outputs(run):
    sh = run / "results/sh/sphere/studio/gt"
    n_tex = len(np.load(run / "results/observations/sphere/studio/gt/texels.npz")["texel"])
    assert np.load(sh / "coeffs_outgoing.npy").shape == np.load(sh / "coeffs_incoming.npy").shape == (n_tex, 49, 3)
    assert np.load(sh / "spectra_outgoing.npy").shape == (n_tex, 7, 3)
    entropy = np.load(run / "results/entropy/sphere/studio/gt/entropy.npy")
    unobserved = np.load(run / "results/entropy/sphere/studio/gt/unobserved.npy")
    assert np.isfinite(entropy).all() and entropy.min() >= 0.0 and entropy.max() <= 1.0
    assert (entropy[unobserved] == 1.0).all()
    assert read_exr(run / "results/entropy/sphere/studio/gt/entropy.exr").shape == (32, 32)
    for name, channels in (("base_color", 3), ("roughness", 1), ("metallic", 1)):
        texture = read_exr(run / f"results/estimates/sphere/studio/gt/spectrum/{name}.exr")
        assert texture.shape[:2] == (32, 32) and (texture.ndim == 2) == (channels == 1)
        assert texture.min() >= 0.0 and texture.max() <= 1.0


def test_every_method_writes_loadable_textures_and_a_decreasing_loss(run):
    import pandas as pd

    for method in ("freq", "freq_noshadow", "freq_nomask", "rh2001"):
        estimate = run / f"results/estimates/sphere/studio/gt/{method}"
        for name in ("base_color", "roughness", "metallic"):
            texture = read_exr(estimate / f"{name}.exr")
            assert texture.shape[:2] == (32, 32) and 0.0 <= texture.min() and texture.max() <= 1.0
        loss = pd.read_csv(estimate / "loss.tsv", sep="\t")["loss"].to_numpy()
        assert len(loss) == 150 and loss[-1] < 0.8 * loss[0]


def test_parameter_mse_table_covers_every_method(run):
    import pandas as pd

    table = pd.read_csv(run / "results/tables/parameter_mse.tsv", sep="\t")
    assert set(table.columns) == {"object", "env", "poses", "method", "metric", "value"}
    assert set(table.method) == {"spectrum", "freq", "freq_noshadow", "freq_nomask", "rh2001"}
    assert set(table.object) == {"sphere"}  # the re-imported copy has no ground truth
    average = table[table.metric == "mse_average"]
    assert len(average) == 5 and average.value.between(0.0, 1.0).all()
