rule optimise_svbrdf:
    """Per-texel SVBRDF through the frequency-domain forward model, by Adam or
    per-texel Levenberg-Marquardt (optimise.solver); which terms the model
    includes is the method's entry in freqbrdf.methods.METHODS (freq: shadowing
    and masking; freq_paper: the light pre-filtered as in the paper;
    freq_noshadow, freq_nomask, rh2001: the Table 4 ablation)."""
    input:
        unpack(optimise_start),
        observations=layout.OBSERVATIONS,
        envmap=envmap_file,
        code=library("optimise_svbrdf"),
    output:
        estimate=directory(layout.ESTIMATE),
    log:
        layout.log("optimise_svbrdf", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("optimise_svbrdf", "{object}_{env}_{poses}_{method}")
    wildcard_constraints:
        method=wildcard_pattern(methods_of("optimise_svbrdf")),
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(1300, "texels"),
        runtime=minutes(6, "texels"),
    params:
        optimise=config["optimise"],
    script:
        "../scripts/optimise_svbrdf.py"
