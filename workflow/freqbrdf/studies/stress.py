"""Captures that break the model's assumptions, and what they do to the estimates.

The benchmark's captures satisfy everything the estimators assume: a known light,
no occluder but the object itself, and the principled (GGX) BSDF. The stress
captures (config ``stress_captures``, rules/stress.smk) break one assumption each.
This module scores them from the tidy metrics (:mod:`freqbrdf.report.tables.tidy`) and from
the captures' own files:

- :func:`pose_effect_table`: the same captures estimated from SfM poses instead of
  the renderer's (what pose error costs in material error).
- :func:`stress_table`: each stress capture beside the capture it differs from by
  one assumption (a mismatched BSDF, an unseen occluder, a uniform material).
- :func:`blocked_light` and :func:`region_table`: inside and outside the part of
  the object an unseen occluder shadows (paper 001's setting).
- :func:`image_psnr`: how alike the two captures of a light/material ambiguity
  pair look.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
import pandas as pd

from freqbrdf.util.colour import LUMINANCE
from freqbrdf.capture.observations import sample_equirect
from freqbrdf.sphere.sampling import fibonacci_sphere
from freqbrdf.report.tables.display import MISSING, fmt, method_label, ordered_methods
from freqbrdf.report.tables.tidy import mean_metric


def blocked_light(positions: np.ndarray, normals: np.ndarray, envmap: np.ndarray, height: float, radius: float,
                  directions: int = 2048) -> np.ndarray:
    """Fraction of each surface point's irradiance that a horizontal disk blocks.

    The disk lies in the plane ``y = height``, centred on the vertical axis; the
    light is the environment map at infinity. Self-occlusion by the object is not
    counted (both with and without the disk), so the fraction is exact for a convex
    object and an estimate otherwise.

    Parameters
    ----------
    positions, normals : ndarray, shape (T, 3)
        World positions above the disk and unit normals.
    envmap : ndarray, shape (H, 2H, 3)
        Equirectangular radiance.
    height, radius : float
        The disk (``radius`` > 0).
    directions : int
        Fibonacci directions the hemisphere integral is sampled with.

    Returns
    -------
    ndarray, shape (T,), float64
        In [0, 1]: blocked / total cosine-weighted luminance; 0 where no light arrives.
    """
    positions = np.asarray(positions, dtype=np.float64)
    normals = np.asarray(normals, dtype=np.float64)
    if positions.shape != normals.shape or positions.ndim != 2 or positions.shape[1] != 3:
        raise ValueError(f"positions and normals must both have shape (T, 3), got {positions.shape} and {normals.shape}")
    if not radius > 0.0:
        raise ValueError(f"radius must be > 0, got {radius}")
    dirs = fibonacci_sphere(directions)  # (D, 3), equal solid angles
    light = sample_equirect(np.asarray(envmap, dtype=np.float64), dirs) @ LUMINANCE  # (D,)
    down = dirs[:, 1] < 0.0
    out = np.zeros(len(positions))
    for start in range(0, len(positions), 4096):
        p, n = positions[start : start + 4096], normals[start : start + 4096]
        weight = np.maximum(n @ dirs.T, 0.0) * light  # (t, D): cosine-weighted light
        # Where a ray p + s d (s > 0) meets the plane, and whether that point is on the disk.
        s = np.where(down, (height - p[:, 1:2]) / np.where(down, dirs[:, 1], -1.0), -1.0)
        hit_x = p[:, 0:1] + s * dirs[:, 0]
        hit_z = p[:, 2:3] + s * dirs[:, 2]
        blocked = (s > 0.0) & (hit_x**2 + hit_z**2 <= radius**2)
        total = weight.sum(axis=1)
        out[start : start + 4096] = np.divide((weight * blocked).sum(axis=1), total, out=np.zeros_like(total),
                                              where=total > 0.0)
    return out


def region_table(error: Mapping[str, np.ndarray], uncertainty: Mapping[str, np.ndarray],
                 shadowed: np.ndarray) -> pd.DataFrame:
    """Mean per-texel error of each method and mean of each uncertainty map, inside and outside a region.

    Parameters
    ----------
    error : mapping
        Method -> per-texel squared parameter error, shape (T,).
    uncertainty : mapping
        Name -> uncertainty of the same texels, shape (T,): ``entropy`` (normalised), and
        ``posterior_<method>`` (a method's expected squared parameter error under its posterior).
    shadowed : ndarray, shape (T,), bool
        The region (e.g. texels an unseen occluder shadows).

    Returns
    -------
    DataFrame
        Rows ``shadowed`` and ``lit``; columns ``texels``, ``mean_<name>`` per uncertainty map
        and ``mse_<method>`` (NaN for an empty region).
    """
    shadowed = np.asarray(shadowed, dtype=bool)
    rows = {}
    for name, mask in (("shadowed", shadowed), ("lit", ~shadowed)):
        row = {"texels": int(mask.sum())}
        row |= {f"mean_{u}": float(v[mask].mean()) if mask.any() else np.nan for u, v in uncertainty.items()}
        row |= {f"mse_{m}": float(e[mask].mean()) if mask.any() else np.nan for m, e in error.items()}
        rows[name] = row
    return pd.DataFrame.from_dict(rows, orient="index")


def image_psnr(a: Sequence[np.ndarray], b: Sequence[np.ndarray], masks: Sequence[np.ndarray]) -> float:
    """PSNR (dB) between two image sets over masked pixels, peak = the largest value of ``a`` there.

    Parameters
    ----------
    a, b : sequence of ndarray, shape (H, W, 3)
        Linear radiance, view by view.
    masks : sequence of ndarray, shape (H, W), bool
        Pixels compared.
    """
    if not len(a) == len(b) == len(masks) or not len(a):
        raise ValueError(f"image_psnr needs equally many images and masks, got {len(a)}, {len(b)}, {len(masks)}")
    x = np.concatenate([np.asarray(i)[m] for i, m in zip(a, masks)])
    y = np.concatenate([np.asarray(i)[m] for i, m in zip(b, masks)])
    if not x.size:
        raise ValueError("image_psnr: the masks select no pixel")
    mse = float(np.mean((x.astype(np.float64) - y) ** 2))
    return float(10.0 * np.log10(float(x.max()) ** 2 / mse)) if mse > 0 else float("inf")


def _cell(df: pd.DataFrame, obj: str, env: str, poses: str, method: str, metric: str, digits: int) -> str:
    return fmt(mean_metric(df, method, metric, object=obj, env=env, poses=poses), digits)


def pose_effect_table(df: pd.DataFrame, primary: str, other: str, captures: Sequence[tuple[str, str]],
                      methods: Sequence[str]) -> pd.DataFrame:
    """Each method's parameter MSE and relighting PSNR-H from two pose sources, and the change.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics (:func:`freqbrdf.report.tables.tidy.check_tidy`) holding both pose sources.
    primary, other : str
        Pose sources (e.g. ``gt`` and ``colmap``); the change is ``other - primary``.
    captures : sequence of (object, env)
        The captures averaged over (those scored under both sources).
    methods : sequence of str

    Returns
    -------
    DataFrame
        One row per method; means over the captures (and relighting environments).
    """
    keep = df[df[["object", "env"]].apply(tuple, axis=1).isin(set(map(tuple, captures)))]
    rows = []
    for method in ordered_methods(methods):
        values = {source: (mean_metric(keep, method, "mse_average", poses=source),
                           mean_metric(keep, method, "psnr_h", poses=source)) for source in (primary, other)}
        (mse_a, psnr_a), (mse_b, psnr_b) = values[primary], values[other]
        rows.append({
            "Method": method_label(method),
            f"MSE ({primary})": fmt(mse_a, 4), f"MSE ({other})": fmt(mse_b, 4),
            "MSE change": MISSING if None in (mse_a, mse_b) else f"{mse_b - mse_a:+.4f}",
            f"PSNR-H ({primary})": fmt(psnr_a, 2), f"PSNR-H ({other})": fmt(psnr_b, 2),
            "PSNR-H change": MISSING if None in (psnr_a, psnr_b) else f"{psnr_b - psnr_a:+.2f} dB",
        })
    return pd.DataFrame(rows)


def stress_table(df: pd.DataFrame, stress: Mapping[str, tuple[str, str]],
                 references: Mapping[str, tuple[str, str] | None], poses: str,
                 methods: Sequence[str]) -> pd.DataFrame:
    """Each stress capture beside the capture it differs from by one assumption.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics, with ``mean_entropy`` rows (method ``''``) per capture and the
        ``mean_posterior_error`` rows metrics.csv has (``freq``'s).
    stress : mapping
        Capture object name -> (env, what it breaks), in display order.
    references : mapping
        Capture object name -> the (object, env) it is compared with, or None.
    poses : str
        Pose source of the rows.
    methods : sequence of str

    Returns
    -------
    DataFrame
        One row per stress capture and method: parameter MSE, BRDF log-RMSE, relighting
        PSNR-H, the method's mean posterior error and the capture's mean entropy, each as
        ``stress (reference)``.
    """
    rows = []
    for name, (env, what) in stress.items():
        ref = references.get(name)
        for method in ordered_methods(methods):
            row = {"Capture": f"{name} / {env}", "Breaks": what,
                   "Compared with": MISSING if ref is None else f"{ref[0]} / {ref[1]}", "Method": method_label(method)}
            for metric, label, digits, who in (("mse_average", "MSE", 4, method), ("brdf_log_rmse", "BRDF log-RMSE", 3, method),
                                               ("psnr_h", "PSNR-H", 2, method),
                                               ("mean_posterior_error", "Mean posterior error", 4, method),
                                               ("mean_entropy", "Mean entropy", 3, "")):
                ours = _cell(df, name, env, poses, who, metric, digits)
                theirs = MISSING if ref is None else _cell(df, *ref, poses, who, metric, digits)
                row[label] = f"{ours} ({theirs})"
            rows.append(row)
    return pd.DataFrame(rows)


def pair_table(df: pd.DataFrame, pairs: Sequence[tuple[tuple[str, str], tuple[str, str], float]],
               references: Mapping[str, tuple[str, str] | None], poses: str, methods: Sequence[str]) -> pd.DataFrame:
    """Light/material ambiguity pairs: how alike their images are, and their entropy and errors.

    Parameters
    ----------
    df : DataFrame
        Tidy metrics with ``mean_entropy`` rows.
    pairs : sequence of ((object, env), (object, env), psnr)
        The two captures of each pair and the PSNR (dB) between their training views.
    references : mapping
        Capture object name -> the benchmark capture (object, env) whose entropy it is read beside.
    poses : str
    methods : sequence of str

    Returns
    -------
    DataFrame
        One row per capture of each pair: image PSNR to its partner, mean entropy (the
        reference's in brackets), and each method's roughness MSE.
    """
    rows = []
    for first, second, psnr in pairs:
        for (obj, env), partner in ((first, second), (second, first)):
            ref = references.get(obj)
            entropy = _cell(df, obj, env, poses, "", "mean_entropy", 3)
            row = {"Capture": f"{obj} / {env}", "Partner": f"{partner[0]} / {partner[1]}",
                   "Image PSNR to partner": fmt(psnr, 1, " dB"),
                   "Mean entropy": entropy + ("" if ref is None else f" ({_cell(df, *ref, poses, '', 'mean_entropy', 3)})")}
            row |= {f"Roughness MSE {method_label(m)}": _cell(df, obj, env, poses, m, "mse_roughness", 4)
                    for m in ordered_methods(methods)}
            rows.append(row)
    return pd.DataFrame(rows)


def ambiguity_pairs(stress: Mapping[str, Mapping[str, object]]) -> list[tuple[str, str]]:
    """Each light/material ambiguity pair of config ``stress_captures`` once, in config order,
    whether its ``pair`` key is set on one capture or on both.

    Returns
    -------
    list of (str, str)
        (first, second) capture names, the first being the earlier in config.
    """
    order = list(stress)
    pairs = {tuple(sorted((name, str(spec["pair"])), key=order.index))
             for name, spec in stress.items() if "pair" in spec}
    return sorted(pairs, key=lambda pair: order.index(pair[0]))


def stress_description(capture: Mapping[str, object]) -> str:
    """What a stress capture (a config ``stress_captures`` entry) breaks, in a few words."""
    parts = []
    model = capture.get("model", "principled")
    if model == "beckmann_blend":
        parts.append("Beckmann microfacets (GGX fitted)")
    elif model == "ggx_blend":
        parts.append("GGX lobes, other diffuse and Fresnel (control)")
    if capture.get("clearcoat", 0.0):
        parts.append(f"clear coat {capture['clearcoat']:g} (gloss {capture.get('clearcoat_gloss', 0.0):g})")
    if "occluder" in capture:
        occluder = capture["occluder"]
        parts.append(f"unseen occluder (disk r {occluder['radius']:g} at y {occluder['height']:g})")
    uniform = [f"{key} {capture[key]:g}" for key in ("roughness", "metallic") if key in capture]
    if uniform:
        parts.append("uniform " + ", ".join(uniform))
    if "pair" in capture:
        parts.append(f"ambiguity pair of {capture['pair']}")
    return "; ".join(parts) or "nothing (a control)"


def stress_reference(name: str, stress: Mapping[str, Mapping[str, object]],
                     benchmark: Sequence[tuple[str, str]]) -> tuple[str, str] | None:
    """The capture a stress capture is compared with, differing from it by the one assumption.

    In order: for Beckmann lobes, a GGX-blend control of the same object and environment;
    for any other, a plain stress capture (no key but ``object`` and ``env``) of the same
    object and environment, e.g. the control of an occluded capture under its own light;
    else the benchmark capture of its object under its environment; else None.

    Parameters
    ----------
    name : str
        A key of ``stress``.
    stress : mapping
        config ``stress_captures``.
    benchmark : sequence of (object, env)
        The benchmark's captures.
    """
    capture = stress[name]
    base = (capture["object"], capture["env"])
    control = {"ggx_blend"} if capture.get("model") == "beckmann_blend" else {"principled"}
    for other, spec in stress.items():
        if other != name and (spec["object"], spec["env"]) == base and set(spec) <= {"object", "env", "model"} \
                and spec.get("model", "principled") in control:
            return other, spec["env"]
    return base if base in set(map(tuple, benchmark)) else None
