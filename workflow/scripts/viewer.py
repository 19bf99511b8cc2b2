"""Rule viewer: a capture's ground truth and estimates side by side in one self-contained HTML page."""

from pathlib import Path

import numpy as np

from freqbrdf.artefacts import read_entropy, read_posterior_std
from freqbrdf.estimate.optimise.posterior import expected_error_atlas
from freqbrdf.scene.cameras import cameras_from_json
from freqbrdf.export.gltf import read_glb
from freqbrdf.util.io import atomic_path, read_json
from freqbrdf.util.logs import run_script
from freqbrdf.export.viewer import (ENTROPY, Panel, asset_credits, capture_light_first, overlay_image,
                                   posterior_overlay, same_mesh, viewer_html)


def main(smk, log):
    panels = [Panel(**panel) for panel in smk.params.panels]
    paths = [*smk.input.truth, *smk.input.estimates]
    if len(paths) != len(panels):
        raise ValueError(f"{len(paths)} .glb inputs for {len(panels)} panels {[p.name for p in panels]}")
    scenes = [read_glb(path) for path in paths]
    for path, scene, panel in zip(paths, scenes, panels):
        if [m.name for m in scene.materials] != [panel.name]:
            raise ValueError(f"{path}: materials {[m.name for m in scene.materials]}, expected one named {panel.name!r}")
        if not same_mesh(scene.mesh, scenes[0].mesh):
            raise ValueError(f"{path}: its mesh differs from that of {paths[0]}; the panels share one mesh")
    cameras_path = Path(smk.input.cameras) / "cameras.json"
    cameras = cameras_from_json(read_json(cameras_path), cameras_path)
    # The page opens on the capture's first view; the panels are square, so the
    # vertical field of view of that view is kept.
    fov_deg = float(np.degrees(2.0 * np.arctan(0.5 * cameras.height / cameras.K[0, 1, 1])))
    envs = capture_light_first({name: Path(path).read_bytes()
                                for name, path in zip(smk.params.envs, smk.input.envs, strict=True)}, smk.wildcards.env)
    credits = asset_credits([read_json(path) for path in smk.input.sources])
    overlays = {ENTROPY: overlay_image(read_entropy(smk.input.entropy).atlas)}
    for method, estimate in zip(smk.params.posteriors, smk.input.posteriors, strict=True):
        overlays[method] = posterior_overlay(expected_error_atlas(read_posterior_std(estimate)))
    html = viewer_html(smk.params.title, scenes[0].mesh, [s.materials[0] for s in scenes], panels, envs,
                       overlays, cameras.centres[0], fov_deg, credits=credits)
    with atomic_path(smk.output[0]) as tmp:
        tmp.write_text(html, encoding="utf-8")
    log.info("%s: %d panels, %d environments, %.1f MB", smk.output[0], len(panels), len(envs), len(html) / 1e6)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
