rule light_table:
    """The shadowed light of one environment map tabulated over a grid of normals
    (optimise.light_table): fitted once per map, read by every estimate under it
    whose light is the map's own."""
    input:
        envmap=layout.ENVMAP,
        code=library("light_table"),
    output:
        directory(layout.LIGHT_TABLE),
    log:
        layout.log("light_table", "{env}"),
    benchmark:
        layout.benchmark("light_table", "{env}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(1000),
        runtime=minutes(2),
    params:
        lmax=config["optimise"]["lmax"],
        point_sources=config["optimise"]["point_sources"],
        size=config["optimise"]["light_table"],
    script:
        "../scripts/light_table.py"


use rule light_table as import_light_table with:
    input:
        envmap=layout.IMPORT_ENVMAP,
        code=library("light_table"),
    output:
        directory(layout.IMPORT_LIGHT_TABLE),
    log:
        layout.log("import_light_table", "{object}"),
    benchmark:
        layout.benchmark("import_light_table", "{object}")


rule optimise_svbrdf:
    """Per-texel SVBRDF through the frequency-domain forward model, by Adam or
    per-texel Levenberg-Marquardt (optimise.solver); which terms the model
    includes is the method's entry in freqbrdf.methods.METHODS (freq: shadowing
    and masking; freq_paper: the light pre-filtered as in the paper;
    freq_noshadow, freq_nomask, rh2001: the Table 4 ablation)."""
    input:
        unpack(optimise_start),
        unpack(light_table_input),
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
