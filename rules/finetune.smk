# Differentiable-rendering baseline (mitsuba) and fine-tuning of the freq
# estimate (freq+mitsuba) with Mitsuba 3. Both write the same estimate layout
# as optimise_svbrdf, which would otherwise also match these method names.
ruleorder: mitsuba_svbrdf > optimise_svbrdf


def mitsuba_start(wildcards):
    """freq+mitsuba starts from the freq estimate; the baseline from a constant 0.5 (no input)."""
    if wildcards.method == "freq+mitsuba":
        return {"init": f"results/estimates/{wildcards.object}/{wildcards.env}/{wildcards.poses}/freq"}
    return {}


def mitsuba_settings(wildcards):
    """Optimiser settings of one run: config `mitsuba`, with `mitsuba.finetune`
    overriding epochs and spp for freq+mitsuba; a seed per capture and method."""
    settings = {key: value for key, value in config["mitsuba"].items() if key != "finetune"}
    if wildcards.method == "freq+mitsuba":
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
        capture=lambda wildcards: capture_dir(wildcards, "train"),
        poses=pose_dir,
        mesh=mesh_file,
        envmap=envmap_file,
        code=library("mitsuba_svbrdf"),
    output:
        estimate=directory("results/estimates/{object}/{env}/{poses}/{method}"),
    wildcard_constraints:
        method=MITSUBA_METHODS,
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
