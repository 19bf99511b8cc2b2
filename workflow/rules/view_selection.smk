# Entropy-guided view selection (beyond the paper; docs/view_selection.md): the ranking
# of candidate poses for the first synthetic capture, and the comparison with random and
# evenly spread views on every synthetic capture (config view_selection.sweep_counts;
# none when the list is empty).
VIEW_SELECTION_CAPTURES = BENCHMARK_CAPTURES[:1]
VIEW_SELECTION_SWEEP_CAPTURES = BENCHMARK_CAPTURES if config["view_selection"]["sweep_counts"] else []
VIEW_SELECTION_SWEEP_KEYS = ["texels", "posterior_min_views", "sweep_counts", "pilot_views"]


# The ranked candidates of the first synthetic capture and, with view_selection.sweep_counts,
# the comparison of selection strategies.
VIEW_SELECTION_TARGETS = [
    fill(layout.VIEW_SELECTION, object=o, env=e, poses=POSES, name="ranked.tsv") for o, e in VIEW_SELECTION_CAPTURES
] + (
    [fill(layout.TABLE, name="view_selection.tsv"), fill(layout.FIGURE, name="view_selection.png")]
    if VIEW_SELECTION_SWEEP_CAPTURES
    else []
)


rule view_selection:
    """A capture's candidate poses ranked by the expected decrease of its mean spectrum entropy
    if each were added, from their geometry, the light and the capture's estimate (no images)."""
    input:
        unpack(candidate_poses),
        observations=layout.OBSERVATIONS,
        mesh=mesh_file,
        envmap=envmap_file,
        code=library("view_selection"),
    output:
        ranked=fill(layout.VIEW_SELECTION, name="ranked.tsv"),
        candidates=fill(layout.VIEW_SELECTION, name="candidates.json"),
    log:
        layout.log("view_selection", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("view_selection", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(800, "texels"),
        runtime=minutes(2, "texels"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        settings=config["view_selection"],
        render=config["render"],
        band_limit=config["observations"]["band_limit"],
        ray_offset=config["observations"]["ray_offset"],
        sh=config["sh"],
        spectrum=config["spectrum"],
        seed=lambda w: derived_seed(config["seed"], "view_selection", w.object, w.env, w.poses),
    script:
        "../scripts/view_selection.py"


rule view_selection_sweep:
    """freq's parameter MSE with k training views chosen by expected entropy, at random
    (several seeds) and evenly spread, for each k of view_selection.sweep_counts."""
    input:
        unpack(lambda w: light_table_input(w, "freq")),
        observations=layout.OBSERVATIONS,
        poses=pose_dir,
        envmap=envmap_file,
        truth=lambda w: [object_files(w.object)[n] for n in TEXTURES],
        code=library("view_selection_sweep"),
    output:
        table=fill(layout.VIEW_SELECTION, name="sweep.tsv"),
    log:
        layout.log("view_selection_sweep", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("view_selection_sweep", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(1500, "texels"),
        runtime=minutes(30, "texels"),
    params:
        settings={key: config["view_selection"][key] for key in VIEW_SELECTION_SWEEP_KEYS},
        seeds=lambda w: [
            derived_seed(config["seed"], "view_selection", w.object, w.env, w.poses, str(i))
            for i in range(config["view_selection"]["sweep_seeds"])
        ],
        texel_seed=lambda w: derived_seed(config["seed"], "view_selection", w.object, w.env, w.poses),
        band_limit=config["observations"]["band_limit"],
        sh=config["sh"],
        spectrum=config["spectrum"],
        optimise=config["optimise"],
    script:
        "../scripts/view_selection_sweep.py"


rule view_selection_table:
    """The sweeps of every synthetic capture in one table, and freq's MSE against k per strategy."""
    input:
        sweeps=[
            fill(layout.VIEW_SELECTION, object=o, env=e, poses=POSES, name="sweep.tsv")
            for o, e in VIEW_SELECTION_SWEEP_CAPTURES
        ],
        code=library("view_selection_table"),
    output:
        table=fill(layout.TABLE, name="view_selection.tsv"),
        figure=report(
            fill(layout.FIGURE, name="view_selection.png"),
            category="Uncertainty",
            caption="../report/view_selection.rst",
            labels={"figure": "entropy-guided views"},
        ),
    log:
        layout.log("view_selection_table"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(500),
        runtime=minutes(1),
    params:
        captures=VIEW_SELECTION_SWEEP_CAPTURES,
    script:
        "../scripts/view_selection_table.py"
