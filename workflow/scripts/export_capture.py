"""Rule export_capture: a rendered capture in the NeRF-Blender / Stanford-ORB layout."""

from pathlib import Path

from freqbrdf.capture.exchange import export_capture
from freqbrdf.util.io import atomic_directory
from freqbrdf.util.logs import run_script


def main(smk, log):
    with atomic_directory(smk.output[0]) as tmp:
        export_capture({"train": Path(smk.input.train), "test": Path(smk.input.test)},
                       Path(smk.input.mesh), Path(smk.input.envmap), tmp)
    log.info("exported to %s", smk.output[0])


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
