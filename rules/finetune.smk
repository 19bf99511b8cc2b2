# Differentiable-rendering baseline (mitsuba) and fine-tuning of another
# method's estimate (freq+mitsuba) with Mitsuba 3.


rule mitsuba_svbrdf:
    """SVBRDF textures by differentiable rendering: Mitsuba's prb integrator and
    Adam on the base colour, roughness and metallic textures of a principled
    BSDF, one training view per step (mitsuba: from 0.5; freq+mitsuba: from freq)."""
    input:
        unpack(mitsuba_start),
        unpack(mitsuba_evaluation),
        capture=lambda wildcards: capture_dir(wildcards, "train"),
        poses=pose_dir,
        mesh=mesh_file,
        envmap=envmap_file,
        code=library("mitsuba_svbrdf"),
    output:
        estimate=directory("results/estimates/{object}/{env}/{poses}/{method}"),
    log:
        "results/logs/mitsuba_svbrdf/{object}_{env}_{poses}_{method}.log",
    benchmark:
        "results/benchmarks/mitsuba_svbrdf/{object}_{env}_{poses}_{method}.tsv"
    wildcard_constraints:
        method=wildcard_pattern(methods_of("mitsuba_svbrdf")),
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(6, "inverse"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        resolution=config["textures"]["resolution"],
        settings=mitsuba_settings,
    script:
        "../workflow/scripts/mitsuba_svbrdf.py"
