# Shared definitions: names from config, wildcard constraints (only here), the inputs
# several rule files share, and the library modules each rule depends on. Every path
# comes from freqbrdf.layout; each rule file defines its own input functions and targets.
import math
from dataclasses import asdict

from freqbrdf import layout
from freqbrdf.config import is_captured, relight_envs as config_relight_envs
from freqbrdf.util.seeds import derived_seed
from freqbrdf.util.sizing import size_factor
from freqbrdf.util.mitsuba_setup import planned_variant
from freqbrdf.dependencies import script_modules
from freqbrdf.estimate.mitsuba_settings import run_settings
from freqbrdf.export.viewer import ENTROPY as ENTROPY_OVERLAY
from freqbrdf.layout import fill
from freqbrdf.scene import assets, scans
from freqbrdf.methods import FREQUENCY_RULES, METHODS as METHOD_REGISTRY, methods_of, wildcard_pattern
from freqbrdf.sphere.brdf import TEXTURES

SYNTHETIC_OBJECTS = list(config["objects"])
REAL_CAPTURES = config["real_captures"]  # name -> {dir, env, up_axis, ...}: captures imported from disk
# name -> {object, env, model, clearcoat, occluder, roughness, metallic}: synthetic captures that
# break the model's assumptions (config/stress.yaml), each an object of its own under one env.
STRESS = config["stress_captures"]
TRUTH_OBJECTS = SYNTHETIC_OBJECTS + list(STRESS)  # objects with ground-truth textures
OBJECTS = TRUTH_OBJECTS + list(REAL_CAPTURES)
DEFINED_ENVS = list(config["envs"])  # ENVS, below: those this run uses
CAPTURE_ENVS = list(config["capture_envs"])
SPLITS = ["train", "test"]
POSES = config["poses"]["source"]
POSE_COMPARE = [p for p in config["poses"]["compare"] if p != POSES]  # further sources scored on the benchmark
METHODS = list(config["methods"])  # names in freqbrdf.methods.METHODS (checked by check_config)
# Settings that only change how relit images are scored (metrics, the real captures' scores,
# the relighting figure): only those rules receive them, so editing one reruns nothing upstream.
METRIC_KEYS = ["mask_min_coverage", "hdr_clip", "hdr_normalise", "hdr_scale", "interval_widths"]
# Every (object, env) pair that has a training capture; synthetic ones have ground truth.
# The benchmark's captures make the paper's tables; the stress captures their own (rules/stress.smk).
BENCHMARK_CAPTURES = [(o, e) for o in SYNTHETIC_OBJECTS for e in CAPTURE_ENVS]
STRESS_CAPTURES = [(name, capture["env"]) for name, capture in STRESS.items()]
SYNTHETIC_CAPTURES = BENCHMARK_CAPTURES + STRESS_CAPTURES
CAPTURES = SYNTHETIC_CAPTURES + [(name, capture["env"]) for name, capture in REAL_CAPTURES.items()]
# (object, env, poses) of every synthetic capture metrics.csv scores: each under the run's
# pose source, and the benchmark's also under each of poses.compare.
SCORED = [(o, e, POSES) for o, e in SYNTHETIC_CAPTURES] + [
    (o, e, p) for p in POSE_COMPARE for o, e in BENCHMARK_CAPTURES
]


def object_shape(name):
    """The procedural shape of a synthetic object: its own name, or a stress capture's base object."""
    return STRESS[name]["object"] if name in STRESS else name


def stress_material(name):
    """Uniform texture values of a stress capture's object ({} for the benchmark's objects)."""
    return {key: STRESS[name][key] for key in ("roughness", "metallic") if key in STRESS.get(name, {})}


def scene_settings(wildcards):
    """How a capture is rendered beyond its textures: the BSDF model, clear coat, and an
    occluder in the training views only (the test views measure the material, not the occluder)."""
    capture = STRESS.get(wildcards.object, {})
    settings = {key: capture[key] for key in ("model", "clearcoat", "clearcoat_gloss") if key in capture}
    if wildcards.split == "train" and "occluder" in capture:
        settings["occluder"] = capture["occluder"]
    return settings


def relight_envs(obj, env, method):
    """Environments a synthetic capture's estimates are relit under (freqbrdf.config.relight_envs),
    none for a method evaluate.relight_methods leaves out. What the estimate has seen: its
    capture's environment, or for a merge (merge_svbrdf) those of every capture of the object."""
    relit = config["evaluate"]["relight_methods"]
    if relit != "all" and method not in relit:
        return []
    merged = METHOD_REGISTRY[method].rule == "merge_svbrdf"
    seen = [e for o, e in CAPTURES if o == obj] if merged else [env]
    return config_relight_envs(config["envs"], config["evaluate"]["relight_envs"], env, seen)


# Every relit image set (object, env, poses, method, relight_env): synthetic captures
# only; a real capture's test views are relit under their own maps (rule relight_real).
# Rule relight writes those of one estimate into one directory, relit_dir(...)/{relight_env}.
RELIGHTS = [(o, e, p, m, r) for o, e, p in SCORED for m in METHODS for r in relight_envs(o, e, m)]
# The environments this run lights a capture with or relights under, in config order: one that
# `envs` defines for other presets (the default's captured maps under config/tiny.yaml) costs nothing.
ENVS = [e for e in DEFINED_ENVS if e in {e for _, e in SYNTHETIC_CAPTURES} | {r for *_, r in RELIGHTS}]


def relit_dir(o, e, p, m):
    """Output of the relighting of one estimate (relight): a subdirectory per relighting environment."""
    return fill(layout.RELIT, object=o, env=e, poses=p, method=m)


wildcard_constraints:
    object="|".join(OBJECTS),
    env="|".join(DEFINED_ENVS + [capture["env"] for capture in REAL_CAPTURES.values()]),
    split="|".join(SPLITS),
    poses="gt|colmap",
    method=wildcard_pattern(list(METHOD_REGISTRY)),


# Scheduler resources (docs/cluster.md, "Running on a cluster"): each rule's peak memory (MB) and
# wall time (minutes) of its largest job on the shipped default config, measured from
# the benchmark files of a default run (python bench/resources.py) with headroom, and
# scaled to this configuration by what the job's work grows with.
def memory(mb, kind="fixed"):
    """``mb`` scaled by `freqbrdf.util.sizing.size_factor`, at least 500."""
    return max(500, math.ceil(mb * size_factor(config, kind)))


def minutes(amount, kind="fixed"):
    """``amount`` minutes scaled by `freqbrdf.util.sizing.size_factor`, at least 1."""
    return max(1, math.ceil(amount * size_factor(config, kind)))


# Rules that run Mitsuba ask for a GPU when they will use one (mitsuba.variant cuda_ad_rgb, or auto
# where this machine has a CUDA device), so that --resources gpu=1 runs one such job per device;
# the SLURM executor turns the gpu resource into --gpus.
MITSUBA_VARIANT = planned_variant(config["mitsuba"]["variant"])
MITSUBA_GPUS = int(MITSUBA_VARIANT == "cuda_ad_rgb")

LIBRARY = WORKFLOW / "freqbrdf"
SCRIPTS = WORKFLOW / "scripts"


def library(script):
    """Source files of the library modules that rule script ``workflow/scripts/{script}.py``
    imports (transitively, `freqbrdf.dependencies`); declaring them as inputs makes
    an edit to the library rerun exactly the rules that use it."""
    return [str(LIBRARY / path) for path in script_modules(SCRIPTS / f"{script}.py", LIBRARY)]


def object_files(name):
    """Ground-truth files of one object, keyed like the build_object outputs."""
    textures = {texture: fill(layout.OBJECT_TEXTURE, object=name, texture=texture) for texture in TEXTURES}
    return {"mesh": fill(layout.OBJECT_MESH, object=name)} | textures


def truth_files(wildcards):
    """Ground-truth texture files of an object, in TEXTURES order: procedural, imported
    with a real capture (config real_captures.{name}.textures), or none."""
    if wildcards.object in REAL_CAPTURES:
        if "textures" not in REAL_CAPTURES[wildcards.object]:
            return []
        return [fill(layout.IMPORT_TRUTH, object=wildcards.object, texture=name) for name in TEXTURES]
    return [object_files(wildcards.object)[name] for name in TEXTURES]


def capture_dir(wildcards, split):
    """Native capture directory of a split: rendered, or imported from disk."""
    if wildcards.object in REAL_CAPTURES:
        return fill(layout.IMPORT_SPLIT, object=wildcards.object, split=split)
    return fill(layout.CAPTURE, object=wildcards.object, env=wildcards.env, split=split)


def mesh_file(wildcards):
    """The object's mesh: procedural, or imported with a real capture."""
    if wildcards.object in REAL_CAPTURES:
        return fill(layout.IMPORT_MESH, object=wildcards.object)
    return fill(layout.OBJECT_MESH, object=wildcards.object)


def envmap_file(wildcards):
    """The environment map lighting a capture: procedural, or imported with a real capture."""
    if wildcards.object in REAL_CAPTURES:
        return fill(layout.IMPORT_ENVMAP, object=wildcards.object)
    return fill(layout.ENVMAP, env=wildcards.env)


def uses_light_table(method):
    """Whether a method's model takes the table of rule light_table (shadowed, its light the map's own
    rather than pre-filtered per capture, and optimise.light_table.rows above 0)."""
    entry = METHOD_REGISTRY[method]
    return (
        entry.rule == "optimise_svbrdf"
        and entry.shadowing
        and not entry.prefiltered
        and config["optimise"]["light_table"]["rows"] > 0
    )


def light_table_file(wildcards):
    """The table of the map lighting a capture (rule light_table), as envmap_file finds the map."""
    if wildcards.object in REAL_CAPTURES:
        return fill(layout.IMPORT_LIGHT_TABLE, object=wildcards.object)
    return fill(layout.LIGHT_TABLE, env=wildcards.env)


def light_table_input(wildcards, method=None):
    """{"light_table": the capture's table} if ``method`` (default: the wildcard's) uses one
    (uses_light_table), else nothing."""
    return {"light_table": light_table_file(wildcards)} if uses_light_table(method or wildcards.method) else {}


# The package of the captured light and the scans (freqbrdf.scene.assets), fetched by rule fetch_asset_package.
ASSET_PACKAGE = fill(layout.RESOURCE, name=assets.TARBALL)


# How xatlas packs the atlas of a scan, or of an imported mesh without usable UVs.
ATLAS = asdict(scans.AtlasSettings.from_config(config))


def asset_sources(wildcards):
    """Source records (origin, licence) of a capture's object, if synthetic, and of every environment."""
    objects = [] if wildcards.object in REAL_CAPTURES else [fill(layout.OBJECT_SOURCE, object=wildcards.object)]
    return objects + expand(layout.ENVMAP_SOURCE, env=ENVS)


def object_package(wildcards):
    """The package a scanned object's mesh is read from; nothing for a procedural one."""
    return {"package": ASSET_PACKAGE} if object_shape(wildcards.object) in scans.SCANS else {}


def env_package(wildcards):
    """The package an environment of kind hdri is read from; nothing for a procedural one."""
    return {"package": ASSET_PACKAGE} if is_captured(config["envs"][wildcards.env]) else {}


def pose_dir(wildcards):
    """Directory whose cameras.json holds the poses of a training capture:
    the capture itself (gt: the renderer's cameras) or the SfM result (colmap)."""
    if wildcards.poses == "gt":
        return capture_dir(wildcards, "train")
    return fill(layout.COLMAP_POSES, object=wildcards.object, env=wildcards.env)


# ---- input functions of rules/estimate.smk
def optimise_start(wildcards):
    """The spectrum-only estimate when the optimiser starts from it (optimise.init: spectrum)."""
    if config["optimise"]["init"] == "spectrum":
        return {
            "init": fill(
                layout.ESTIMATE, object=wildcards.object, env=wildcards.env, poses=wildcards.poses, method="spectrum"
            )
        }
    return {}


# ---- input functions of rules/evaluate.smk
def method_benchmarks(o, e, p, m):
    """Benchmark files of the jobs a method needs once the observations exist, its own rule last."""
    method = METHOD_REGISTRY[m]
    estimator = method.rule
    if estimator == "spectrum_search":
        return [layout.benchmark("fit_sh", f"{o}_{e}_{p}"), layout.benchmark("spectrum_search", f"{o}_{e}_{p}")]
    if method.start is not None:
        before = method_benchmarks(o, e, p, method.start)
    elif estimator == "optimise_svbrdf" and config["optimise"]["init"] == "spectrum":
        before = method_benchmarks(o, e, p, "spectrum")
    else:
        before = []
    if uses_light_table(m):  # the map's table, though another capture under the map may share it
        before.append(
            layout.benchmark("import_light_table", o) if o in REAL_CAPTURES else layout.benchmark("light_table", e)
        )
    return before + [layout.benchmark(estimator, f"{o}_{e}_{p}_{m}")]


# ---- input functions of rules/view_selection.smk
def candidate_poses(wildcards):
    """The cameras.json of config view_selection.candidate_poses, if one is given."""
    path = config["view_selection"]["candidate_poses"]
    return {"candidates": path} if path else {}


# ---- input functions of rules/export.smk
VIEWER_POSTERIORS = [m for m in METHODS if METHOD_REGISTRY[m].has_posterior]


def viewer_posteriors(wildcards):
    """The estimates (directories) whose posterior the viewer overlays, in VIEWER_POSTERIORS order."""
    w = wildcards
    return [fill(layout.ESTIMATE, object=w.object, env=w.env, poses=w.poses, method=m) for m in VIEWER_POSTERIORS]


def viewer_panels(wildcards):
    """The viewer's panels: the ground truth (synthetic captures only), then every method, whose
    uncertainty overlay is its posterior's (an overlay named after it) or the capture's entropy."""
    panels = (
        []
        if wildcards.object in REAL_CAPTURES
        else [{"name": layout.TRUTH, "label": "Ground truth", "uncertainty": None}]
    )
    return panels + [
        {"name": m, "label": METHOD_REGISTRY[m].label, "uncertainty": m if m in VIEWER_POSTERIORS else ENTROPY_OVERLAY}
        for m in METHODS
    ]


# ---- input functions of rules/mitsuba.smk
def mitsuba_start(wildcards):
    """The estimate a fine-tuning method starts from (its registry entry's start);
    the baseline starts from a constant 0.5 (no input)."""
    start = METHOD_REGISTRY[wildcards.method].start
    if start is not None:
        return {
            "init": fill(
                layout.ESTIMATE, object=wildcards.object, env=wildcards.env, poses=wildcards.poses, method=start
            )
        }
    return {}


def mitsuba_evaluation(wildcards):
    """Ground truth and observed texels of a synthetic capture, against which the run logs
    its parameter MSE after every epoch (evaluation only: issue 14's equal-accuracy ratio)."""
    if wildcards.object in REAL_CAPTURES:
        return {}
    w = wildcards
    return {
        "truth": [object_files(w.object)[n] for n in TEXTURES],
        "observations": fill(layout.OBSERVATIONS, object=w.object, env=w.env, poses=w.poses),
    }


def mitsuba_settings(wildcards):
    """Optimiser settings of one run (freqbrdf.estimate.mitsuba_settings.run_settings)."""
    w = wildcards
    return run_settings(config, w.object, w.env, w.poses, w.method)


# ---- input functions of rules/merge.smk
def merge_envs(wildcards):
    """Environments of every capture of the object, in the config's order whichever capture the
    merge is filed under (a tie is averaged: freqbrdf.estimate.merge.lowest_merge)."""
    return [e for o, e in CAPTURES if o == wildcards.object]


def merge_inputs(wildcards):
    """The start method's estimate of every capture of the object (merge_envs order), and their
    spectrum entropies where the method merges by them (an estimate carries its posterior)."""
    w = wildcards
    method = METHOD_REGISTRY[w.method]
    envs = merge_envs(w)
    inputs = {
        "estimates": [fill(layout.ESTIMATE, object=w.object, env=e, poses=w.poses, method=method.start) for e in envs]
    }
    if method.merged_by == "entropy":
        inputs["entropy"] = [fill(layout.ENTROPY, object=w.object, env=e, poses=w.poses) for e in envs]
    return inputs


# ---- input functions of rules/report.smk
def capture_relights(wildcards):
    """(method, relight_env) of every relit image set of one capture, relighting environment-major."""
    pairs = [(m, r) for o, e, p, m, r in RELIGHTS if (o, e, p) == (wildcards.object, wildcards.env, wildcards.poses)]
    return sorted(pairs, key=lambda pair: (ENVS.index(pair[1]), METHODS.index(pair[0])))


def relight_figure_envs(wildcards):
    """Relighting environments of one capture's figure, in the order of its references input."""
    return list(dict.fromkeys(r for _, r in capture_relights(wildcards)))
