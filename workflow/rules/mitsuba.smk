# Differentiable-rendering baseline (mitsuba) and fine-tuning of another
# method's estimate (freq+mitsuba) with Mitsuba 3.


rule mitsuba:
    """SVBRDF textures by differentiable rendering: Mitsuba's prb integrator and
    Adam on the base colour, roughness and metallic textures of a principled
    BSDF, mitsuba.views_per_step training views per step (mitsuba: from 0.5;
    freq+mitsuba: from freq)."""
    input:
        unpack(mitsuba_start),
        unpack(mitsuba_evaluation),
        capture=lambda wildcards: capture_dir(wildcards, "train"),
        poses=pose_dir,
        mesh=mesh_file,
        envmap=envmap_file,
        code=library("mitsuba"),
    output:
        estimate=directory(layout.ESTIMATE),
    log:
        layout.log("mitsuba", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("mitsuba", "{object}_{env}_{poses}_{method}")
    wildcard_constraints:
        method=wildcard_pattern(methods_of("mitsuba")),
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(12, "inverse"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        resolution=config["textures"]["resolution"],
        settings=mitsuba_settings,
    script:
        "../scripts/mitsuba.py"
