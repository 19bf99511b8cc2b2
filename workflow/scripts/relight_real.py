"""Rule relight_real: one method's textures rendered from a real capture's test views, each under its own map."""

from pathlib import Path

from freqbrdf.artefacts import read_svbrdf
from freqbrdf.scene.cameras import Cameras, cameras_from_json
from freqbrdf.capture.exchange import pinhole_fov_deg
from freqbrdf.scene.envmaps import turn_envmap
from freqbrdf.util.io import atomic_directory, read_exr, read_json, write_exr
from freqbrdf.util.logs import run_script
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.util.previews import contact_sheet
from freqbrdf.scene.render import relit_views


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    test = Path(smk.input.test)
    cameras = cameras_from_json(read_json(test / "cameras.json"), test / "cameras.json")
    fov = pinhole_fov_deg(cameras, test / "cameras.json")
    textures = read_svbrdf(smk.input.estimate)
    degrees = float(read_json(smk.input.rotation)["degrees"])
    own = (test / "envmaps").is_dir()
    log.info("%d test views, each under %s", len(cameras), "its own map" if own else "the capture's map")
    previews = []
    with atomic_directory(smk.output[0]) as tmp:
        for k, name in enumerate(cameras.names):
            envmap = turn_envmap(read_exr(test / "envmaps" / f"{name}.exr"), degrees) if own else read_exr(smk.input.envmap)
            view = Cameras(K=cameras.K[k : k + 1], world_to_camera=cameras.world_to_camera[k : k + 1],
                           width=cameras.width, height=cameras.height, names=(name,))
            image = next(iter(relit_views(mi, smk.input.mesh, textures, envmap, view, fov_x_deg=fov,
                                          spp=smk.params.spp, max_depth=smk.params.max_depth,
                                          seed=smk.params.seed + k)))
            write_exr(tmp / "images" / f"{name}.exr", image)
            if len(previews) < 8:
                previews.append(image)
        contact_sheet(tmp / "preview.png", previews)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
