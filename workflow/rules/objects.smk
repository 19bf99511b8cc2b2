rule build_object:
    """Mesh with a UV atlas (procedural, or a scan atlased by xatlas) and its seeded
    ground-truth SVBRDF; a stress capture's object is its base object, optionally with
    a uniform roughness or metallic."""
    input:
        unpack(object_package),
        code=library("build_object"),
    output:
        **object_files("{object}"),
        **{f"{texture}_png": fill(layout.OBJECT_PREVIEW, texture=texture) for texture in TEXTURES},
        source=layout.OBJECT_SOURCE,
    log:
        layout.log("build_object", "{object}"),
    benchmark:
        layout.benchmark("build_object", "{object}")
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        detail=config["meshes"]["detail"],
        atlas=ATLAS,
        textures=config["textures"],
        shape=lambda wildcards: object_shape(wildcards.object),
        seed=lambda wildcards: derived_seed(config["seed"], "object", object_shape(wildcards.object)),
        material=lambda wildcards: stress_material(wildcards.object),
    script:
        "../scripts/build_object.py"
