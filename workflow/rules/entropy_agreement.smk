# Entropy agreement (paper Table 3) on the first synthetic captures
# (config entropy_agreement.captures; none when 0).
AGREEMENT_CAPTURES = BENCHMARK_CAPTURES[: config["entropy_agreement"]["captures"]]


rule entropy_agreement:
    """On a seeded sample of a capture's observed texels, the entropy of a grid of uniform
    materials path traced by Mitsuba, of the same grid through our forward model (angular),
    and of the power spectra, with their Pearson correlations and times."""
    input:
        observations=layout.OBSERVATIONS,
        sh=layout.SH_FIT,
        envmap=envmap_file,
        mesh=mesh_file,
        code=library("entropy_agreement"),
    output:
        summary=fill(layout.AGREEMENT, name="agreement.json"),
        arrays=fill(layout.AGREEMENT, name="entropy.npz"),
        figure=report(
            fill(layout.AGREEMENT, name="agreement.png"),
            category="Uncertainty",
            caption="../report/entropy_agreement.rst",
            labels={"capture": "{object} / {env}", "figure": "entropy agreement"},
        ),
    log:
        layout.log("entropy_agreement", "{object}_{env}_{poses}"),
    benchmark:
        layout.benchmark("entropy_agreement", "{object}_{env}_{poses}")
    conda:
        "../envs/freqbrdf.yaml"
    threads: 2
    resources:
        mem_mb=memory(800),
        runtime=minutes(2, "agreement"),
        gpu=MITSUBA_GPUS,
    params:
        variant=config["mitsuba"]["variant"],
        settings={k: v for k, v in config["entropy_agreement"].items() if k != "captures"},
        spectrum=config["spectrum"],
        lmax=config["optimise"]["lmax"],
        lobe=config["optimise"]["lobe"],
        view_weight=config["optimise"]["view_weight"],
        diffuse=config["optimise"]["diffuse"],
        max_depth=config["render"]["max_depth"],
        seed=lambda w: derived_seed(config["seed"], "entropy_agreement", w.object, w.env, w.poses),
    script:
        "../scripts/entropy_agreement.py"
