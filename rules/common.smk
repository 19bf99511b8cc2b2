# Shared definitions: names from config, wildcard constraints (only here), and
# the library modules each rule depends on.
import math
from pathlib import Path

from freqbrdf.sphere.brdf import TEXTURES
from freqbrdf.config import derived_seed, size_factor
from freqbrdf.dependencies import script_modules
from freqbrdf.methods import FREQUENCY_RULES, METHODS as METHOD_REGISTRY, methods_of, wildcard_pattern

SYNTHETIC_OBJECTS = list(config["objects"])
REAL_CAPTURES = config["real_captures"]  # name -> {dir, env, up_axis, ...}: captures imported from disk
# name -> {object, env, model, clearcoat, occluder, roughness, metallic}: synthetic captures that
# break the model's assumptions (config/stress.yaml), each an object of its own under one env.
STRESS = config["stress_captures"]
TRUTH_OBJECTS = SYNTHETIC_OBJECTS + list(STRESS)  # objects with ground-truth textures
OBJECTS = TRUTH_OBJECTS + list(REAL_CAPTURES)
ENVS = list(config["envs"])
CAPTURE_ENVS = list(config["capture_envs"])
SPLITS = ["train", "test"]
POSES = config["poses"]["source"]
POSE_COMPARE = [p for p in config["poses"]["compare"] if p != POSES]  # further sources scored on the benchmark
METHODS = list(config["methods"])  # names in freqbrdf.methods.METHODS (checked by check_config)
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


def relight_envs(env, method):
    """Environments a synthetic capture's estimates are relit under (config evaluate.relight_envs).
    held_out leaves out the capture's own environment and, for a merge of all the object's
    captures (merge_svbrdf), every capture environment: the merge has seen them all."""
    choice = config["evaluate"]["relight_envs"]
    if choice == "held_out":
        seen = CAPTURE_ENVS if METHOD_REGISTRY[method].rule == "merge_svbrdf" else [env]
        return [e for e in ENVS if e not in seen]
    return ENVS if choice == "all" else list(choice)


# Every relit image set (object, env, poses, method, relight_env): synthetic captures
# only; a real capture's test views are relit under their own maps (rule relight_real).
# Rule relight writes those of one estimate into one directory, relit_dir(...)/{relight_env}.
RELIGHTS = [(o, e, p, m, r) for o, e, p in SCORED for m in METHODS for r in relight_envs(e, m)]


def relit_dir(o, e, p, m):
    """Output of the relighting of one estimate (relight): a subdirectory per relighting environment."""
    return f"results/relight/{o}/{e}/{p}/{m}"


wildcard_constraints:
    object="|".join(OBJECTS),
    env="|".join(ENVS + [capture["env"] for capture in REAL_CAPTURES.values()]),
    split="|".join(SPLITS),
    poses="gt|colmap",
    method=wildcard_pattern(list(METHOD_REGISTRY)),


# Scheduler resources (README "Running on a cluster"): each rule's peak memory (MB) and
# wall time (minutes) of its largest job on the shipped default config, measured from
# the benchmark files of a default run (python bench/resources.py) with headroom, and
# scaled to this configuration by what the job's work grows with.
def memory(mb, kind="fixed"):
    """``mb`` scaled by `freqbrdf.config.size_factor`, at least 500."""
    return max(500, math.ceil(mb * size_factor(config, kind)))


def minutes(amount, kind="fixed"):
    """``amount`` minutes scaled by `freqbrdf.config.size_factor`, at least 1."""
    return max(1, math.ceil(amount * size_factor(config, kind)))


# Rules that run Mitsuba ask for a GPU when they will use one (mitsuba.variant: cuda_ad_rgb);
# the SLURM executor turns the gpu resource into --gpus.
MITSUBA_GPUS = int(config["mitsuba"]["variant"] == "cuda_ad_rgb")

LIBRARY = REPO / "workflow" / "freqbrdf"
SCRIPTS = REPO / "workflow" / "scripts"


def library(script):
    """Source files of the library modules that rule script ``workflow/scripts/{script}.py``
    imports (transitively, `freqbrdf.dependencies`); declaring them as inputs makes
    an edit to the library rerun exactly the rules that use it."""
    return [str(LIBRARY / path) for path in script_modules(SCRIPTS / f"{script}.py", LIBRARY)]


def object_files(name):
    """Ground-truth files of one object, keyed like the build_object outputs."""
    base = f"results/objects/{name}"
    return {"mesh": f"{base}/mesh.ply"} | {texture: f"{base}/{texture}.exr" for texture in TEXTURES}


def truth_files(wildcards):
    """Ground-truth texture files of an object, in TEXTURES order: procedural, imported
    with a real capture (config real_captures.{name}.textures), or none."""
    if wildcards.object in REAL_CAPTURES:
        if "textures" not in REAL_CAPTURES[wildcards.object]:
            return []
        return [f"results/imports/{wildcards.object}/truth/{name}.exr" for name in TEXTURES]
    return [object_files(wildcards.object)[name] for name in TEXTURES]


def capture_dir(wildcards, split):
    """Native capture directory of a split: rendered, or imported from disk."""
    if wildcards.object in REAL_CAPTURES:
        return f"results/imports/{wildcards.object}/{split}"
    return f"results/captures/{wildcards.object}/{wildcards.env}/{split}"


def mesh_file(wildcards):
    """The object's mesh: procedural, or imported with a real capture."""
    if wildcards.object in REAL_CAPTURES:
        return f"results/imports/{wildcards.object}/mesh.ply"
    return f"results/objects/{wildcards.object}/mesh.ply"


def envmap_file(wildcards):
    """The environment map lighting a capture: procedural, or imported with a real capture."""
    if wildcards.object in REAL_CAPTURES:
        return f"results/imports/{wildcards.object}/envmap.exr"
    return f"results/envs/{wildcards.env}.exr"


def pose_dir(wildcards):
    """Directory whose cameras.json holds the poses of a training capture:
    the capture itself (gt: the renderer's cameras) or the SfM result (colmap)."""
    if wildcards.poses == "gt":
        return capture_dir(wildcards, "train")
    return f"results/poses/{wildcards.object}/{wildcards.env}/colmap"


def final_outputs():
    """Every final output of the workflow (the targets of rule all)."""
    outputs = []
    for name in TRUTH_OBJECTS:
        outputs += list(object_files(name).values())
    outputs += expand("results/envs/{env}_spectrum.png", env=ENVS)
    outputs.append("results/envs/spectra.png")
    outputs += [f"results/captures/{o}/{e}/train" for o, e in SYNTHETIC_CAPTURES]
    outputs += expand("results/captures/{object}/{env}/test", object=SYNTHETIC_OBJECTS, env=ENVS)
    if config["poses"]["evaluate_colmap"]:
        outputs.append("results/tables/pose_errors.tsv")
    outputs += [f"results/observations/{o}/{e}/{POSES}" for o, e in CAPTURES]
    outputs += [f"results/estimates/{o}/{e}/{POSES}/{m}" for o, e in CAPTURES for m in METHODS]
    outputs += [f"results/entropy/{o}/{e}/{POSES}" for o, e in CAPTURES]
    outputs += list(dict.fromkeys(relit_dir(o, e, p, m) for o, e, p, m, _ in RELIGHTS))
    outputs += real_capture_outputs()  # rules/exchange.smk
    outputs.append("results/tables/metrics.csv")
    outputs += report_outputs()  # rules/report.smk: tables, claims, per-capture figures
    outputs += gltf_outputs()  # rules/export.smk: .glb files, .hdr environments, viewer pages
    outputs += view_selection_outputs()  # rules/view_selection.smk
    outputs += stress_outputs()  # rules/stress.smk
    return outputs


# ---- input functions and targets of rules/estimate.smk
def optimise_start(wildcards):
    """The spectrum-only estimate when the optimiser starts from it (optimise.init: spectrum)."""
    if config["optimise"]["init"] == "spectrum":
        return {"init": f"results/estimates/{wildcards.object}/{wildcards.env}/{wildcards.poses}/spectrum"}
    return {}


# ---- input functions and targets of rules/evaluate.smk
def method_benchmarks(o, e, p, m):
    """Benchmark files of the jobs a method needs once the observations exist, its own rule last."""
    bench = "results/benchmarks"
    method = METHOD_REGISTRY[m]
    estimator = method.rule
    if estimator == "spectrum_search":
        return [f"{bench}/fit_sh/{o}_{e}_{p}.tsv", f"{bench}/spectrum_search/{o}_{e}_{p}.tsv"]
    if method.start is not None:
        before = method_benchmarks(o, e, p, method.start)
    elif estimator == "optimise_svbrdf" and config["optimise"]["init"] == "spectrum":
        before = method_benchmarks(o, e, p, "spectrum")
    else:
        before = []
    return before + [f"{bench}/{estimator}/{o}_{e}_{p}_{m}.tsv"]


# ---- input functions and targets of rules/exchange.smk
def real_capture_outputs():
    """Every output of the real captures alone (targets of rule real_captures)."""
    outputs = []
    for name, capture in REAL_CAPTURES.items():
        o, e = name, capture["env"]
        outputs += [f"results/imports/{o}/env_orientation.tsv", f"results/observations/{o}/{e}/{POSES}"]
        outputs += [f"results/estimates/{o}/{e}/{POSES}/{m}" for m in METHODS]
        outputs += [f"results/entropy/{o}/{e}/{POSES}", f"results/figures/{o}/{e}/{POSES}/maps.png"]
        outputs.append(f"results/tables/real/{o}_{e}_{POSES}_relight.csv")
        if "textures" in capture:
            outputs.append(f"results/tables/real/{o}_{e}_{POSES}.csv")
    return outputs


# ---- input functions and targets of rules/view_selection.smk
def candidate_poses(wildcards):
    """The cameras.json of config view_selection.candidate_poses, if one is given."""
    path = config["view_selection"]["candidate_poses"]
    return {"candidates": path} if path else {}


def view_selection_outputs():
    """The ranked candidates of the first synthetic capture and, with view_selection.sweep_counts,
    the comparison of selection strategies (targets of rule all)."""
    outputs = [f"results/view_selection/{o}/{e}/{POSES}/ranked.tsv" for o, e in VIEW_SELECTION_CAPTURES]
    if VIEW_SELECTION_SWEEP_CAPTURES:
        outputs += ["results/tables/view_selection.tsv", "results/figures/view_selection.png"]
    return outputs


# ---- input functions and targets of rules/stress.smk
def stress_outputs():
    """The stress page and figure when the config has stress captures or compared pose sources."""
    if not (STRESS or POSE_COMPARE):
        return []
    return ["results/tables/stress.md", "results/tables/stress.html", "results/figures/stress.png"]


# ---- input functions and targets of rules/export.smk
def gltf_outputs():
    """Every .glb, .hdr and viewer page the export rules write (targets of rule all)."""
    outputs = [f"results/gltf/{o}/{TRUTH_GLTF}.glb" for o in TRUTH_OBJECTS]
    outputs += [f"results/gltf/{o}/{e}/{POSES}/{m}.glb" for o, e in CAPTURES for m in METHODS]
    outputs += expand("results/envs/{env}.hdr", env=ENVS)
    outputs += [f"results/viewer/{o}/{e}/{POSES}/viewer.html" for o, e in CAPTURES]
    return outputs


def viewer_panels(wildcards):
    """The viewer's panels: the ground truth (synthetic captures only), then every method."""
    panels = (
        [] if wildcards.object in REAL_CAPTURES else [{"name": TRUTH_GLTF, "label": "Ground truth", "overlay": False}]
    )
    return panels + [{"name": m, "label": METHOD_REGISTRY[m].label, "overlay": True} for m in METHODS]


# ---- input functions and targets of rules/finetune.smk
def mitsuba_start(wildcards):
    """The estimate a fine-tuning method starts from (its registry entry's start);
    the baseline starts from a constant 0.5 (no input)."""
    start = METHOD_REGISTRY[wildcards.method].start
    if start is not None:
        return {"init": f"results/estimates/{wildcards.object}/{wildcards.env}/{wildcards.poses}/{start}"}
    return {}


def mitsuba_evaluation(wildcards):
    """Ground truth and observed texels of a synthetic capture, against which the run logs
    its parameter MSE after every epoch (evaluation only: issue 14's equal-accuracy ratio)."""
    if wildcards.object in REAL_CAPTURES:
        return {}
    w = wildcards
    return {
        "truth": [object_files(w.object)[n] for n in TEXTURES],
        "observations": f"results/observations/{w.object}/{w.env}/{w.poses}",
    }


def mitsuba_settings(wildcards):
    """Optimiser settings of one run: config `mitsuba`, with `mitsuba.finetune`
    overriding epochs and spp when fine-tuning; a seed per capture and method."""
    settings = {key: value for key, value in config["mitsuba"].items() if key not in ("finetune", "variant")}
    if METHOD_REGISTRY[wildcards.method].start is not None:
        settings.update(config["mitsuba"]["finetune"])
    settings["seed"] = derived_seed(
        config["seed"], "mitsuba", wildcards.object, wildcards.env, wildcards.poses, wildcards.method
    )
    return settings


# ---- input functions and targets of rules/merge.smk
def merge_envs(wildcards):
    """Environments of every capture of the object, the one the merge is filed under first (ties go to it)."""
    return [wildcards.env] + [e for o, e in CAPTURES if o == wildcards.object and e != wildcards.env]


def merge_inputs(wildcards):
    """The start method's estimate and the spectrum entropy of every capture of the object (merge_envs order)."""
    w = wildcards
    start = METHOD_REGISTRY[w.method].start
    envs = merge_envs(w)
    return {
        "estimates": [f"results/estimates/{w.object}/{e}/{w.poses}/{start}" for e in envs],
        "entropy": [f"results/entropy/{w.object}/{e}/{w.poses}" for e in envs],
    }


# ---- input functions and targets of rules/report.smk
def report_outputs():
    """Every file the report rules write (targets of rule all)."""
    outputs = [f"results/tables/{t}.{ext}" for t in TABLES for ext in ("md", "tex")]
    outputs += ["results/tables/tables.md", "results/tables/tables.html", "results/tables/claims.html"]
    outputs += [f"results/figures/{o}/{e}/{POSES}/maps.png" for o, e in CAPTURES]
    outputs += [f"results/figures/{o}/{e}/{POSES}/relight.png" for o, e in SYNTHETIC_CAPTURES]
    outputs += [f"results/figures/{o}/{e}/{POSES}/regulariser.png" for o, e in CAPTURES]
    outputs += [f"results/views/{o}/{e}/{POSES}/views.png" for o, e in VIEWS_CAPTURES]
    outputs += [f"results/entropy_agreement/{o}/{e}/{POSES}/agreement.png" for o, e in AGREEMENT_CAPTURES]
    if CONVERGENCE_CURVES:
        outputs += [f"results/figures/{o}/{e}/{POSES}/convergence.png" for o, e in SYNTHETIC_CAPTURES]
    return outputs


def capture_relights(wildcards):
    """(method, relight_env) of every relit image set of one capture, relighting environment-major."""
    pairs = [(m, r) for o, e, p, m, r in RELIGHTS if (o, e, p) == (wildcards.object, wildcards.env, wildcards.poses)]
    return sorted(pairs, key=lambda pair: (ENVS.index(pair[1]), METHODS.index(pair[0])))


def relight_figure_envs(wildcards):
    """Relighting environments of one capture's figure, in the order of its references input."""
    return list(dict.fromkeys(r for _, r in capture_relights(wildcards)))
