rule build_object:
    """Procedural mesh with a UV atlas and its seeded ground-truth SVBRDF."""
    input:
        code=library("make_object"),
    output:
        **object_files("{object}"),
        base_color_png="results/objects/{object}/base_color.png",
        roughness_png="results/objects/{object}/roughness.png",
        metallic_png="results/objects/{object}/metallic.png",
    params:
        detail=config["meshes"]["detail"],
        textures=config["textures"],
        seed=lambda wildcards: derived_seed(config["seed"], "object", wildcards.object),
    log:
        "results/logs/build_object/{object}.log",
    benchmark:
        "results/benchmarks/build_object/{object}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/make_object.py"
