"""Rule export_env: an environment map as Radiance .hdr, the HDR format viewers and engines read."""

from freqbrdf.util.io import read_exr
from freqbrdf.util.logs import run_script
from freqbrdf.export.rgbe import write_hdr


def main(smk, log):
    envmap = read_exr(smk.input.envmap)
    if envmap.ndim != 3 or envmap.shape[2] < 3:
        raise ValueError(f"{smk.input.envmap}: environment map is {envmap.shape}, expected (H, 2H, 3)")
    write_hdr(smk.output[0], envmap[..., :3])
    log.info("%s: %dx%d", smk.output[0], envmap.shape[1], envmap.shape[0])


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
