rule colmap_poses:
    """Camera poses of a training capture by pycolmap SfM (SIFT, exhaustive matching,
    incremental mapping on tone-mapped views), similarity-aligned to the capture's
    reference cameras, with a per-view pose-error table. Fails, naming the option
    to change, if too few views register, or if the poses are off and an estimate
    uses them (poses.source or poses.compare); scored only, they are kept."""
    input:
        capture=lambda wildcards: capture_dir(wildcards, "train"),
        code=library("colmap_poses"),
    output:
        directory(layout.COLMAP_POSES),
    log:
        layout.log("colmap_poses", "{object}_{env}"),
    benchmark:
        layout.benchmark("colmap_poses", "{object}_{env}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(1, "pixels"),
    params:
        colmap=config["poses"]["colmap"],
        gates={
            key: config["poses"][key]
            for key in ("min_registered_fraction", "max_median_rotation_deg", "max_median_centre_error")
        },
        seed=lambda wildcards: derived_seed(config["seed"], "sfm", wildcards.object, wildcards.env),
        poses_used="colmap" in [POSES, *POSE_COMPARE],
    script:
        "../scripts/colmap_poses.py"


rule pose_errors:
    """Registered views and median pose errors of SfM on every synthetic capture, one row each."""
    input:
        poses=[fill(layout.COLMAP_POSES, object=o, env=e) for o, e in BENCHMARK_CAPTURES],
        code=library("pose_errors"),
    output:
        layout.POSE_ERRORS,
    log:
        layout.log("pose_errors"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        captures=BENCHMARK_CAPTURES,
    script:
        "../scripts/pose_errors.py"
