rule build_object:
    """Procedural mesh with a UV atlas and its seeded ground-truth SVBRDF."""
    input:
        code=library("make_object"),
    output:
        **object_files("{object}"),
        **{f"{texture}_png": f"results/objects/{{object}}/{texture}.png" for texture in TEXTURES},
    log:
        "results/logs/build_object/{object}.log",
    benchmark:
        "results/benchmarks/build_object/{object}.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        detail=config["meshes"]["detail"],
        textures=config["textures"],
        seed=lambda wildcards: derived_seed(config["seed"], "object", wildcards.object),
    script:
        "../workflow/scripts/make_object.py"
