# Captures that break the model's assumptions (config stress_captures) and the benchmark
# estimated from other pose sources (config poses.compare), scored apart from the paper's
# tables: one page of tables and one figure (config/stress.yaml runs them).
from freqbrdf.studies.stress import ambiguity_pairs, stress_description, stress_reference

OCCLUDED = [(o, e) for o, e in STRESS_CAPTURES if "occluder" in STRESS[o]]
# The ambiguity pairs as ((object, env), (object, env)) captures.
PAIRS = [((a, STRESS[a]["env"]), (b, STRESS[b]["env"])) for a, b in ambiguity_pairs(STRESS)]


# The stress page and figure when the config has stress captures or compared pose sources.
STRESS_TARGETS = (
    [
        fill(layout.TABLE, name="stress.md"),
        fill(layout.TABLE, name="stress.html"),
        fill(layout.FIGURE, name="stress.png"),
    ]
    if STRESS or POSE_COMPARE
    else []
)


rule stress_tables:
    """The pose-effect table (each method's MSE and relighting from every pose source),
    each stress capture beside the capture it differs from by one assumption, error and
    entropy inside and outside an unseen occluder's shadow, and the ambiguity pairs."""
    input:
        metrics=layout.METRICS,
        observations=[fill(layout.OBSERVATIONS, object=o, env=e, poses=POSES) for o, e in STRESS_CAPTURES],
        entropy=[fill(layout.ENTROPY, object=o, env=e, poses=POSES) for o, e in STRESS_CAPTURES],
        truth=[object_files(o)[name] for o, _ in STRESS_CAPTURES for name in TEXTURES],
        estimates=[
            fill(layout.ESTIMATE, object=o, env=e, poses=POSES, method=m) for o, e in STRESS_CAPTURES for m in METHODS
        ],
        envmaps=[fill(layout.ENVMAP, env=e) for _, e in OCCLUDED],
        pairs=[fill(layout.CAPTURE, object=o, env=e, split="train") for pair in PAIRS for o, e in pair],
        code=library("stress_tables"),
    output:
        md=fill(layout.TABLE, name="stress.md"),
        html=report(
            fill(layout.TABLE, name="stress.html"),
            category="Tables",
            caption="../report/stress.rst",
            labels={"table": "stress captures and pose effect"},
        ),
        figure=report(
            fill(layout.FIGURE, name="stress.png"),
            category="Stress captures",
            caption="../report/stress_figure.rst",
            labels={"figure": "entropy and error of the stress captures"},
        ),
        regions=fill(layout.TABLE, name="stress_regions.tsv"),
    log:
        layout.log("stress_tables"),
    conda:
        "../envs/freqbrdf.yaml"
    resources:
        mem_mb=memory(800, "texels"),
        runtime=minutes(1, "texels"),
    params:
        poses=POSES,
        compare=POSE_COMPARE,
        benchmark=BENCHMARK_CAPTURES,
        methods=METHODS,
        captures=STRESS_CAPTURES,
        descriptions={o: stress_description(STRESS[o]) for o, _ in STRESS_CAPTURES},
        references={o: stress_reference(o, STRESS, BENCHMARK_CAPTURES) for o, _ in STRESS_CAPTURES},
        occluded=[(o, e, STRESS[o]["occluder"]) for o, e in OCCLUDED],
        pairs=PAIRS,
        # a texel is in the occluder's shadow when the disk blocks at least this share of its light
        shadow_fraction=0.1,
    script:
        "../scripts/stress_tables.py"
