# Differentiable-rendering baseline (mitsuba) and fine-tuning of another
# method's estimate (freq+mitsuba) with Mitsuba 3.


def mitsuba_start(wildcards):
    """The estimate a fine-tuning method starts from (its registry entry's start);
    the baseline starts from a constant 0.5 (no input)."""
    start = METHOD_REGISTRY[wildcards.method].start
    if start is not None:
        return {"init": f"results/estimates/{wildcards.object}/{wildcards.env}/{wildcards.poses}/{start}"}
    return {}


def mitsuba_evaluation(wildcards):
    """Ground truth and observed texels of a synthetic capture, against which the run logs
    its parameter MSE after every epoch (evaluation only: issue 14's equal-accuracy ratio)."""
    if wildcards.object in REAL_CAPTURES:
        return {}
    w = wildcards
    return {"truth": [object_files(w.object)[n] for n in TEXTURES],
            "observations": f"results/observations/{w.object}/{w.env}/{w.poses}"}


def mitsuba_settings(wildcards):
    """Optimiser settings of one run: config `mitsuba`, with `mitsuba.finetune`
    overriding epochs and spp when fine-tuning; a seed per capture and method."""
    settings = {key: value for key, value in config["mitsuba"].items() if key != "finetune"}
    if METHOD_REGISTRY[wildcards.method].start is not None:
        settings.update(config["mitsuba"]["finetune"])
    settings["seed"] = derived_seed(config["seed"], "mitsuba", wildcards.object, wildcards.env,
                                    wildcards.poses, wildcards.method)
    return settings


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
    wildcard_constraints:
        method=wildcard_pattern(methods_of("mitsuba_svbrdf")),
    params:
        resolution=config["textures"]["resolution"],
        settings=mitsuba_settings,
    threads: 2
    resources:
        mem_mb=4000,
    log:
        "results/logs/mitsuba_svbrdf/{object}_{env}_{poses}_{method}.log",
    benchmark:
        "results/benchmarks/mitsuba_svbrdf/{object}_{env}_{poses}_{method}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/mitsuba_svbrdf.py"
