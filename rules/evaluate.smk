rule parameter_errors:
    """Parameter MSE of every method against the ground-truth textures (synthetic captures)."""
    input:
        estimates=[f"results/estimates/{o}/{e}/{POSES}/{m}" for o, e in SYNTHETIC_CAPTURES for m in METHODS],
        truth=[f for o in SYNTHETIC_OBJECTS for f in object_files(o).values()],
        observations=[f"results/observations/{o}/{e}/{POSES}" for o, e in SYNTHETIC_CAPTURES],
        code=library("metrics", "spectral"),
    output:
        "results/tables/parameter_mse.tsv",
    params:
        captures=[(o, e, POSES, m) for o, e in SYNTHETIC_CAPTURES for m in METHODS],
    log:
        "results/logs/parameter_errors.log",
    conda:
        "../envs/freqbrdf.yaml"
    script:
        "../workflow/scripts/parameter_errors.py"
