"""Rule render_capture: HDR views, coverage masks and cameras of one (object, env, split)."""

import time

import numpy as np

from freqbrdf.scene.cameras import cameras_to_json, check_capture_files, mitsuba_to_world, rig_cameras
from freqbrdf.artefacts import read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.util.io import atomic_directory, read_exr, write_exr, write_json, write_png
from freqbrdf.util.logs import progress, run_script
from freqbrdf.util.mitsuba_setup import setup_mitsuba
from freqbrdf.util.previews import contact_sheet
from freqbrdf.scene.render import capture_bsdf, capture_scene, mask_scene, occluder_disk, render_views


def main(smk, log):
    mi = setup_mitsuba(smk.params.variant, smk.threads)
    p = smk.params
    size = p.render["resolution"]
    cameras = rig_cameras(p.views, size, p.render["fov_deg"], p.render["camera_distance"], azimuth_deg=p.azimuth_deg)
    to_world = np.stack([mitsuba_to_world(m) for m in cameras.world_to_camera])
    frame = dict(width=size, height=size, fov_x_deg=p.render["fov_deg"])

    with atomic_directory(smk.output[0], complete=check_capture_files) as tmp:
        _render_into(mi, smk, log, cameras, to_world, frame, tmp)


def _render_into(mi, smk, log, cameras, to_world, frame, tmp):
    p = smk.params
    textures = read_svbrdf({name: smk.input[name] for name in TEXTURES})
    settings = dict(p.scene)  # the capture's BSDF and occluder (config stress_captures; none in the benchmark)
    occluder = settings.pop("occluder", None)
    bsdf = capture_bsdf(mi, dict(textures), **settings)
    occluders = [] if occluder is None else [occluder_disk(mi, occluder["height"], occluder["radius"])]
    scene = capture_scene(
        mi, smk.input.mesh, bsdf, read_exr(smk.input.envmap),
        spp=p.render["spp"], max_depth=p.render["max_depth"], occluders=occluders, **frame,
    )
    if occluder is not None:
        lowest = min(float(shape.bbox().min.y) for shape in scene.shapes() if shape.is_mesh())
        if occluder["height"] >= lowest:
            raise ValueError(f"config key stress_captures.{smk.wildcards.object}.occluder.height: "
                             f"{occluder['height']} is not below the object (lowest point y = {lowest:.3f})")
    log.info("scene: %s BSDF%s%s", settings.get("model", "principled"),
             f", clear coat {settings['clearcoat']}" if settings.get("clearcoat") else "",
             f", occluder disk at y = {occluder['height']}, radius {occluder['radius']}" if occluder else "")
    start = time.perf_counter()
    previews = []
    for i, (name, image) in enumerate(zip(cameras.names, render_views(mi, scene, to_world, seed=p.seed))):
        write_exr(tmp / "images" / f"{name}.exr", image)  # raises, naming the view, on NaN/Inf
        if len(previews) < 8:
            previews.append(image)
        log.info("view %s rendered: %s", name, progress(i + 1, len(cameras), time.perf_counter() - start))

    masks = mask_scene(mi, smk.input.mesh, spp=p.render["mask_spp"], **frame)
    for name, coverage in zip(cameras.names, render_views(mi, masks, to_world, seed=p.seed)):
        write_png(tmp / "masks" / f"{name}.png", coverage[..., 0])
    log.info("masks rendered (%.1f s elapsed)", time.perf_counter() - start)

    write_json(tmp / "cameras.json", cameras_to_json(cameras))
    contact_sheet(tmp / "preview.png", previews)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
