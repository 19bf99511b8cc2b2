# Settings of the reference test renders (render_capture) that the relit images
# must share; the metric settings (config evaluate, but relight_envs) are
# deliberately not here, so editing them never reruns a render.
RELIGHT_KEYS = ["resolution", "spp", "max_depth", "fov_deg"]


rule relight:
    """One method's textures rendered from the held-out test views of an object
    under another environment, exactly as the reference test views were rendered."""
    input:
        estimate="results/estimates/{object}/{env}/{poses}/{method}",
        mesh="results/objects/{object}/mesh.ply",
        envmap="results/envs/{relight_env}.exr",
        test="results/captures/{object}/{relight_env}/test",  # cameras; the reference images
        code=library("relight"),
    output:
        directory("results/relight/{object}/{env}/{poses}/{method}/{relight_env}"),
    params:
        render={key: config["render"][key] for key in RELIGHT_KEYS},
        # The reference renders' seed: same sample sequence, so a perfect estimate
        # reproduces the reference image noise and all.
        seed=lambda wildcards: derived_seed(config["seed"], "render", wildcards.object, wildcards.relight_env, "test"),
    threads: 2
    resources:
        mem_mb=4000,
    log:
        "results/logs/relight/{object}_{env}_{poses}_{method}_{relight_env}.log",
    benchmark:
        "results/benchmarks/relight/{object}_{env}_{poses}_{method}_{relight_env}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/relight.py"
