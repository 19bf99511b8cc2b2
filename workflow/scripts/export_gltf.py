"""Rules export_gltf and export_truth_gltf: SVBRDF textures on the object's mesh as binary glTF (.glb)."""

from freqbrdf.artefacts import read_svbrdf
from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.export.gltf import GltfMaterial, write_glb
from freqbrdf.util.logs import run_script
from freqbrdf.scene.ply import read_ply


def main(smk, log):
    # An estimate is a directory of textures; the ground truth is the object's texture files.
    source = smk.input.estimate if hasattr(smk.input, "estimate") else {name: smk.input[name] for name in TEXTURES}
    textures = read_svbrdf(source)
    mesh = read_ply(smk.input.mesh)
    write_glb(smk.output[0], mesh, [GltfMaterial.from_textures(smk.params.name, textures)])
    log.info("%s: %d triangles, %dx%d textures", smk.output[0], len(mesh.faces), *textures.base_color.shape[:2])


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
