RENDER_KEYS = ["resolution", "spp", "max_depth", "fov_deg", "camera_distance", "mask_spp"]


rule render_capture:
    """HDR views of one object under one environment on a Fibonacci upper
    hemisphere, with coverage masks and OpenCV cameras. Split `train` feeds the
    estimators; split `test` (a rotated rig) is held out for relighting."""
    input:
        **object_files("{object}"),
        envmap=layout.ENVMAP,
        code=library("render_capture"),
    output:
        directory(layout.CAPTURE),
    log:
        layout.log("render_capture", "{object}_{env}_{split}"),
    benchmark:
        layout.benchmark("render_capture", "{object}_{env}_{split}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(400, "pixels"),
        runtime=minutes(2, "samples"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        # Only the settings that change the images, so editing e.g. test_views
        # does not rerun the training renders.
        render={key: config["render"][key] for key in RENDER_KEYS},
        views=lambda wildcards: config["render"][f"{wildcards.split}_views"],
        scene=scene_settings,
        azimuth_deg=lambda wildcards: 0.0 if wildcards.split == "train" else config["render"]["test_azimuth_deg"],
        seed=lambda wildcards: derived_seed(config["seed"], "render", wildcards.object, wildcards.env, wildcards.split),
    script:
        "../scripts/render_capture.py"
