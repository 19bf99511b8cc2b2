# Uncertainty-guided merge of one object's estimates from all its captures (paper Table 6).


rule merge_svbrdf:
    """Per texel, the parameters of the capture least uncertain there (mitsuba_merged: Mitsuba's
    estimates by the spectrum entropy, as in the paper; freq_merged: ours by their posterior)."""
    input:
        unpack(merge_inputs),
        code=library("merge_svbrdf"),
    output:
        estimate=directory(layout.ESTIMATE),
    log:
        layout.log("merge_svbrdf", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("merge_svbrdf", "{object}_{env}_{poses}_{method}")
    wildcard_constraints:
        method=wildcard_pattern(methods_of("merge_svbrdf")),
    conda:
        "../envs/freqbrdf.yaml"
    threads: 1
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        envs=merge_envs,
        merged_by=lambda w: METHOD_REGISTRY[w.method].merged_by,
    script:
        "../scripts/merge_svbrdf.py"
