"""Rule import_capture: a NeRF-Blender / Stanford-ORB capture, every file checked, in the native layout."""

from pathlib import Path

from freqbrdf.capture.exchange import import_capture
from freqbrdf.scene.scans import AtlasSettings
from freqbrdf.util.logs import run_script


def main(smk, log):
    # Snakemake removes every output of a failed job, so a half import never survives.
    counts = import_capture(Path(smk.input.source), {"train": Path(smk.output.train), "test": Path(smk.output.test)},
                            Path(smk.output.mesh), Path(smk.output.envmap),
                            up_axis=smk.params.up_axis, camera=smk.params.camera,
                            atlas=AtlasSettings(**smk.params.atlas), log=log)
    log.info("imported %s (%s-up, %s cameras): %s views", smk.input.source, smk.params.up_axis, smk.params.camera, counts)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
