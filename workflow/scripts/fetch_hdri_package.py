"""Rule fetch_hdri_package: the npm package of the captured HDR maps, checked against npm's integrity hash."""

from pathlib import Path

from freqbrdf.scene import hdri
from freqbrdf.util.logs import run_script


def main(smk, log):
    target = Path(smk.output[0])
    fetched = hdri.fetch_package(target.parent)
    if fetched != target:
        raise ValueError(f"{target}: the package is named {fetched.name}")
    log.info("%s@%s: %s, %.1f MB, integrity checked (%s)", hdri.PACKAGE, hdri.VERSION, target,
             target.stat().st_size / 1e6, hdri.CREDIT)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
