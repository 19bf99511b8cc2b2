rule build_env:
    """Equirectangular HDR environment map of one named environment."""
    input:
        code=library("build_env"),
    output:
        exr=layout.ENVMAP,
        preview=layout.ENVMAP_PREVIEW,
    log:
        layout.log("build_env", "{env}"),
    benchmark:
        layout.benchmark("build_env", "{env}")
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
        "../scripts/build_env.py"


rule env_spectrum:
    """Spherical-harmonics power spectrum of one environment: how much high-frequency light it has."""
    input:
        exr=layout.ENVMAP,
        code=library("env_spectrum"),
    output:
        tsv=fill(layout.ENV_SPECTRUM, ext="tsv"),
        png=report(fill(layout.ENV_SPECTRUM, ext="png"), category="Environments", caption="../report/env_spectrum.rst"),
    log:
        layout.log("env_spectrum", "{env}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        lmax=config["envmaps"]["spectrum_lmax"],
    script:
        "../scripts/env_spectrum.py"


rule env_spectra:
    """All environments' spectra on one plot."""
    input:
        spectra=expand(fill(layout.ENV_SPECTRUM, ext="tsv"), env=ENVS),
        code=library("env_spectra"),
    output:
        report(layout.ENV_SPECTRA, category="Environments", caption="../report/env_spectra.rst"),
    log:
        layout.log("env_spectra"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        envs=ENVS,
    script:
        "../scripts/env_spectra.py"
