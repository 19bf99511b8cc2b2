# The spectrum-only estimate comes from spectrum_search; every other method from the optimiser.
ruleorder: spectrum_search > optimise_svbrdf


rule optimise_svbrdf:
    """Per-texel SVBRDF by Adam through the frequency-domain forward model
    (freq: shadowing and masking; freq_paper: the same on the light pre-filtered
    as in the paper; freq_noshadow, freq_nomask: ablations; rh2001: neither,
    Ramamoorthi-Hanrahan)."""
    input:
        observations="results/observations/{object}/{env}/{poses}",
        envmap=envmap_file,
        init="results/estimates/{object}/{env}/{poses}/spectrum",
        code=library("optimise_svbrdf"),
    output:
        estimate=directory("results/estimates/{object}/{env}/{poses}/{method}"),
    params:
        optimise=config["optimise"],
    threads: 2
    resources:
        mem_mb=4000,
    log:
        "results/logs/optimise_svbrdf/{object}_{env}_{poses}_{method}.log",
    benchmark:
        "results/benchmarks/optimise_svbrdf/{object}_{env}_{poses}_{method}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/optimise_svbrdf.py"
