"""Where every result lives: the path templates of ``results/``, one per artefact.

The rules (``rules/*.smk``) use the templates as outputs, with their named wildcards
(``{object}``, ``{env}``, ``{split}``, ``{poses}``, ``{method}``, ...), and fill them with
`str.format` where they name another rule's output; the benches fill them the same way.
Scripts never build a path: they take every path from Snakemake (``tests/test_layout.py``).
A path template changes here, and nowhere else.
"""

from __future__ import annotations

import os
from pathlib import Path

__all__ = ["RESULTS", "fill", "located", "log", "benchmark"]

RESULTS = "results"

# Synthetic scenes (rules/objects.smk, rules/envs.smk, rules/captures.smk)
OBJECT_MESH = "results/objects/{object}/mesh.ply"
OBJECT_TEXTURE = "results/objects/{object}/{texture}.exr"
OBJECT_PREVIEW = "results/objects/{object}/{texture}.png"
OBJECT_SOURCE = "results/objects/{object}/source.json"  # the shape's origin and licence
ENVMAP = "results/envs/{env}.exr"
ENVMAP_PREVIEW = "results/envs/{env}.png"
ENVMAP_HDR = "results/envs/{env}.hdr"
ENVMAP_SOURCE = "results/envs/{env}.json"  # where the map comes from: its kind, settings, licence, clean-up
ENV_SPECTRUM = "results/envs/{env}_spectrum.{ext}"
ENV_SPECTRA = "results/envs/spectra.png"
LIGHT_TABLE = "results/envs/{env}_light_table"  # the shadowed light tabulated over normals (rules/estimate.smk)
CAPTURE = "results/captures/{object}/{env}/{split}"
RESOURCE = "results/resources/{name}"  # packages fetched from a registry (the captured light's npm package)

# Captures made elsewhere (rules/exchange.smk)
EXPORT = "results/exports/{object}/{env}"
IMPORT_SPLIT = "results/imports/{object}/{split}"
IMPORT_MESH = "results/imports/{object}/mesh.ply"
IMPORT_ENVMAP_GIVEN = "results/imports/{object}/envmap_given.exr"
IMPORT_ENVMAP = "results/imports/{object}/envmap.exr"
IMPORT_LIGHT_TABLE = "results/imports/{object}/light_table"
IMPORT_ORIENTATION = "results/imports/{object}/env_orientation.tsv"
IMPORT_ROTATION = "results/imports/{object}/env_rotation.json"
IMPORT_TRUTH = "results/imports/{object}/truth/{texture}.exr"
REAL_SCORES = "results/tables/real/{object}_{env}_{poses}.csv"
REAL_RELIGHT_SCORES = "results/tables/real/{object}_{env}_{poses}_relight.csv"

# Poses, observations, estimates (rules/poses.smk to rules/merge.smk)
COLMAP_POSES = "results/poses/{object}/{env}/colmap"
POSE_ERRORS = "results/tables/pose_errors.tsv"
OBSERVATIONS = "results/observations/{object}/{env}/{poses}"
SH_FIT = "results/sh/{object}/{env}/{poses}"
ESTIMATE = "results/estimates/{object}/{env}/{poses}/{method}"
ENTROPY = "results/entropy/{object}/{env}/{poses}"

# Relighting (rules/relight.smk, rules/exchange.smk): a subdirectory per relighting environment
RELIT = "results/relight/{object}/{env}/{poses}/{method}"
RELIT_REAL = "results/relight_real/{object}/{env}/{poses}/{method}"

# Studies (rules/views.smk, rules/entropy_agreement.smk, rules/view_selection.smk, rules/stress.smk)
VIEWS = "results/views/{object}/{env}/{poses}/views.{ext}"
AGREEMENT = "results/entropy_agreement/{object}/{env}/{poses}/{name}"
VIEW_SELECTION = "results/view_selection/{object}/{env}/{poses}/{name}"

# Evaluation, report and exports (rules/evaluate.smk, rules/report.smk, rules/export.smk)
METRICS = "results/tables/metrics.csv"
SPARSIFICATION = "results/tables/sparsification.tsv"  # the curves behind the ause_* metrics
RELIABILITY = "results/tables/reliability.tsv"  # the posterior's coverage at several nominal levels
TABLE = "results/tables/{name}"
FIGURE = "results/figures/{name}"
CAPTURE_FIGURE = "results/figures/{object}/{env}/{poses}/{name}"
GLTF = "results/gltf/{object}/{env}/{poses}/{method}.glb"
TRUTH = "truth"  # the ground truth's name beside the methods': its .glb file, glTF node and material, viewer panel
TRUTH_GLTF = "results/gltf/{object}/" + TRUTH + ".glb"
VIEWER = "results/viewer/{object}/{env}/{poses}/viewer.html"
REPORT = "results/report.html"  # snakemake --report's target
# The config of the last successful run here (the Snakefile's onsuccess), which a plain
# `snakemake --report` reports (freqbrdf.config.reports_last_run)
RUN_CONFIG = "results/run_config.yaml"
REPORT_SCREENSHOTS = "results/report_screenshots"

# What every job leaves beside its outputs
LOG = "results/logs/{rule}/{job}.log"
BENCHMARK = "results/benchmarks/{rule}/{job}.tsv"


class _Wildcards(dict):
    """Fields not given to `fill` stay in the path as wildcards."""

    def __missing__(self, key: str) -> str:
        return "{" + key + "}"


def fill(template: str, **values: object) -> str:
    """``template`` with the fields in ``values`` filled and every other field left as a wildcard.

    >>> fill(ESTIMATE, method="spectrum")
    'results/estimates/{object}/{env}/{poses}/spectrum'
    """
    return template.format_map(_Wildcards(values))


def located(template: str, root: str | os.PathLike | None = None, **values: object) -> Path:
    """`fill` as a path, every field given, under ``root`` in place of ``results/`` when given
    (a results tree elsewhere, e.g. another clone's, as the benches accept).

    >>> str(located(ENVMAP, "/tmp/run/results", env="studio"))
    '/tmp/run/results/envs/studio.exr'
    """
    path = fill(template, **values)
    if "{" in path:
        raise KeyError(f"{template}: a field is not given in {sorted(values)}")
    relative = Path(path).relative_to(RESULTS)
    return (Path(root) if root is not None else Path(RESULTS)) / relative


def log(rule: str, job: str = "") -> str:
    """Log file of one job of ``rule``: ``job`` names it by its wildcards (``"{object}_{env}"``);
    a rule with a single job has ``results/logs/{rule}.log``."""
    return LOG.format(rule=rule, job=job) if job else f"{RESULTS}/logs/{rule}.log"


def benchmark(rule: str, job: str = "") -> str:
    """Snakemake benchmark file (time, memory) of one job of ``rule``, named as `log` names its log."""
    return BENCHMARK.format(rule=rule, job=job) if job else f"{RESULTS}/benchmarks/{rule}.tsv"
