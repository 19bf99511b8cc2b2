rule fit_sh:
    """Spherical-harmonics fits of the outgoing radiance B and the incoming light L
    of every texel, and their power spectra (cached for every later stage)."""
    input:
        observations=layout.OBSERVATIONS,
        code=library("fit_sh"),
    output:
        directory(layout.SH_FIT),
    log:
        layout.log("fit_sh", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("fit_sh", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(800, "texels"),
        runtime=minutes(1, "texels"),
    params:
        sh=config["sh"],
    script:
        "../scripts/fit_sh.py"


rule spectrum_search:
    """Spectrum-only estimate (grid search over K_s and alpha) and the per-texel
    entropy of its likelihood: the method's uncertainty map."""
    input:
        sh=layout.SH_FIT,
        observations=layout.OBSERVATIONS,
        envmap=envmap_file,
        code=library("spectrum_search"),
    output:
        estimate=directory(fill(layout.ESTIMATE, method="spectrum")),
        entropy=directory(layout.ENTROPY),
    log:
        layout.log("spectrum_search", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("spectrum_search", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(700, "texels"),
        runtime=minutes(1, "texels"),
    params:
        spectrum=config["spectrum"],
    script:
        "../scripts/spectrum_search.py"
