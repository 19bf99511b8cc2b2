"""Rule import_textures: a real capture's ground-truth SVBRDF textures, checked."""

from pathlib import Path

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.capture.exchange import import_textures
from freqbrdf.util.logs import run_script


def main(smk, log):
    import_textures(Path(smk.input.source), {name: Path(smk.output[name]) for name in TEXTURES}, smk.params.resolution)
    log.info("ground truth from %s", smk.input.source)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
