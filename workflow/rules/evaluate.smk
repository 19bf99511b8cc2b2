# What the metrics rule scores; its input lists follow these orders.
METRIC_ESTIMATES = [(o, e, p, m) for o, e, p in SCORED for m in METHODS]
METRIC_REFERENCES = sorted({(o, r) for o, _, _, _, r in RELIGHTS})
METRIC_TIMINGS = METRIC_ESTIMATES + [(o, c["env"], POSES, m) for o, c in REAL_CAPTURES.items() for m in METHODS]


rule metrics:
    """Every number of the benchmark in one tidy table: parameter MSE, relighting
    (PSNR-H, PSNR-L, SSIM, MSE), entropy-error correlation, time and memory.
    Each input list is in the order of the params entry of the same name."""
    input:
        estimates=[fill(layout.ESTIMATE, object=o, env=e, poses=p, method=m) for o, e, p, m in METRIC_ESTIMATES],
        truth=[object_files(o)[name] for o in TRUTH_OBJECTS for name in TEXTURES],
        observations=[fill(layout.OBSERVATIONS, object=o, env=e, poses=p) for o, e, p in SCORED],
        entropy=[fill(layout.ENTROPY, object=o, env=e, poses=p) for o, e, p in SCORED],
        relit=[relit_dir(o, e, p, m) for o, e, p, m, _ in RELIGHTS],  # each holds {relight_env}/
        references=[fill(layout.CAPTURE, object=o, env=r, split="test") for o, r in METRIC_REFERENCES],
        benchmarks=[f for o, e, p, m in METRIC_TIMINGS for f in method_benchmarks(o, e, p, m)],
        extraction=[layout.benchmark("extract_observations", f"{o}_{e}_{p}") for o, e, p in SCORED],
        views=[fill(layout.VIEWS, object=o, env=e, poses=POSES, ext="tsv") for o, e in VIEWS_CAPTURES],
        agreement=[
            fill(layout.AGREEMENT, object=o, env=e, poses=POSES, name="agreement.json") for o, e in AGREEMENT_CAPTURES
        ],
        code=library("metrics"),
    output:
        metrics=report(
            layout.METRICS,
            category="Tables",
            caption="../report/metrics.rst",
            labels={"table": "metrics.csv (every number)"},
        ),
        sparsification=layout.SPARSIFICATION,
        reliability=layout.RELIABILITY,
    log:
        layout.log("metrics"),
    benchmark:
        layout.benchmark("metrics")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2  # the relit image sets are scored on a thread each
    resources:
        mem_mb=memory(500, "texels"),
        runtime=minutes(2, "texels"),
    params:
        metrics={key: config["evaluate"][key] for key in METRIC_KEYS},
        synthetic=METRIC_ESTIMATES,
        objects=TRUTH_OBJECTS,
        captures=SCORED,
        entropy_methods=[m for m in METHODS if METHOD_REGISTRY[m].entropy_scored],
        relights=RELIGHTS,
        references=METRIC_REFERENCES,
        timings=[(o, e, p, m, len(method_benchmarks(o, e, p, m))) for o, e, p, m in METRIC_TIMINGS],
        methods=METHODS,
        # a decaying learning rate makes the baseline's last epoch small by construction
        lr_decay=config["mitsuba"]["lr_decay"],
        views=[(o, e, POSES) for o, e in VIEWS_CAPTURES],
        agreement=[(o, e, POSES) for o, e in AGREEMENT_CAPTURES],
    script:
        "../scripts/metrics.py"
