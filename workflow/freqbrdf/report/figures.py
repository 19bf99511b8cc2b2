"""The report's figures: recovered maps against ground truth with the entropy and error maps,
relit renders beside the ground-truth renders, convergence and sparsification curves.

Kept apart from :mod:`freqbrdf.util.previews` (whose figure helpers it shares) on
purpose: rules declare the library modules they run as inputs, and only the
report rules use these figures, so editing them reruns nothing upstream.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING

import numpy as np

from freqbrdf.util.colour import to_srgb, tonemap
from freqbrdf.report.metrics import parameter_error_map
from freqbrdf.report.relight_metrics import STANFORD_ORB, HdrScoring, hdr_pair, psnr_h
from freqbrdf.report.tables.display import method_label  # the registry's display names, as the tables print them
from freqbrdf.util.previews import atlas_image, pyplot, save_figure

if TYPE_CHECKING:  # pragma: no cover
    import pandas as pd
    from matplotlib.figure import Figure

GREY = "0.85"  # outside the UV atlas (or not scored)


def atlas_masks(resolution: int, texel: np.ndarray, observed: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Texels inside the UV atlas, and those that some view observes, as (R, R) images.

    Parameters
    ----------
    resolution : int
        Atlas size R.
    texel : ndarray, shape (T,), int
        Flat indices ``i * R + j`` of the atlas texels (observations' ``texels.npz``).
    observed : ndarray, shape (T,), bool
        Whether any view observes each texel.

    Returns
    -------
    inside, seen : ndarray, shape (R, R), bool
    """
    inside = np.zeros(resolution * resolution, bool)
    seen = np.zeros(resolution * resolution, bool)
    inside[texel] = True
    seen[texel[np.asarray(observed, bool)]] = True
    return inside.reshape(resolution, resolution), seen.reshape(resolution, resolution)


def error_scale(errors: Mapping[str, np.ndarray], seen: np.ndarray, quantile: float = 0.99) -> float:
    """One upper limit of the colour scale for every method's error map, so they compare.

    The ``quantile`` of the squared errors over observed texels of all methods
    (a few outliers would otherwise wash every map out); at least 1e-6.
    """
    values = np.concatenate([e[seen] for e in errors.values()]) if errors and seen.any() else np.zeros(1)
    return max(float(np.quantile(values, quantile)), 1e-6)


def capture_maps_figure(
    path: str | os.PathLike,
    truth: Mapping[str, np.ndarray] | None,
    estimates: Mapping[str, Mapping[str, np.ndarray]],
    entropy: np.ndarray,
    inside: np.ndarray,
    seen: np.ndarray,
    title: str,
) -> dict[str, float]:
    """Ground truth against each method's maps, with our entropy and each method's error.

    One row per SVBRDF (ground truth first, methods by display name), columns
    base colour (sRGB), roughness, metallic (grey, 0 black to 1 white), and a
    fourth map: our entropy (Turbo, 0 certain to 1 uncertain) in the
    ground-truth row, the per-texel squared parameter error (mean of the three
    groups, one shared scale) in every method's row. Every value scale sits in
    the first two rows (the parameters' under the ground truth, the entropy's
    beside it, the error's beside the first method's map), so a window that
    shows the figure's top shows them all, however many methods follow (the
    default run's 11 rows, 2,000 pixels, are taller than the report's window).
    Grey: outside the atlas; in the entropy and error maps also never observed
    (an unobserved texel's entropy is the maximum by definition, and its error
    is not scored).

    Parameters
    ----------
    path : path-like
        PNG destination.
    truth : mapping or None
        Ground-truth ``base_color`` (R, R, 3), ``roughness``, ``metallic`` (R, R);
        None for a real capture (no ground truth: no error maps).
    estimates : mapping of method name to SVBRDF mapping
        As ``truth``, in display order; names registered in :mod:`freqbrdf.methods`.
    entropy : ndarray, shape (R, R)
        Normalised entropy in [0, 1].
    inside, seen : ndarray, shape (R, R), bool
        From :func:`atlas_masks`.
    title : str
        Figure title.

    Returns
    -------
    dict
        Method name -> parameter MSE over observed texels (empty without ground
        truth), the numbers printed in the row labels.
    """
    fig, mse = draw_capture_maps(truth, estimates, entropy, inside, seen, title)
    save_figure(fig, path, dpi=100)
    return mse


def draw_capture_maps(
    truth: Mapping[str, np.ndarray] | None,
    estimates: Mapping[str, Mapping[str, np.ndarray]],
    entropy: np.ndarray,
    inside: np.ndarray,
    seen: np.ndarray,
    title: str,
) -> tuple[Figure, dict[str, float]]:
    """The figure of :func:`capture_maps_figure`, unsaved, and its MSE per method; the caller closes it."""
    plt = pyplot()
    errors = {m: parameter_error_map(truth, est) for m, est in estimates.items()} if truth is not None else {}
    vmax = error_scale(errors, seen)
    rows = [("ground truth", truth)] + list(estimates.items())
    fig, axes = plt.subplots(len(rows), 4, figsize=(4 * 2.1, len(rows) * 1.75 + 0.9), squeeze=False,
                             layout="constrained")
    grey_map = plt.get_cmap("gray").with_extremes(bad=GREY)
    turbo = plt.get_cmap("turbo").with_extremes(bad=GREY)
    magma = plt.get_cmap("magma").with_extremes(bad=GREY)
    mse = {}
    shown_entropy = shown_error = None
    for r, (name, svbrdf) in enumerate(rows):
        ax_base, ax_rough, ax_metal, ax_extra = axes[r]
        _draw_svbrdf(axes[r][:3], svbrdf, inside, grey_map)
        label = name if r == 0 else method_label(name)
        if r == 0:
            shown_entropy = ax_extra.imshow(np.where(seen, entropy, np.nan), cmap=turbo, vmin=0.0, vmax=1.0,
                                            interpolation="nearest")
        elif name in errors:
            mse[name] = float(errors[name][seen].mean()) if seen.any() else float("nan")
            shown_error = ax_extra.imshow(np.where(seen, errors[name], np.nan), cmap=magma, vmin=0.0, vmax=vmax,
                                          interpolation="nearest")
            label = f"{label}\nMSE {mse[name]:.3f}"
        else:
            ax_extra.text(0.5, 0.5, "no ground truth", ha="center", va="center", fontsize=8)
        ax_base.set_ylabel(label, fontsize=9)
    _title_columns(axes, ("base colour", "roughness", "metallic", "entropy (ours)"))
    if len(rows) > 1 and errors:
        axes[1, 3].set_title("squared error", fontsize=9)
    _parameter_scales(fig, axes, grey_map)
    if shown_entropy is not None:
        fig.colorbar(shown_entropy, ax=axes[0, 3], shrink=0.9, label="entropy")
    if shown_error is not None:
        # one shared scale for every method's row, as long as one row and level with the first
        fig.colorbar(shown_error, ax=axes[1:, 3].tolist(), shrink=0.9 / (len(rows) - 1), anchor=(0.0, 1.0),
                     panchor=(1.0, 1.0), label="squared error")
    fig.suptitle(title, fontsize=10)
    return fig, mse


def _title_columns(axes: np.ndarray, titles: Sequence[str]) -> None:
    """Titles over the first row of a grid of image axes (R, C), and no ticks anywhere."""
    for ax in axes.ravel():
        ax.set_xticks([])
        ax.set_yticks([])
    for ax, name in zip(axes[0], titles):
        ax.set_title(name, fontsize=9)


def _parameter_scales(fig, axes: np.ndarray, grey_map) -> None:
    """One value scale for each parameter column (0-2) of a maps grid, under its first row (the
    ground truth): base colour per channel (linear value, drawn sRGB-encoded as the maps are),
    roughness and metallic as drawn. Under the first row, not the last: a figure taller than
    the window then still shows them (they were cut off at the bottom of the report's view)."""
    from matplotlib.cm import ScalarMappable
    from matplotlib.colors import ListedColormap, Normalize

    unit = Normalize(0.0, 1.0)
    base_scale = ListedColormap(np.repeat(to_srgb(np.linspace(0.0, 1.0, 256))[:, None], 3, axis=1))
    for c, (cmap, label) in enumerate(((base_scale, "base colour (linear)"),
                                       (grey_map, "roughness"), (grey_map, "metallic"))):
        # the space a bar takes is a fraction of the row's height
        fig.colorbar(ScalarMappable(unit, cmap), ax=axes[0, c], location="bottom", shrink=0.9,
                     aspect=15, fraction=0.15, label=label)


def _draw_svbrdf(axes, svbrdf: Mapping[str, np.ndarray] | None, inside: np.ndarray, grey_map) -> None:
    """Base colour (sRGB), roughness and metallic of one SVBRDF on three axes, grey outside the atlas."""
    if svbrdf is None:
        for ax in axes:
            ax.text(0.5, 0.5, "no ground truth\n(real capture)", ha="center", va="center", fontsize=8)
        return
    base = to_srgb(svbrdf["base_color"])
    base[~inside] = float(GREY)
    axes[0].imshow(base, interpolation="nearest")
    for ax, name in zip(axes[1:], ("roughness", "metallic")):
        ax.imshow(np.where(inside, svbrdf[name], np.nan), cmap=grey_map, vmin=0.0, vmax=1.0, interpolation="nearest")


def relight_figure(
    path: str | os.PathLike,
    references: Mapping[str, tuple[np.ndarray, np.ndarray]],
    relit: Mapping[str, Mapping[str, np.ndarray]],
    title: str,
    scoring: HdrScoring = STANFORD_ORB,
) -> dict[tuple[str, str], float]:
    """Relit renders of one view beside its ground-truth render, each with its PSNR-H,
    and under each render the squared error that PSNR-H averages.

    Two rows per relighting environment: the renders (tone-mapped alike), then
    the per-pixel squared difference of the images :func:`freqbrdf.report.relight_metrics.psnr_h`
    compares (:func:`freqbrdf.report.relight_metrics.hdr_pair`; mean of the channels, one
    scale per environment; grey outside the scored pixels).

    Parameters
    ----------
    path : path-like
        PNG destination.
    references : mapping of relight_env to (image, mask)
        Ground-truth render of the view, ndarray (H, W, 3) of linear radiance,
        and the pixels scored, ndarray (H, W) of bool.
    relit : mapping of relight_env to mapping of method name to ndarray, shape (H, W, 3)
        The same view rendered with each method's textures, in display order.
    title : str
        Figure title.
    scoring : HdrScoring
        As :func:`freqbrdf.report.relight_metrics.psnr_h` (config ``evaluate.hdr_*``).

    Returns
    -------
    dict
        (relight_env, method) -> PSNR-H of this view, the numbers printed on the renders.
    """
    plt = pyplot()
    methods = list(dict.fromkeys(m for per_env in relit.values() for m in per_env))
    envs = list(references)
    if not envs:
        fig, ax = plt.subplots(figsize=(5, 1.2))
        ax.text(0.5, 0.5, "no relighting renders for this capture", ha="center", va="center")
        ax.set_axis_off()
        fig.suptitle(title, fontsize=10)
        save_figure(fig, path, dpi=100)
        return {}
    cols = 1 + len(methods)
    fig, axes = plt.subplots(2 * len(envs), cols, figsize=(cols * 1.9, len(envs) * 3.6 + 0.4), squeeze=False,
                             layout="constrained")
    magma = plt.get_cmap("magma").with_extremes(bad=GREY)
    scores = {}
    for r, env in enumerate(envs):
        per_env = _relight_rows(fig, axes[2 * r], axes[2 * r + 1], env, *references[env], relit.get(env, {}),
                                methods, magma, scoring)
        scores.update({(env, m): v for m, v in per_env.items()})
    _title_columns(axes, ("ground truth", *(method_label(m) for m in methods)))
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path, dpi=100)
    return scores


def _relight_rows(fig, ax_images: np.ndarray, ax_errors: np.ndarray, env: str, reference: np.ndarray,
                  mask: np.ndarray, relit: Mapping[str, np.ndarray], methods: Sequence[str], magma,
                  scoring: HdrScoring) -> dict[str, float]:
    """One environment's two rows of `relight_figure`: the ground truth and each method's render
    (``relit``: method -> (H, W, 3)), under them the squared errors; returns method -> PSNR-H."""
    scores = {}
    ax_images[0].imshow(tonemap(reference))
    ax_images[0].set_ylabel(f"relit under\n{env}", fontsize=9)
    ax_errors[0].set_axis_off()
    ax_errors[0].text(0.5, 0.5, "below each render:\nthe squared error\nof the images\nPSNR-H compares",
                      ha="center", va="center", fontsize=8)
    errors = {}
    for c, method in enumerate(methods, start=1):
        image = relit.get(method)
        if image is None:  # e.g. a merge, which has seen every capture environment
            for ax in (ax_images[c], ax_errors[c]):
                ax.text(0.5, 0.5, f"not relit\nunder {env}", ha="center", va="center", fontsize=8)
            continue
        ax_images[c].imshow(tonemap(image))
        p, q = hdr_pair(image, reference, mask, scoring)
        errors[method] = ((p - q) ** 2).mean(axis=2)
        scores[method] = psnr_h(image, reference, mask, scoring)
        ax_images[c].text(0.03, 0.97, f"PSNR-H {scores[method]:.2f}", transform=ax_images[c].transAxes,
                          ha="left", va="top", fontsize=7, color="white",
                          bbox={"facecolor": "black", "alpha": 0.6, "pad": 1.5, "linewidth": 0})
    vmax = error_scale(errors, mask)
    shown = None
    for c, method in enumerate(methods, start=1):
        if method in errors:
            shown = ax_errors[c].imshow(np.where(mask, errors[method], np.nan), cmap=magma, vmin=0.0, vmax=vmax,
                                        interpolation="nearest")
    if shown is not None:
        fig.colorbar(shown, ax=ax_errors[1:].tolist(), shrink=0.8, label="squared error")
    return scores


def convergence_figure(
    path: str | os.PathLike,
    curves: Mapping[str, tuple[np.ndarray, np.ndarray]],
    points: Mapping[str, tuple[float, float]],
    title: str,
    timing: str,
) -> None:
    """Parameter MSE against time: the differentiable-rendering runs as curves, the
    frequency-domain methods as points at their time from the capture.

    Parameters
    ----------
    path : path-like
        PNG destination.
    curves : mapping of method to (elapsed_s (N,), mse (N,))
        Convergence of each run, times from the capture (a fine-tuning run starts where
        the method it fine-tunes ends).
    points : mapping of method to (seconds, mse)
        One-shot methods.
    title : str
        Figure title.
    timing : str
        Where the times were taken (`freqbrdf.util.mitsuba_setup.timing_note`).
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 3.6), layout="constrained")
    for method, (t, mse) in curves.items():
        ax.plot(np.maximum(t, 1e-2), mse, marker="o", markersize=3, label=method_label(method))
    for method, (t, mse) in points.items():
        ax.scatter([max(t, 1e-2)], [mse], marker="*", s=90, zorder=3, label=method_label(method))
        ax.axhline(mse, color="grey", linewidth=0.5, linestyle=":")
    ax.set_xscale("log")
    ax.set_xlabel(f"seconds from the capture (Mitsuba: optimisation only)\n{timing}", fontsize=9)
    ax.set_ylabel("parameter MSE (observed texels)")
    ax.legend(fontsize=7, ncol=2)
    ax.set_title(title, fontsize=9)
    save_figure(fig, path, dpi=100)


def regulariser_figure(path: str | os.PathLike, ratios: Mapping[str, np.ndarray], title: str) -> None:
    """Per fit option, the error of the fitted log(S_B / S_L) per degree over texels (paper Fig. 3).

    Parameters
    ----------
    path : path-like
        PNG destination.
    ratios : mapping of option to ndarray, shape (T, lmax)
        The error of each texel at degrees 1..lmax (NaN ignored); 0 is exact.
    title : str
        Figure title.
    """
    plt = pyplot()
    fig, ax = plt.subplots(figsize=(6.0, 3.6), layout="constrained")
    for option, ratio in ratios.items():
        degrees = np.arange(1, ratio.shape[1] + 1)
        q25, q50, q75 = np.nanpercentile(ratio, [25, 50, 75], axis=0)
        ax.plot(degrees, q50, marker="o", markersize=3, label=option)
        ax.fill_between(degrees, q25, q75, alpha=0.2)
    ax.axhline(0.0, color="black", linewidth=0.6)
    ax.set_xlabel("SH degree l")
    ax.set_ylabel("error of log(S_B / S_L)")
    ax.legend(fontsize=8, title="fit (median, quartiles over texels)", title_fontsize=7)
    ax.set_title(title, fontsize=9)
    save_figure(fig, path, dpi=100)


def views_figure(path: str | os.PathLike, table: pd.DataFrame, title: str) -> None:
    """Parameter MSE and mean entropy against the number of training views (paper Fig. 8).

    Parameters
    ----------
    path : path-like
        PNG destination.
    table : DataFrame
        Columns ``views``, ``mse_average``, ``mean_entropy``, one row per subset: the mean per
        count is drawn as a line, each subset as a point.
    title : str
        Figure title.
    """
    plt = pyplot()
    means = table.groupby("views", as_index=False)[["mse_average", "mean_entropy"]].mean()
    fig, ax = plt.subplots(figsize=(5.5, 3.4), layout="constrained")
    ax.plot(means["views"], means["mse_average"], marker="o", color="tab:blue", label="parameter MSE")
    ax.scatter(table["views"], table["mse_average"], s=8, color="tab:blue", alpha=0.5)
    ax.set_xlabel("training views")
    ax.set_ylabel("parameter MSE (freq)", color="tab:blue")
    twin = ax.twinx()
    twin.plot(means["views"], means["mean_entropy"], marker="s", color="tab:red", label="mean entropy")
    twin.scatter(table["views"], table["mean_entropy"], s=8, color="tab:red", alpha=0.5)
    twin.set_ylabel("mean entropy", color="tab:red")
    ax.set_title(title, fontsize=9)
    save_figure(fig, path, dpi=100)


_AGREEMENT_PANELS = (("angular", "angular (our forward model)"), ("spectrum", "power spectrum"),
                     ("mitsuba_reduced", "Mitsuba, half the paths"))


def entropy_agreement_figure(path: str | os.PathLike, entropy: Mapping[str, np.ndarray],
                             pearson: Mapping[str, float], title: str) -> None:
    """Each cheap entropy of the same texels against the Mitsuba grid's (paper Table 3).

    Parameters
    ----------
    entropy : mapping of str to ndarray
        ``mitsuba``, ``angular``, ``spectrum`` and ``mitsuba_reduced``, each shape ``(S,)`` in [0, 1].
    pearson : mapping of str to float
        ``pearson_<name>`` against ``mitsuba``, printed in each panel.
    title : str
        Figure title.
    """
    plt = pyplot()
    fig, axes = plt.subplots(1, len(_AGREEMENT_PANELS), figsize=(10.5, 3.6), layout="constrained", sharey=True)
    for ax, (name, label) in zip(axes, _AGREEMENT_PANELS):
        ax.scatter(entropy[name], entropy["mitsuba"], s=4, alpha=0.5, color="tab:blue", linewidths=0)
        ax.plot([0, 1], [0, 1], color="0.6", linewidth=0.8)
        ax.set(xlim=(0, 1), ylim=(0, 1), xlabel=f"entropy: {label}", aspect="equal")
        ax.set_title(f"Pearson {pearson[f'pearson_{name}']:.2f}", fontsize=9)
    axes[0].set_ylabel("entropy: Mitsuba grid")
    fig.suptitle(title, fontsize=10)
    save_figure(fig, path, dpi=100)


VIEW_SELECTION_STYLES = {"entropy": ("tab:red", "o", "entropy-guided"), "random": ("tab:grey", "s", "random"),
                         "even": ("tab:blue", "^", "evenly spread"),
                         "posterior": ("tab:green", "D", "posterior-guided")}


def view_selection_figure(path: str | os.PathLike, table: pd.DataFrame) -> None:
    """``freq``'s parameter MSE against the number of views per selection strategy, one panel per capture.

    Parameters
    ----------
    path : path-like
        PNG destination.
    table : DataFrame
        Columns ``object``, ``env``, ``strategy`` (keys of `VIEW_SELECTION_STYLES`), ``views``,
        ``mse_average``; random strategies once per repetition (drawn as mean and range).
    """
    plt = pyplot()
    captures = list(dict.fromkeys(zip(table["object"], table["env"])))
    fig, axes = plt.subplots(1, len(captures), figsize=(3.2 * len(captures) + 0.6, 3.0), layout="constrained",
                             squeeze=False)
    for ax, (o, e) in zip(axes[0], captures):
        rows = table[(table["object"] == o) & (table["env"] == e)]
        for strategy, (colour, marker, label) in VIEW_SELECTION_STYLES.items():
            mse = rows[rows["strategy"] == strategy].groupby("views")["mse_average"]
            if not len(mse):
                continue
            mean = mse.mean()
            ax.plot(mean.index, mean.values, marker=marker, color=colour, label=label)
            if mse.size().max() > 1:
                ax.fill_between(mean.index, mse.min().values, mse.max().values, color=colour, alpha=0.2, lw=0)
        ax.set_title(f"{o} / {e}", fontsize=9)
        ax.set_xlabel("training views k")
    axes[0, 0].set_ylabel("parameter MSE (freq)")
    axes[0, -1].legend(fontsize=8)
    save_figure(fig, path, dpi=100)


def stress_figure(path: str | os.PathLike, rows: list[Mapping[str, object]], method: str) -> None:
    """One row per stress capture (rule stress_tables): its entropy, a method's per-texel squared
    parameter error and, for an occluded capture, the share of light the occluder blocks, on the atlas.

    Parameters
    ----------
    path : path-like
        PNG destination.
    rows : list of mapping
        ``name`` (str), ``resolution`` (atlas size R), ``texels`` (T,) flat atlas indices of the
        observed texels, and per texel ``entropy``, ``error`` and ``blocked`` (T,) (None: no occluder).
    method : str
        Display name of the method whose error is shown.
    """
    plt = pyplot()
    if not rows:
        fig, ax = plt.subplots(figsize=(4, 1))
        ax.axis("off")
        ax.text(0.5, 0.5, "no stress captures in this configuration", ha="center", va="center")
        save_figure(fig, path)
        return
    fig, axes = plt.subplots(len(rows), 3, figsize=(10, 3.2 * len(rows)), squeeze=False)
    cmap = plt.get_cmap("turbo").with_extremes(bad=GREY)
    pooled = np.concatenate([np.asarray(r["error"]) for r in rows])
    vmax = error_scale({method: pooled}, np.ones(pooled.shape, bool))
    titles = ["entropy", f"{method}: squared error", "light the occluder blocks"]
    for r, (axs, row) in enumerate(zip(axes, rows)):
        panels = [(row["entropy"], 1.0), (row["error"], vmax), (row["blocked"], 1.0)]
        axs[0].set_ylabel(row["name"], fontsize=9)
        for ax, title, (values, top) in zip(axs, titles, panels):
            ax.set_xticks([])
            ax.set_yticks([])
            if values is None:
                ax.set_frame_on(False)
                continue
            shown = ax.imshow(atlas_image(row["resolution"], row["texels"], values), cmap=cmap, vmin=0.0,
                              vmax=top, interpolation="nearest")
            if r == 0 or title == titles[2]:
                ax.set_title(title, fontsize=9)
            fig.colorbar(shown, ax=ax, fraction=0.046)
    save_figure(fig, path)


SPARSIFICATION_STYLE = {"entropy": ("C3", "-"), "views": ("C0", "-"), "light": ("C2", "-"),
                        "random": ("0.5", ":"), "oracle": ("k", "--")}
"""Colour and line of each uncertainty map's sparsification curve (the others are not drawn)."""


def sparsification_figure(path: str | os.PathLike, curves: pd.DataFrame, method: str, error: str = "parameter") -> None:
    """Sparsification curves of one method, one panel per capture.

    Parameters
    ----------
    curves : DataFrame
        ``object, env, poses, method, error, map, fraction, value`` (rule metrics' sparsification.tsv).
    method, error : str
        Which method's curves, for which per-texel error.
    """
    rows = curves[(curves.method == method) & (curves.error == error)]
    captures = list(dict.fromkeys(zip(rows.object, rows.env, rows.poses)))
    if not captures:
        raise ValueError(f"no sparsification curves of method {method!r} for the {error} error")
    plt = pyplot()
    fig, axes = plt.subplots(1, len(captures), figsize=(3.2 * len(captures), 3.0), squeeze=False, sharey=True)
    for ax, (obj, env, poses) in zip(axes[0], captures):
        own = rows[(rows.object == obj) & (rows.env == env) & (rows.poses == poses)]
        for name, (colour, line) in SPARSIFICATION_STYLE.items():
            curve = own[own["map"] == name]
            ax.plot(curve.fraction, curve.value, color=colour, linestyle=line, label=name)
        ax.set_title(f"{obj} / {env}")
        ax.set_xlabel("fraction of texels removed")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel(f"mean {error} error of the rest (relative)")
    axes[0, -1].legend(fontsize=8)
    save_figure(fig, path)


def reliability_figure(path: str | os.PathLike, table: pd.DataFrame, method: str) -> None:
    """Reliability diagram of a method's posterior: observed against nominal coverage of its
    central intervals, one line per capture, one panel per parameter (the diagonal: calibrated).

    Parameters
    ----------
    table : DataFrame
        ``object, env, poses, method, parameter, level, coverage`` (rule metrics' reliability.tsv).
    method : str
        Whose posterior.
    """
    rows = table[table.method == method]
    if rows.empty:
        raise ValueError(f"no reliability rows of method {method!r}")
    parameters = list(dict.fromkeys(rows.parameter))
    plt = pyplot()
    fig, axes = plt.subplots(1, len(parameters), figsize=(2.8 * len(parameters), 3.0), squeeze=False,
                             sharey=True, layout="constrained")
    for ax, parameter in zip(axes[0], parameters):
        own = rows[rows.parameter == parameter]
        for (obj, env), curve in own.groupby(["object", "env"], sort=False):
            ax.plot(curve.level, curve.coverage, marker="o", markersize=3, label=f"{obj} / {env}")
        ax.plot([0, 1], [0, 1], color="grey", linestyle="--", linewidth=0.8)
        ax.set(xlim=(0.45, 1.0), ylim=(min(0.45, float(rows.coverage.min()) - 0.02), 1.0), title=parameter,
               xlabel="nominal coverage")
        ax.grid(alpha=0.3)
    axes[0, 0].set_ylabel("observed coverage")
    axes[0, -1].legend(fontsize=7)
    save_figure(fig, path)
