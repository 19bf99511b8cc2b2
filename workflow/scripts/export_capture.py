"""Rule export_capture: a rendered capture in the NeRF-Blender / Stanford-ORB layout."""

import shutil
from pathlib import Path

from freqbrdf.capture_io import export_capture
from freqbrdf.logs import run_script


def main(smk, log):
    out = Path(smk.output[0])
    tmp = out.with_name(f".{out.name}.partial")
    shutil.rmtree(tmp, ignore_errors=True)
    try:
        export_capture({"train": Path(smk.input.train), "test": Path(smk.input.test)},
                       Path(smk.input.mesh), Path(smk.input.envmap), tmp)
        shutil.rmtree(out, ignore_errors=True)
        tmp.rename(out)
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    log.info("exported to %s", out)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
