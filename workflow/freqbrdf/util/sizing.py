"""How much work a job does under a configuration, relative to the shipped default: the
Snakefile scales each rule's measured memory and time by it (docs/cluster.md)."""

from __future__ import annotations

from typing import Any


# The configuration the rules' measured resources refer to (config/config.yaml as shipped):
# `size_factor` scales them to another configuration's work.
REFERENCE_SIZE = {("render", "resolution"): 256, ("render", "spp"): 64, ("render", "train_views"): 24,
                  ("textures", "resolution"): 256, ("mitsuba", "spp"): 8, ("mitsuba", "epochs"): 48,
                  ("entropy_agreement", "texels"): 256, ("entropy_agreement", "spp"): 8,
                  ("entropy_agreement", "grid"): 8}
SIZE_KINDS = ("fixed", "pixels", "samples", "texels", "inverse", "agreement")


def size_factor(config: dict[str, Any], kind: str) -> float:
    """How much more work a job of ``kind`` does under ``config`` than under the shipped default.

    Parameters
    ----------
    config : dict
        The merged configuration.
    kind : {"fixed", "pixels", "samples", "texels", "inverse", "agreement"}
        What the job's time and memory grow with: nothing; the training images'
        pixels (resolution^2 x views); their samples (pixels x spp); texels x
        views; the differentiable-rendering baseline's samples (pixels x
        ``mitsuba.spp`` x ``mitsuba.epochs``); the entropy agreement's paths
        (texels x spp x grid^3 x views).

    Returns
    -------
    float
        1 for the default configuration.
    """
    def ratio(*key: str) -> float:
        value = config
        for k in key:
            value = value[k]
        return float(value) / REFERENCE_SIZE[key]

    if kind not in SIZE_KINDS:
        raise ValueError(f"size kind must be one of {SIZE_KINDS}, got {kind!r}")
    views = ratio("render", "train_views")
    pixels = ratio("render", "resolution") ** 2 * views
    factors = {
        "fixed": 1.0,
        "pixels": pixels,
        "samples": pixels * ratio("render", "spp"),
        "texels": ratio("textures", "resolution") ** 2 * views,
        "inverse": pixels * ratio("mitsuba", "spp") * ratio("mitsuba", "epochs"),
        "agreement": views * ratio("entropy_agreement", "texels") * ratio("entropy_agreement", "spp")
        * ratio("entropy_agreement", "grid") ** 3,
    }
    return factors[kind]
