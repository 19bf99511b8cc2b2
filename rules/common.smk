# Shared definitions: names from config, wildcard constraints (only here), and
# the library modules each rule depends on.
from pathlib import Path

from freqbrdf.brdf import TEXTURES
from freqbrdf.config import derived_seed
from freqbrdf.dependencies import script_modules
from freqbrdf.methods import FREQUENCY_RULES, METHODS as METHOD_REGISTRY, methods_of, wildcard_pattern

SYNTHETIC_OBJECTS = list(config["objects"])
REAL_CAPTURES = config["real_captures"]  # name -> {dir, env, up_axis, ...}: captures imported from disk
OBJECTS = SYNTHETIC_OBJECTS + list(REAL_CAPTURES)
ENVS = list(config["envs"])
CAPTURE_ENVS = list(config["capture_envs"])
SPLITS = ["train", "test"]
POSES = config["poses"]["source"]
METHODS = list(config["methods"])  # names in freqbrdf.methods.METHODS (checked by check_config)
# Every (object, env) pair that has a training capture; synthetic ones have ground truth.
SYNTHETIC_CAPTURES = [(o, e) for o in SYNTHETIC_OBJECTS for e in CAPTURE_ENVS]
CAPTURES = SYNTHETIC_CAPTURES + [
    (name, capture["env"]) for name, capture in REAL_CAPTURES.items()
]


def relight_envs(env, method):
    """Environments a synthetic capture's estimates are relit under (config evaluate.relight_envs).
    held_out leaves out the capture's own environment and, for a merge of all the object's
    captures (rule merge_svbrdf), every capture environment: the merge has seen them all."""
    choice = config["evaluate"]["relight_envs"]
    if choice == "held_out":
        seen = CAPTURE_ENVS if METHOD_REGISTRY[method].rule == "merge_svbrdf" else [env]
        return [e for e in ENVS if e not in seen]
    return ENVS if choice == "all" else list(choice)


# Every relit image set (object, env, poses, method, relight_env): synthetic captures
# only; a real capture's test views are relit under their own maps (rule relight_real).
# Rule relight writes those of one estimate into one directory, relit_dir(...)/{relight_env}.
RELIGHTS = [(o, e, POSES, m, r) for o, e in SYNTHETIC_CAPTURES for m in METHODS for r in relight_envs(e, m)]


def relit_dir(o, e, p, m):
    """Output of rule relight for one estimate: a subdirectory per relighting environment."""
    return f"results/relight/{o}/{e}/{p}/{m}"

wildcard_constraints:
    object="|".join(OBJECTS),
    env="|".join(ENVS + [capture["env"] for capture in REAL_CAPTURES.values()]),
    split="|".join(SPLITS),
    poses="gt|colmap",
    method=wildcard_pattern(list(METHOD_REGISTRY)),


LIBRARY = Path(workflow.basedir) / "workflow" / "freqbrdf"
SCRIPTS = Path(workflow.basedir) / "workflow" / "scripts"


def library(script):
    """Source files of the library modules that rule script ``workflow/scripts/{script}.py``
    imports (transitively, `freqbrdf.dependencies`); declaring them as inputs makes
    an edit to the library rerun exactly the rules that use it."""
    return [str(LIBRARY / f"{module}.py") for module in script_modules(SCRIPTS / f"{script}.py", LIBRARY)]


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
    for name in SYNTHETIC_OBJECTS:
        outputs += list(object_files(name).values())
    outputs += expand("results/envs/{env}_spectrum.png", env=ENVS)
    outputs.append("results/envs/spectra.png")
    outputs += expand("results/captures/{object}/{env}/train", object=SYNTHETIC_OBJECTS, env=CAPTURE_ENVS)
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
    return outputs
