from freqbrdf.capture.exchange import source_checksum

# Every output of the real captures alone: the targets of rule real_captures (and of rule all).
REAL_CAPTURE_TARGETS = [
    path
    for o, capture in REAL_CAPTURES.items()
    for e in [capture["env"]]
    for path in [
        fill(layout.IMPORT_ORIENTATION, object=o),
        fill(layout.OBSERVATIONS, object=o, env=e, poses=POSES),
        *[fill(layout.ESTIMATE, object=o, env=e, poses=POSES, method=m) for m in METHODS],
        fill(layout.ENTROPY, object=o, env=e, poses=POSES),
        fill(layout.CAPTURE_FIGURE, object=o, env=e, poses=POSES, name="maps.png"),
        fill(layout.REAL_RELIGHT_SCORES, object=o, env=e, poses=POSES),
        *([fill(layout.REAL_SCORES, object=o, env=e, poses=POSES)] if "textures" in capture else []),
    ]
]


rule export_capture:
    """A rendered capture (both splits, mesh, environment) in the NeRF-Blender /
    Stanford-ORB layout, for other tools, or to test the import path."""
    input:
        train=fill(layout.CAPTURE, split="train"),
        test=fill(layout.CAPTURE, split="test"),
        mesh=layout.OBJECT_MESH,
        envmap=layout.ENVMAP,
        sources=[layout.OBJECT_SOURCE, layout.ENVMAP_SOURCE],
        code=library("export_capture"),
    output:
        directory(layout.EXPORT),
    log:
        layout.log("export_capture", "{object}_{env}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(1, "pixels"),
    script:
        "../scripts/export_capture.py"


rule import_capture:
    """A capture on disk in the NeRF-Blender / Stanford-ORB layout (config
    `real_captures`), every file read and checked, converted to the native layout
    the estimators read (Y-up world, OpenCV cameras, the pipeline's PLY)."""
    input:
        source=lambda wildcards: REAL_CAPTURES[wildcards.object]["dir"],
        code=library("import_capture"),
    output:
        train=directory(fill(layout.IMPORT_SPLIT, split="train")),
        test=directory(fill(layout.IMPORT_SPLIT, split="test")),
        mesh=layout.IMPORT_MESH,
        envmap=layout.IMPORT_ENVMAP_GIVEN,
    log:
        layout.log("import_capture", "{object}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(1, "pixels"),
    params:
        # Snakemake sees only the source directory's timestamp, which a file
        # rewritten inside it leaves alone; a changed checksum reruns the import
        # (the params rerun trigger). Evaluated when the job runs, so a source
        # written by this workflow (config/tiny.yaml) is hashed once it exists.
        checksum=lambda wildcards: source_checksum(REAL_CAPTURES[wildcards.object]["dir"]),
        up_axis=lambda wildcards: REAL_CAPTURES[wildcards.object]["up_axis"],
        camera=lambda wildcards: REAL_CAPTURES[wildcards.object]["camera"],
        atlas=ATLAS,
    script:
        "../scripts/import_capture.py"


rule env_orientation:
    """Scores the imported environment map over rotations about the up axis against
    the training views (freqbrdf.capture.orientation); warns, naming the best rotation, when
    the given one is clearly worse, and applies the best one with `align_env: true`."""
    input:
        capture=fill(layout.IMPORT_SPLIT, split="train"),
        mesh=layout.IMPORT_MESH,
        envmap=layout.IMPORT_ENVMAP_GIVEN,
        code=library("env_orientation"),
    output:
        envmap=layout.IMPORT_ENVMAP,
        scores=layout.IMPORT_ORIENTATION,
        rotation=layout.IMPORT_ROTATION,
    log:
        layout.log("env_orientation", "{object}"),
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        align=lambda wildcards: REAL_CAPTURES[wildcards.object]["align_env"],
        source=lambda wildcards: REAL_CAPTURES[wildcards.object]["dir"],
        settings=config["observations"],
        lmax=config["sh"]["lmax"],
        resolution=config["textures"]["resolution"],
        seed=lambda wildcards: derived_seed(config["seed"], "env_orientation", wildcards.object),
    script:
        "../scripts/env_orientation.py"


rule import_textures:
    """Ground-truth textures of a real capture (config `real_captures.{name}.textures`),
    checked against the estimates' atlas size."""
    input:
        source=lambda wildcards: REAL_CAPTURES[wildcards.object]["textures"],
        code=library("import_textures"),
    output:
        **{name: fill(layout.IMPORT_TRUTH, texture=name) for name in TEXTURES},
    log:
        layout.log("import_textures", "{object}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        checksum=lambda wildcards: source_checksum(REAL_CAPTURES[wildcards.object]["textures"]),
        resolution=config["textures"]["resolution"],
    script:
        "../scripts/import_textures.py"


rule score_real_capture:
    """Parameter MSE and entropy-error correlation of every method on a real capture
    with ground-truth textures, in the columns of results/tables/metrics.csv."""
    input:
        estimates=lambda w: [
            fill(layout.ESTIMATE, object=w.object, env=w.env, poses=w.poses, method=m) for m in METHODS
        ],
        truth=truth_files,
        observations=layout.OBSERVATIONS,
        entropy=layout.ENTROPY,
        code=library("score_real_capture"),
    output:
        layout.REAL_SCORES,
    log:
        layout.log("score_real_capture", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(1, "texels"),
    params:
        methods=METHODS,
        entropy_methods=[m for m in METHODS if METHOD_REGISTRY[m].entropy_scored],
    script:
        "../scripts/score_real_capture.py"


rule relight_real:
    """One method's textures rendered from a real capture's test views, each under
    its own environment (test_env/ of the capture, turned like envmap.exr), or
    under the capture's environment where the capture gives none."""
    input:
        estimate=layout.ESTIMATE,
        mesh=layout.IMPORT_MESH,
        test=fill(layout.IMPORT_SPLIT, split="test"),
        envmap=layout.IMPORT_ENVMAP,
        rotation=layout.IMPORT_ROTATION,
        code=library("relight_real"),
    output:
        directory(layout.RELIT_REAL),
    log:
        layout.log("relight_real", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("relight_real", "{object}_{env}_{poses}_{method}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(2, "samples"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        spp=config["render"]["spp"],
        max_depth=config["render"]["max_depth"],
        seed=lambda wildcards: derived_seed(config["seed"], "relight_real", wildcards.object),
    script:
        "../scripts/relight_real.py"


rule score_real_relight:
    """PSNR-H, PSNR-L, SSIM and MSE of every method's relit test views of a real
    capture against its test photographs, in the columns of metrics.csv
    (relight_env: test_views)."""
    input:
        relit=lambda w: [fill(layout.RELIT_REAL, object=w.object, env=w.env, poses=w.poses, method=m) for m in METHODS],
        test=fill(layout.IMPORT_SPLIT, split="test"),
        code=library("score_real_relight"),
    output:
        layout.REAL_RELIGHT_SCORES,
    log:
        layout.log("score_real_relight", "{object}_{env}_{poses}"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(1, "pixels"),
    params:
        methods=METHODS,
        metrics={key: config["evaluate"][key] for key in METRIC_KEYS},
    script:
        "../scripts/score_real_relight.py"


rule real_captures:
    """Only the real captures (config `real_captures`): import, orientation check,
    observations, every method's estimates, entropy, the maps figure, the relit
    test views' scores and, with ground truth, the parameter scores; nothing of
    the synthetic benchmark."""
    input:
        REAL_CAPTURE_TARGETS,
