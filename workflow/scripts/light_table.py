"""Rule light_table: the shadowed light of one environment map on a grid of normals
(freqbrdf.estimate.light_table), for every estimate under the map whose light is the map's own."""

import time

from freqbrdf.estimate.light_table import TableSize, shadowed_light_table, write_light_table
from freqbrdf.estimate.optimise.model import map_light
from freqbrdf.util.io import atomic_directory, read_exr
from freqbrdf.util.logs import run_script


def main(smk, log):
    p = smk.params
    size = TableSize(**p.size)
    start = time.perf_counter()
    light = map_light(read_exr(smk.input.envmap), p.lmax, p.point_sources)
    table = shadowed_light_table(light, size.rows, size.rank, smk.threads)
    log.info("%d x %d normals x rank %d at degree %d in %.1f s", size.rows, 2 * size.rows, size.rank, light.lmax,
             time.perf_counter() - start)
    with atomic_directory(smk.output[0]) as tmp:
        write_light_table(tmp, table)


run_script(main, snakemake)  # noqa: F821 (injected by Snakemake)
