# Shared definitions: names from config, wildcard constraints (only here), and
# the library modules each rule depends on.
from pathlib import Path

from freqbrdf.config import derived_seed

OBJECTS = list(config["objects"])
ENVS = list(config["envs"])
CAPTURE_ENVS = list(config["capture_envs"])
SPLITS = ["train", "test"]
POSES = config["poses"]["source"]

wildcard_constraints:
    object="|".join(OBJECTS),
    env="|".join(ENVS),
    split="|".join(SPLITS),
    poses="gt|colmap",


LIBRARY = Path(workflow.basedir) / "workflow" / "freqbrdf"


def library(*modules):
    """Source files of library modules a rule runs; declaring them as inputs
    makes an edit to the library rerun exactly the rules that use it."""
    return [str(LIBRARY / f"{module}.py") for module in ("__init__", "logs", "io", *modules)]


def object_files(name):
    """Ground-truth files of one object, keyed like the build_object outputs."""
    base = f"results/objects/{name}"
    return {
        "mesh": f"{base}/mesh.ply",
        "base_color": f"{base}/base_color.exr",
        "roughness": f"{base}/roughness.exr",
        "metallic": f"{base}/metallic.exr",
    }


def benchmark_outputs():
    """Every final output of the stages defined so far."""
    outputs = []
    for name in OBJECTS:
        outputs += list(object_files(name).values())
    outputs += expand("results/envs/{env}_spectrum.png", env=ENVS)
    outputs.append("results/envs/spectra.png")
    outputs += expand("results/captures/{object}/{env}/train", object=OBJECTS, env=CAPTURE_ENVS)
    outputs += expand("results/captures/{object}/{env}/test", object=OBJECTS, env=ENVS)
    outputs += expand("results/observations/{object}/{env}/{poses}", object=OBJECTS, env=CAPTURE_ENVS, poses=POSES)
    return outputs
