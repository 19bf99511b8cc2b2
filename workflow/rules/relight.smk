# Settings of the reference test renders (render_capture) that the relit images
# must share; the metric settings (config evaluate, but relight_envs) are
# deliberately not here, so editing them never reruns a render.
RELIGHT_KEYS = ["resolution", "spp", "max_depth", "fov_deg"]


rule relight:
    """One method's textures rendered from the held-out test views of an object
    under every environment it is relit under (relight_envs), exactly as the
    reference test views were rendered. One job per estimate: Mitsuba starts once
    and its compiled kernels serve every environment."""
    input:
        estimate=layout.ESTIMATE,
        mesh=layout.OBJECT_MESH,
        envmaps=lambda w: [fill(layout.ENVMAP, env=r) for r in relight_envs(w.object, w.env, w.method)],
        # cameras and reference images, one test capture per environment
        tests=lambda w: [
            fill(layout.CAPTURE, object=w.object, env=r, split="test") for r in relight_envs(w.object, w.env, w.method)
        ],
        code=library("relight"),
    output:
        directory(layout.RELIT),
    log:
        layout.log("relight", "{object}_{env}_{poses}_{method}"),
    benchmark:
        layout.benchmark("relight", "{object}_{env}_{poses}_{method}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(500, "pixels"),
        runtime=minutes(2, "samples"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        render={key: config["render"][key] for key in RELIGHT_KEYS},
        relight_envs=lambda w: relight_envs(w.object, w.env, w.method),
        # The reference renders' seeds: same sample sequence, so a perfect estimate
        # reproduces the reference image noise and all.
        seeds=lambda w: [
            derived_seed(config["seed"], "render", w.object, r, "test")
            for r in relight_envs(w.object, w.env, w.method)
        ],
    script:
        "../scripts/relight.py"
