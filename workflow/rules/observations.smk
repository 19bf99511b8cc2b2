rule extract_observations:
    """Per-texel observations of one training capture: radiance, view and mirror
    directions in the texel's frame, and the band-limited incoming light."""
    input:
        capture=lambda wildcards: capture_dir(wildcards, "train"),
        poses=pose_dir,
        mesh=mesh_file,
        envmap=envmap_file,
        code=library("extract_observations"),
    output:
        directory(layout.OBSERVATIONS),
    log:
        layout.log("extract_observations", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("extract_observations", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(900, "texels"),
        runtime=minutes(1, "texels"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        resolution=config["textures"]["resolution"],
        settings=config["observations"],
    script:
        "../scripts/extract_observations.py"
