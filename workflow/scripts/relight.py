"""Rule relight: one method's textures rendered from the held-out test views under every relighting environment."""

import time
from pathlib import Path

from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.artefacts import read_svbrdf
from freqbrdf.util.io import atomic_directory, read_exr, read_json, write_exr
from freqbrdf.util.logs import progress, run_script
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.util.previews import contact_sheet
from freqbrdf.scene.render import relit_views


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    render = smk.params.render
    textures = read_svbrdf(smk.input.estimate)
    envs = smk.params.relight_envs
    start = time.perf_counter()
    with atomic_directory(smk.output[0]) as tmp:
        for i, (env, envmap, test, seed) in enumerate(zip(envs, smk.input.envmaps, smk.input.tests, smk.params.seeds)):
            test = Path(test)
            cameras = cameras_from_json(read_json(test / "cameras.json"), test / "cameras.json")
            if (cameras.width, cameras.height) != (render["resolution"], render["resolution"]):
                raise ValueError(f"{test}/cameras.json: views are {cameras.width}x{cameras.height}, "
                                 f"render.resolution is {render['resolution']}")
            # Exactly the reference renders' scene (render_capture): same mesh, environment,
            # integrator, film, sample count and seed, so that a perfect estimate
            # reproduces the reference image and the score carries no Monte Carlo noise floor.
            relit = relit_views(mi, smk.input.mesh, textures, read_exr(envmap), cameras,
                                fov_x_deg=render["fov_deg"], spp=render["spp"], max_depth=render["max_depth"],
                                seed=seed)
            previews = []
            for name, image in zip(cameras.names, relit):
                write_exr(tmp / env / "images" / f"{name}.exr", image)
                if len(previews) < 8:  # the reference capture's preview.png shows the same first 8 views
                    previews.append(image)
            contact_sheet(tmp / env / "preview.png", previews)
            log.info("relit under %s, %d views: environment %s", env, len(cameras),
                     progress(i + 1, len(envs), time.perf_counter() - start))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
