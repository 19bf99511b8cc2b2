# Settings that only change how results/tables/metrics.csv scores the outputs.
# Only the metrics rule receives them, so editing one reruns nothing upstream.
METRIC_KEYS = ["mask_min_coverage", "hdr_clip", "hdr_normalise"]


def method_benchmarks(o, e, p, m):
    """Benchmark files of the jobs a method needs once the observations exist, its own rule last."""
    bench = "results/benchmarks"
    method = METHOD_REGISTRY[m]
    if method.rule == "spectrum_search":
        return [f"{bench}/fit_sh/{o}_{e}_{p}.tsv", f"{bench}/spectrum_search/{o}_{e}_{p}.tsv"]
    if method.start is not None:
        before = method_benchmarks(o, e, p, method.start)
    elif method.rule == "optimise_svbrdf" and config["optimise"]["init"] == "spectrum":
        before = method_benchmarks(o, e, p, "spectrum")
    else:
        before = []
    return before + [f"{bench}/{method.rule}/{o}_{e}_{p}_{m}.tsv"]


rule metrics:
    """Every number of the benchmark in one tidy table: parameter MSE, relighting
    (PSNR-H, PSNR-L, SSIM, MSE), entropy-error correlation, time and memory."""
    input:
        estimates=[f"results/estimates/{o}/{e}/{POSES}/{m}" for o, e in SYNTHETIC_CAPTURES for m in METHODS],
        truth=[f for o in SYNTHETIC_OBJECTS for f in object_files(o).values()],
        observations=[f"results/observations/{o}/{e}/{POSES}" for o, e in SYNTHETIC_CAPTURES],
        entropy=[f"results/entropy/{o}/{e}/{POSES}" for o, e in SYNTHETIC_CAPTURES],
        relit=[f"results/relight/{o}/{e}/{p}/{m}/{r}" for o, e, p, m, r in RELIGHTS],
        references=sorted({f"results/captures/{o}/{r}/test" for o, _, _, _, r in RELIGHTS}),
        benchmarks=sorted({f for o, e in CAPTURES for m in METHODS for f in method_benchmarks(o, e, POSES, m)}),
        code=library("metrics"),
    output:
        "results/tables/metrics.csv",
    params:
        metrics={key: config["evaluate"][key] for key in METRIC_KEYS},
        synthetic=[(o, e, POSES, m) for o, e in SYNTHETIC_CAPTURES for m in METHODS],
        entropy_methods=[m for m in METHODS if METHOD_REGISTRY[m].entropy_scored],
        relights=RELIGHTS,
        timings=[(o, e, POSES, m, method_benchmarks(o, e, POSES, m)) for o, e in CAPTURES for m in METHODS],
    threads: 1
    log:
        "results/logs/metrics.log",
    benchmark:
        "results/benchmarks/metrics.tsv"
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/metrics.py"
