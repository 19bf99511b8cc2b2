rule fetch_asset_package:
    """The npm package @pmndrs/assets, whose captured HDR maps the hdri environments
    and whose scans the scanned objects use: fetched with npm pack (npm's cache makes a second fetch local) and checked
    against npm's integrity hash."""
    input:
        code=library("fetch_asset_package"),
    output:
        ASSET_PACKAGE,
    log:
        layout.log("fetch_asset_package"),
    conda:
        "../envs/npm.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(5),
    script:
        "../scripts/fetch_asset_package.py"


rule build_env:
    """Equirectangular HDR environment map of one named environment: procedural, or a
    captured map of the package, cleaned of its ringing (kind hdri)."""
    input:
        unpack(env_package),
        code=library("build_env"),
    output:
        exr=layout.ENVMAP,
        preview=layout.ENVMAP_PREVIEW,
        source=layout.ENVMAP_SOURCE,
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
