"""Rule export_gltf: one method's estimate on the object's mesh as binary glTF (.glb)."""

from freqbrdf.artefacts import read_svbrdf
from freqbrdf.export.gltf import write_textures_glb
from freqbrdf.scene.ply import read_ply
from freqbrdf.util.logs import run_script


def main(smk, log):
    textures = read_svbrdf(smk.input.estimate)
    log.info(write_textures_glb(smk.output[0], read_ply(smk.input.mesh), textures, smk.params.name))


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
