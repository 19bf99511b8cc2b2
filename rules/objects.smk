rule build_object:
    """Procedural mesh with a UV atlas and its seeded ground-truth SVBRDF; a stress
    capture's object is its base object, optionally with a uniform roughness or metallic."""
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
        shape=lambda wildcards: object_shape(wildcards.object),
        seed=lambda wildcards: derived_seed(config["seed"], "object", object_shape(wildcards.object)),
        material=lambda wildcards: stress_material(wildcards.object),
    script:
        "../workflow/scripts/make_object.py"
