"""Rule fetch_asset_package: the npm package of the captured HDR maps and scanned meshes, checked against npm's integrity hash."""

from pathlib import Path

from freqbrdf.scene import assets
from freqbrdf.util.logs import run_script


def main(smk, log):
    target = Path(smk.output[0])
    fetched = assets.fetch_package(target.parent)
    if fetched != target:
        raise ValueError(f"{target}: the package is named {fetched.name}")
    log.info("%s@%s: %s, %.1f MB, integrity checked", assets.PACKAGE, assets.VERSION, target,
             target.stat().st_size / 1e6)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
