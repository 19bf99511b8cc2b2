# Entropy-guided merge of one object's estimates from all its captures (paper Table 6).


rule merge_svbrdf:
    """Per texel, the parameters of the capture whose spectrum entropy is lowest there
    (mitsuba_merged: of Mitsuba's estimates, as in the paper; freq_merged: of ours)."""
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
    script:
        "../scripts/merge_svbrdf.py"
