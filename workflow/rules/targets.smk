# The targets of rule all: what every stage produces, and each rule file's own targets
# (REAL_CAPTURE_TARGETS, REPORT_TARGETS, ...); included last, so that every name is defined.
ALL_TARGETS = (
    [path for name in TRUTH_OBJECTS for path in object_files(name).values()]
    + expand(fill(layout.ENV_SPECTRUM, ext="png"), env=ENVS)
    + [layout.ENV_SPECTRA]
    + [fill(layout.CAPTURE, object=o, env=e, split="train") for o, e in SYNTHETIC_CAPTURES]
    # test views where relighting scores them: an environment defined only for other runs costs nothing
    + [fill(layout.CAPTURE, object=o, env=r, split="test") for o, r in sorted({(o, r) for o, _, _, _, r in RELIGHTS})]
    + ([layout.POSE_ERRORS] if config["poses"]["evaluate_colmap"] else [])
    + [fill(layout.OBSERVATIONS, object=o, env=e, poses=POSES) for o, e in CAPTURES]
    + [fill(layout.ESTIMATE, object=o, env=e, poses=POSES, method=m) for o, e in CAPTURES for m in METHODS]
    + [fill(layout.ENTROPY, object=o, env=e, poses=POSES) for o, e in CAPTURES]
    + list(dict.fromkeys(relit_dir(o, e, p, m) for o, e, p, m, _ in RELIGHTS))
    + REAL_CAPTURE_TARGETS
    + [layout.METRICS]
    + REPORT_TARGETS
    + EXPORT_TARGETS
    + VIEW_SELECTION_TARGETS
    + STRESS_TARGETS
)
