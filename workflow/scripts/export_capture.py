"""Rule export_capture: a rendered capture in the NeRF-Blender / Stanford-ORB layout, with the
source records (origin, licence) of its mesh and environment map as ``sources.json``."""

from pathlib import Path

from freqbrdf.capture.exchange import export_capture
from freqbrdf.util.io import atomic_directory, read_json, write_json
from freqbrdf.util.logs import run_script


def main(smk, log):
    with atomic_directory(smk.output[0]) as tmp:
        export_capture({"train": Path(smk.input.train), "test": Path(smk.input.test)},
                       Path(smk.input.mesh), Path(smk.input.envmap), tmp)
        write_json(tmp / "sources.json", [read_json(path) for path in smk.input.sources])
    log.info("exported to %s", smk.output[0])


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
