"""Rule build_object: procedural mesh (PLY) and ground-truth SVBRDF textures (EXR + PNG).

A stress capture's object (config stress_captures) is its base shape with the base's
textures (same seed), where ``params.material`` may make roughness or metallic uniform.
"""

import numpy as np

from freqbrdf.artefacts import write_texture
from freqbrdf.util.logs import run_script
from freqbrdf.scene.meshes import make_mesh
from freqbrdf.scene.ply import write_ply
from freqbrdf.scene.textures import svbrdf_textures


def main(smk, log):
    mesh = make_mesh(smk.params.shape, detail=smk.params.detail)
    write_ply(smk.output.mesh, mesh)
    log.info("mesh: %d vertices, %d triangles", len(mesh.vertices), len(mesh.faces))

    settings = smk.params.textures
    textures = svbrdf_textures(
        settings["resolution"], seed=smk.params.seed, cells=settings["cells"],
        grain_amplitude=settings["grain"], grain_texels=settings["grain_texels"],
    )
    for name, value in smk.params.material.items():
        textures[name] = np.full_like(textures[name], value)
        log.info("%s: uniform %g (a stress capture's material)", name, value)
    for name, texture in textures.items():
        write_texture(smk.output[name], name, texture, preview=smk.output[f"{name}_png"])
        log.info("%s: %s, range [%.3f, %.3f]", name, texture.shape, texture.min(), texture.max())


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
