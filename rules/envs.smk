rule build_env:
    """Equirectangular HDR environment map of one named environment."""
    input:
        code=library("make_env"),
    output:
        exr="results/envs/{env}.exr",
        preview="results/envs/{env}.png",
    log:
        "results/logs/build_env/{env}.log",
    benchmark:
        "results/benchmarks/build_env/{env}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        settings=lambda wildcards: config["envs"][wildcards.env],
        height=config["envmaps"]["height"],
        mean_radiance=config["envmaps"]["mean_radiance"],
    script:
        "../workflow/scripts/make_env.py"


rule env_spectrum:
    """Spherical-harmonics power spectrum of one environment: how much high-frequency light it has."""
    input:
        exr="results/envs/{env}.exr",
        code=library("env_spectrum"),
    output:
        tsv="results/envs/{env}_spectrum.tsv",
        png=report("results/envs/{env}_spectrum.png", category="Environments", caption="../report/env_spectrum.rst"),
    log:
        "results/logs/env_spectrum/{env}.log",
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        lmax=config["envmaps"]["spectrum_lmax"],
    script:
        "../workflow/scripts/env_spectrum.py"


rule env_spectra:
    """All environments' spectra on one plot."""
    input:
        spectra=expand("results/envs/{env}_spectrum.tsv", env=ENVS),
        code=library("env_spectra"),
    output:
        report("results/envs/spectra.png", category="Environments", caption="../report/env_spectra.rst"),
    log:
        "results/logs/env_spectra.log",
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        envs=ENVS,
    script:
        "../workflow/scripts/env_spectra.py"
