rule export_capture:
    """A rendered capture (both splits, mesh, environment) in the NeRF-Blender /
    Stanford-ORB layout, for other tools, or to test the import path."""
    input:
        train="results/captures/{object}/{env}/train",
        test="results/captures/{object}/{env}/test",
        mesh="results/objects/{object}/mesh.ply",
        envmap="results/envs/{env}.exr",
        code=library("export_capture"),
    output:
        directory("results/exports/{object}/{env}"),
    log:
        "results/logs/export_capture/{object}_{env}.log",
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/export_capture.py"


rule import_capture:
    """A capture on disk in the NeRF-Blender / Stanford-ORB layout (config
    `real_captures`), converted to the native layout the estimators read."""
    input:
        source=lambda wildcards: REAL_CAPTURES[wildcards.object]["dir"],
        code=library("import_capture"),
    output:
        train=directory("results/imports/{object}/train"),
        test=directory("results/imports/{object}/test"),
        mesh="results/imports/{object}/mesh.ply",
        envmap="results/imports/{object}/envmap.exr",
    log:
        "results/logs/import_capture/{object}.log",
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/import_capture.py"
