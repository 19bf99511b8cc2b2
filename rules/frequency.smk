rule fit_sh:
    """Spherical-harmonics fits of the outgoing radiance B and the incoming light L
    of every texel, and their power spectra (cached for every later stage)."""
    input:
        observations="results/observations/{object}/{env}/{poses}",
        code=library("fit_sh"),
    output:
        directory("results/sh/{object}/{env}/{poses}"),
    log:
        "results/logs/fit_sh/{object}_{env}_{poses}.log",
    benchmark:
        "results/benchmarks/fit_sh/{object}_{env}_{poses}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(800, "texels"),
        runtime=minutes(1, "texels"),
    params:
        sh=config["sh"],
    script:
        "../workflow/scripts/fit_sh.py"


rule spectrum_search:
    """Spectrum-only estimate (grid search over K_s and alpha) and the per-texel
    entropy of its likelihood: the method's uncertainty map."""
    input:
        sh="results/sh/{object}/{env}/{poses}",
        observations="results/observations/{object}/{env}/{poses}",
        envmap=envmap_file,
        code=library("spectrum_search"),
    output:
        estimate=directory("results/estimates/{object}/{env}/{poses}/spectrum"),
        entropy=directory("results/entropy/{object}/{env}/{poses}"),
    log:
        "results/logs/spectrum_search/{object}_{env}_{poses}.log",
    benchmark:
        "results/benchmarks/spectrum_search/{object}_{env}_{poses}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(700, "texels"),
        runtime=minutes(1, "texels"),
    params:
        spectrum=config["spectrum"],
    script:
        "../workflow/scripts/spectrum_search.py"
