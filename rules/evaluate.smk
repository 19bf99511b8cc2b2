# Settings that only change how results/tables/metrics.csv scores the outputs.
# Only the metrics rule receives them, so editing one reruns nothing upstream.
METRIC_KEYS = ["mask_min_coverage", "hdr_clip", "hdr_normalise"]
# Methods whose per-texel error is correlated with the entropy map.
ENTROPY_METHODS = ["freq", "mitsuba"]


def method_benchmarks(o, e, p, m):
    """Benchmark files of the jobs a method needs once the observations exist, its own rule last."""
    bench = "results/benchmarks"
    spectrum = [f"{bench}/fit_sh/{o}_{e}_{p}.tsv", f"{bench}/spectrum_search/{o}_{e}_{p}.tsv"]
    if m == "spectrum":
        return spectrum
    if m == "mitsuba":
        return [f"{bench}/mitsuba_svbrdf/{o}_{e}_{p}_{m}.tsv"]
    if m == "freq+mitsuba":  # fine-tunes the freq estimate
        return method_benchmarks(o, e, p, "freq") + [f"{bench}/mitsuba_svbrdf/{o}_{e}_{p}_{m}.tsv"]
    own = [f"{bench}/optimise_svbrdf/{o}_{e}_{p}_{m}.tsv"]
    return (spectrum if config["optimise"]["init"] == "spectrum" else []) + own


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
        entropy_methods=[m for m in ENTROPY_METHODS if m in METHODS],
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
