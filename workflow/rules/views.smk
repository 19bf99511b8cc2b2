# Parameter MSE and entropy with fewer training views (paper Fig. 8), on every synthetic
# capture (config evaluate.views_counts, views_subsets; none when the list is empty).
VIEWS_CAPTURES = BENCHMARK_CAPTURES if config["evaluate"]["views_counts"] else []


rule views_sweep:
    """freq's parameter MSE and the mean spectrum entropy of one capture restricted to seeded
    random subsets of its training views (several per count), each with the band limit of its count."""
    input:
        unpack(lambda w: light_table_input(w, "freq")),
        observations=layout.OBSERVATIONS,
        envmap=envmap_file,
        truth=lambda w: [object_files(w.object)[n] for n in TEXTURES],
        code=library("views_sweep"),
    output:
        table=fill(layout.VIEWS, ext="tsv"),
        figure=report(
            fill(layout.VIEWS, ext="png"),
            category="Uncertainty",
            caption="../report/views.rst",
            labels={"capture": "{object} / {env}", "figure": "views"},
        ),
    log:
        layout.log("views_sweep", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("views_sweep", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(1500, "texels"),
        runtime=minutes(12, "texels"),
    params:
        counts=config["evaluate"]["views_counts"],
        subsets=config["evaluate"]["views_subsets"],
        seed=lambda w: derived_seed(config["seed"], "views", w.object, w.env, w.poses),
        band_limit=config["observations"]["band_limit"],
        sh=config["sh"],
        spectrum=config["spectrum"],
        optimise=config["optimise"],
    script:
        "../scripts/views_sweep.py"
