"""Frequency-domain analysis of per-texel observations (METHOD.md sections 3, 4, 6).

The stage turns the per-texel observations (``radiance`` B, ``weight``,
``wo_local``, ``incoming`` L; see README "Observations") into

1. SH coefficients of B and L from sparse, irregular, weighted samples
   (`fit_sh`, regularised least squares),
2. their power spectra (`spectra`),
3. the spectrum-only estimate of the specular lobe (K_s, alpha) on a grid and
   the normalised entropy of its likelihood (`spectrum_search`),
4. the irradiance (`irradiance_at_normals`, `irradiance_from_coeffs`), the
   diffuse albedo from degree 0 (`diffuse_albedo`) and a mapping to the
   principled parameters (`principled_from_lobes`).

Parametrisation
---------------
B and L are both fitted as functions of the local mirror direction
``w_r = (-x, -y, z)`` of ``wo_local`` (`mirror_directions`), fed to
:func:`freqbrdf.sh.real_sh` as if the texel frame were the SH frame. The SH
polar axis is then the texel's local +y (a tangent direction), not the normal
(+z). This is harmless for the spectra: a rotation of the sample directions
rotates each degree's coefficients by an orthogonal matrix, the regulariser
``W = diag(e^l)`` is constant within a degree, so the regularised fit is
rotation-equivariant and the power spectra are rotation invariant. The only
place the normal matters is the irradiance (degree 0 analysis), where
`clamped_cosine_sh` evaluates the clamped-cosine kernel about local +z
explicitly.

Normalisation of the objective D
--------------------------------
Both spectra are divided by the light's total power up to lmax,
``P_L = sum_{l=0..lmax} S_L(l)`` (per texel and channel; by Parseval the
integral of the fitted L^2 over the sphere), before
``D = sum_{l=1..lmax} (S_B(l) - K_s^2 exp(-2 (alpha l)^2) S_L(l))^2`` is formed.
Then

- D is dimensionless and invariant to the light's intensity (B and L scale
  together), so ``sigma`` means the same under bright and dim light;
- the normalised light spectrum at l >= 1 is the fraction of the light's
  energy that varies with direction, so a low-contrast or low-frequency light
  gives small normalised spectra, small differences of D over the grid and a
  flat likelihood (high entropy), as paper Fig. 4 (middle) expects;
- a texel with low K_s keeps a small normalised S_B (at most K_s^2 times the
  light's), so its likelihood is flat as well (Fig. 4, bottom).

Dividing by the power at degrees 1..lmax only (excluding l = 0) was rejected:
it inflates the faint directional part of a nearly constant light to unit
power, so a smooth light (a broad lobe over an ambient term, power at l <= 2
only) comes out more certain than a point light (entropy 0.13 instead of 0.69
on the paper's 10 x 10 grid at lmax 8; point light 0.29 either way). Where the light has no power at l >= 1 (more than
``min_relative_power`` of ``P_L``), e.g. a constant or zero light, nothing
about (K_s, alpha) is identifiable: the channel is flagged and its entropy is
exactly 1.

All functions are pure; arrays in, arrays out.
"""

from __future__ import annotations

from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from .envmaps import LUMINANCE
from .sh import fibonacci_hemisphere, n_coeffs, power_spectrum, real_sh, sh_degrees

__all__ = [
    "REGULARISERS",
    "COMBINE_MODES",
    "NORMALISATIONS",
    "R0_DIELECTRIC",
    "mirror_directions",
    "observed_texels",
    "regulariser_diagonal",
    "fit_sh",
    "zero_pad_lower_hemisphere",
    "spectra",
    "default_grid",
    "residual_width",
    "model_filters",
    "normalised_spectra",
    "spectrum_objective",
    "grid_entropy",
    "combine_entropy",
    "SpectrumSearch",
    "spectrum_search",
    "clamped_cosine_sh",
    "irradiance_from_coeffs",
    "irradiance_at_normals",
    "diffuse_albedo",
    "lobes_from_principled",
    "principled_from_lobes",
]

REGULARISERS = ("exp", "constant", "none")
COMBINE_MODES = ("min", "luminance")
NORMALISATIONS = ("light", "reference")
R0_DIELECTRIC = 0.04  # Disney/Mitsuba principled: specular reflectance at normal incidence of a dielectric
_NONE_RIDGE = 1e-9  # relative ridge of regulariser "none" (see fit_sh)
_FIT_CHUNK_VALUES = 1 << 22  # float64 values of one chunk's design matrix (32 MB)
_LOCAL_NORMAL = (0.0, 0.0, 1.0)


# --------------------------------------------------------------------------
# validation helpers
# --------------------------------------------------------------------------
def _check_int(value: object, name: str, minimum: int) -> int:
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, np.integer)):
        raise TypeError(f"{name} must be an int, got {type(value).__name__} {value!r}")
    if int(value) < minimum:
        raise ValueError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def _check_positive(value: float, name: str) -> float:
    value = float(value)
    if not (np.isfinite(value) and value > 0.0):
        raise ValueError(f"{name} must be a finite number > 0, got {value!r}")
    return value


def _check_choice(value: str, name: str, choices: tuple[str, ...]) -> str:
    if value not in choices:
        raise ValueError(f"{name} must be one of {choices}, got {value!r}")
    return value


def _check_shape(a: np.ndarray, name: str, shape: tuple[int | None, ...]) -> None:
    """``shape`` entries of None match any size."""
    if a.ndim != len(shape) or any(s is not None and s != n for s, n in zip(shape, a.shape)):
        want = "(" + ", ".join("*" if s is None else str(s) for s in shape) + ")"
        raise ValueError(f"{name} must have shape {want}, got shape {a.shape}")


def _lmax_of(n: int, name: str) -> int:
    lmax = int(round(np.sqrt(n))) - 1
    if n < 1 or (lmax + 1) ** 2 != n:
        raise ValueError(f"{name} has {n} coefficients, which is not (lmax + 1)**2 for any lmax >= 0")
    return lmax


# --------------------------------------------------------------------------
# directions and observations
# --------------------------------------------------------------------------
def mirror_directions(wo_local: np.ndarray) -> np.ndarray:
    """Local mirror directions ``w_r = (-x, -y, z)`` of directions to the camera.

    Parameters
    ----------
    wo_local : numpy.ndarray
        Shape ``(..., 3)``: unit directions to the camera in the texel frame
        (x tangent, y bitangent, z normal).

    Returns
    -------
    numpy.ndarray
        Shape ``(..., 3)``, float64: the reflection of ``wo_local`` about the normal.
    """
    w = np.asarray(wo_local, dtype=np.float64)
    if w.ndim < 1 or w.shape[-1] != 3:
        raise ValueError(f"wo_local must have shape (..., 3), got shape {w.shape}")
    return w * np.array([-1.0, -1.0, 1.0])


def observed_texels(weight: np.ndarray) -> np.ndarray:
    """Texels that at least one view observes.

    Parameters
    ----------
    weight : numpy.ndarray
        Shape ``(T, K)``, sample weights (0 where not observed).

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``, bool.
    """
    w = np.asarray(weight)
    _check_shape(w, "weight", (None, None))
    return (w > 0).any(axis=1)


# --------------------------------------------------------------------------
# regularised SH fitting
# --------------------------------------------------------------------------
def regulariser_diagonal(lmax: int, regulariser: str, penalise_dc: bool = True) -> np.ndarray:
    """Diagonal of the regulariser matrix W.

    Parameters
    ----------
    lmax : int
        Maximum degree.
    regulariser : {"exp", "constant", "none"}
        ``exp``: ``W_ii = e^l`` (paper); ``constant``: 1; ``none``: 0.
    penalise_dc : bool
        False sets ``W_00 = 0`` (see `fit_sh`).

    Returns
    -------
    numpy.ndarray
        Shape ``((lmax+1)**2,)``, float64.
    """
    lmax = _check_int(lmax, "lmax", 0)
    _check_choice(regulariser, "regulariser", REGULARISERS)
    degrees = sh_degrees(lmax).astype(np.float64)
    if regulariser == "exp":
        w = np.exp(degrees)
    elif regulariser == "constant":
        w = np.ones_like(degrees)
    else:
        w = np.zeros_like(degrees)
    if not penalise_dc:
        w[0] = 0.0
    return w


def _fit_chunk(
    d: np.ndarray, f: np.ndarray, w: np.ndarray, lmax: int, reg: np.ndarray, lam: float, solver: str
) -> np.ndarray:
    """Solve the regularised normal equations of one chunk of texels; see `fit_sh`."""
    valid = w > 0.0
    # Unobserved samples may carry zero-length directions or non-finite values;
    # replace them so they cannot turn the (zero-weighted) products into NaN.
    d = np.where(valid[..., None], d, np.asarray(_LOCAL_NORMAL))
    f = np.where(valid[..., None], f, 0.0)
    w = np.where(valid, w, 0.0)
    y = real_sh(d, lmax)  # (t, K, n)
    if solver == "dual":
        return _dual_solve(y, f, w, reg, lam)
    yw_t = (y * w[..., None]).transpose(0, 2, 1)  # (t, n, K)
    a = yw_t @ y  # (t, n, n)
    rhs = yw_t @ f  # (t, n, C)
    diag = np.einsum("tii->ti", a)  # writable view of the diagonals
    if solver == "ridge":
        # scale-free ridge relative to the mean diagonal: it only settles the
        # directions the samples do not determine (near minimum-norm solution)
        diag += _NONE_RIDGE * diag.mean(axis=1, keepdims=True)
    else:
        diag += lam * reg
    empty = ~valid.any(axis=1)
    if empty.any():
        a[empty] = np.eye(a.shape[1])
        rhs[empty] = 0.0
    return np.linalg.solve(a, rhs)


def _dual_solve(y: np.ndarray, f: np.ndarray, w: np.ndarray, reg: np.ndarray, lam: float) -> np.ndarray:
    """K x K form of the regularised fit of one chunk; see `fit_sh`.

    Push-through identity: with ``Z = S^1/2 Y`` and ``g = S^1/2 f``,
    ``(Z^T Z + lam W)^-1 Z^T g = W^-1 Z^T (Z W^-1 Z^T + lam I)^-1 g``. An
    unpenalised DC (``W_00 = 0``) is eliminated exactly: for given other
    coefficients it is the weighted mean of the residual, so they solve the
    same problem projected by ``P = I - q q^T`` (``q`` the unit DC column of Z).
    """
    sw = np.sqrt(w)[..., None]
    z = y * sw  # (t, K, n)
    g = f * sw  # (t, K, C)
    diag = np.arange(z.shape[1])
    if reg[0] > 0.0:
        zw = z / reg  # Z W^-1
        gram = zw @ z.transpose(0, 2, 1)  # (t, K, K)
        gram[:, diag, diag] += lam
        return zw.transpose(0, 2, 1) @ np.linalg.solve(gram, g)
    z0 = z[..., 0]  # (t, K)
    norm = np.sqrt(np.einsum("tk,tk->t", z0, z0))
    q = z0 / np.where(norm > 0, norm, 1.0)[:, None]  # 0 for texels without samples
    zac = z[..., 1:]
    zw = zac / reg[1:]
    gram = zw @ zac.transpose(0, 2, 1)
    gq = np.einsum("tij,tj->ti", gram, q)
    qgq = np.einsum("ti,ti->t", q, gq)
    # P G P = G - q (Gq)^T - (Gq) q^T + (q^T G q) q q^T
    gram -= q[:, :, None] * gq[:, None, :] + gq[:, :, None] * q[:, None, :]
    gram += qgq[:, None, None] * (q[:, :, None] * q[:, None, :])
    gram[:, diag, diag] += lam
    pg = g - q[..., None] * np.einsum("tk,tkc->tc", q, g)[:, None, :]
    beta = np.linalg.solve(gram, pg)  # orthogonal to q, so P beta = beta
    c_ac = zw.transpose(0, 2, 1) @ beta  # (t, n - 1, C)
    residual = g - zac @ c_ac
    c0 = np.einsum("tk,tkc->tc", q, residual) / np.where(norm > 0, norm, 1.0)[:, None]
    return np.concatenate([c0[:, None, :], c_ac], axis=1)


def fit_sh(
    directions: np.ndarray,
    values: np.ndarray,
    weights: np.ndarray,
    lmax: int,
    regulariser: str = "exp",
    lam: float = 1e-3,
    chunk: int | None = None,
    solver: str = "auto",
    workers: int = 1,
    penalise_dc: bool = True,
) -> np.ndarray:
    """Per-texel weighted, regularised least-squares SH fit.

    Solves ``(Y^T S Y + lam W) c = Y^T S f`` for every texel, with
    ``S = diag(weights)`` and ``W`` from `regulariser_diagonal`. ``lam`` is
    absolute (not scaled by the number of samples), as in the authors' code.
    With ``regulariser="none"`` a ridge of ``1e-9`` times the mean diagonal of
    ``Y^T S Y`` replaces ``lam W`` (``lam`` is ignored), so rank-deficient
    systems (fewer samples than coefficients, or a hemisphere only) return a
    near minimum-norm solution instead of blowing up.

    ``penalise_dc=False`` sets ``W_00 = 0`` (not in the paper): the constant
    then costs nothing, so constant data are fitted exactly by a constant.
    With the paper's ``W_00 = 1`` and fewer samples than coefficients, the
    smoothest interpolant of constant data is NOT constant (its DC is 0.67
    sqrt(4 pi) at the median texel of the 24-view sphere/studio capture), so
    a diffuse texel's constant radiance leaks into degrees >= 1, where the
    spectrum search reads it as specular reflection (median K_s of the
    dielectric texels 0.75 instead of 0.125 without the DC penalty).

    For ``exp`` and ``constant`` the same solution is also
    ``W^-1 Z^T (Z W^-1 Z^T + lam I)^-1 g`` with ``Z = S^1/2 Y``, ``g = S^1/2 f``
    (push-through identity), a K x K system per texel: cheaper when there are
    fewer samples than coefficients (24 views at lmax 6: 24 vs 49).

    Texels with no sample of positive weight get zero coefficients. Samples
    of zero weight are ignored entirely (their directions and values may be
    anything, even NaN); samples of positive weight need finite values and
    finite, non-zero directions (normalised internally). Fit B and L of the same texels in ONE call by
    concatenating their channels: they share directions and weights, hence
    the normal matrix, and the cost is almost that of one fit.

    Parameters
    ----------
    directions : numpy.ndarray
        Shape ``(T, K, 3)``, unit sample directions (e.g. `mirror_directions`).
    values : numpy.ndarray
        Shape ``(T, K, C)``, sampled function (e.g. radiance).
    weights : numpy.ndarray
        Shape ``(T, K)``, sample weights ``>= 0`` (e.g. cos theta_o, 0 if unobserved).
    lmax : int
        Maximum SH degree.
    regulariser : {"exp", "constant", "none"}
        Regulariser matrix W.
    lam : float
        Regularisation weight, ``> 0`` (ignored for ``none``; use ``none`` for
        an unregularised fit).
    chunk : int, optional
        Texels solved at once (bounds memory); default keeps one chunk's design
        matrix near 32 MB.
    solver : {"auto", "primal", "dual"}
        ``primal``: the n x n normal equations; ``dual``: the K x K form (not
        for ``none``); ``auto``: dual when allowed and ``K < n``. Both give
        the same coefficients up to rounding.
    workers : int
        Threads solving chunks concurrently (numpy releases the GIL in the
        batched products and solves; 2 threads run about 1.7x faster).
    penalise_dc : bool
        Regularise degree 0 as well (paper); see above.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, (lmax+1)**2, C)``, float64, l-major coefficient axis; same
        scale as :func:`freqbrdf.sh.project_equirect` of the same function.
    """
    d = np.asarray(directions)
    f = np.asarray(values)
    w = np.asarray(weights)
    _check_shape(d, "directions", (None, None, 3))
    _check_shape(f, "values", (d.shape[0], d.shape[1], None))
    _check_shape(w, "weights", (d.shape[0], d.shape[1]))
    lmax = _check_int(lmax, "lmax", 0)
    _check_choice(regulariser, "regulariser", REGULARISERS)
    lam = float(lam)
    if regulariser != "none" and not (np.isfinite(lam) and lam > 0.0):
        raise ValueError(f"lam must be a finite number > 0 for regulariser {regulariser!r}, got {lam!r}")
    w64 = w.astype(np.float64)
    if not np.all(np.isfinite(w64)) or (w64 < 0).any():
        bad = w64[~(np.isfinite(w64) & (w64 >= 0))][0]
        raise ValueError(f"weights must be finite and >= 0, got {bad!r}")
    used = w64 > 0
    bad_value = used & ~np.isfinite(f).all(axis=2)
    if bad_value.any():
        t, k = np.argwhere(bad_value)[0]
        raise ValueError(f"values must be finite where weights > 0, got {f[t, k]!r} at texel {t}, sample {k}")
    norms = np.linalg.norm(d, axis=2)
    bad_dir = used & ~(np.isfinite(norms) & (norms > 0))
    if bad_dir.any():
        t, k = np.argwhere(bad_dir)[0]
        raise ValueError(
            f"directions must be finite and non-zero where weights > 0, got {d[t, k]!r} at texel {t}, sample {k}"
        )
    n_tex, n_obs = w.shape
    n = n_coeffs(lmax)
    if chunk is None:
        chunk = max(1, _FIT_CHUNK_VALUES // max(1, n * (n_obs + n)))
    chunk = _check_int(chunk, "chunk", 1)
    _check_choice(solver, "solver", ("auto", "primal", "dual"))
    dual_ok = regulariser != "none"
    if solver == "dual" and not dual_ok:
        raise ValueError("solver='dual' needs regulariser 'exp' or 'constant', got 'none'")
    if regulariser == "none":
        method = "ridge"
    elif solver == "dual" or (solver == "auto" and dual_ok and n_obs < n):
        method = "dual"
    else:
        method = "primal"
    reg = regulariser_diagonal(lmax, regulariser, bool(penalise_dc))
    workers = _check_int(workers, "workers", 1)
    out = np.zeros((n_tex, n, f.shape[2]))

    def solve(start: int) -> None:
        stop = min(n_tex, start + chunk)
        out[start:stop] = _fit_chunk(
            d[start:stop].astype(np.float64),
            f[start:stop].astype(np.float64),
            w64[start:stop],
            lmax,
            reg,
            lam,
            method,
        )

    starts = range(0, n_tex, chunk)
    if workers == 1 or len(starts) == 1:
        for start in starts:
            solve(start)
    else:
        # chunks write disjoint slices of `out`, so threads need no locking
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(solve, starts))
    return out


def _lower_hemisphere_points(n: int) -> np.ndarray:
    """Fibonacci points on the local lower (-z) hemisphere, (n, 3)."""
    p = fibonacci_hemisphere(n)  # about +Y
    return np.stack([p[:, 0], p[:, 2], -p[:, 1]], axis=-1)  # rotation taking +Y to -z


def zero_pad_lower_hemisphere(
    directions: np.ndarray, values: np.ndarray, weights: np.ndarray, n_pad: int, pad_weight: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Append samples of value 0 on the local lower hemisphere (paper Fig. 3 baseline).

    Parameters
    ----------
    directions, values, weights : numpy.ndarray
        Shapes ``(T, K, 3)``, ``(T, K, C)``, ``(T, K)`` as for `fit_sh`.
    n_pad : int
        Number of Fibonacci directions added on ``z < 0`` (same for every texel).
    pad_weight : float
        Weight of the added samples.

    Returns
    -------
    tuple of numpy.ndarray
        Directions ``(T, K + n_pad, 3)``, values ``(T, K + n_pad, C)``, weights
        ``(T, K + n_pad)``.
    """
    d = np.asarray(directions, dtype=np.float64)
    f = np.asarray(values, dtype=np.float64)
    w = np.asarray(weights, dtype=np.float64)
    _check_shape(d, "directions", (None, None, 3))
    _check_shape(f, "values", (d.shape[0], d.shape[1], None))
    _check_shape(w, "weights", (d.shape[0], d.shape[1]))
    n_pad = _check_int(n_pad, "n_pad", 1)
    pad_weight = _check_positive(pad_weight, "pad_weight")
    n_tex = d.shape[0]
    pad = np.broadcast_to(_lower_hemisphere_points(n_pad), (n_tex, n_pad, 3))
    return (
        np.concatenate([d, pad], axis=1),
        np.concatenate([f, np.zeros((n_tex, n_pad, f.shape[2]))], axis=1),
        np.concatenate([w, np.full((n_tex, n_pad), pad_weight)], axis=1),
    )


def spectra(coeffs: np.ndarray) -> np.ndarray:
    """Power per degree of per-texel SH coefficients.

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``(T, (lmax+1)**2, C)`` as returned by `fit_sh`.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, lmax+1, C)``, float64: ``S(l) = sum_m c_lm^2``.
    """
    c = np.asarray(coeffs)
    _check_shape(c, "coeffs", (None, None, None))
    _lmax_of(c.shape[1], f"coeffs of shape {c.shape} (axis 1)")
    return power_spectrum(np.moveaxis(c, 1, -1)).transpose(0, 2, 1).copy()


# --------------------------------------------------------------------------
# spectrum-only estimate and entropy
# --------------------------------------------------------------------------
def default_grid(n_ks: int = 8, n_alpha: int = 8, alpha_min: float = 0.0) -> tuple[np.ndarray, np.ndarray]:
    """Evenly spaced grid of specular reflectance and lobe width.

    Parameters
    ----------
    n_ks, n_alpha : int
        Grid sizes (8 x 8 in the authors' code, 10 x 10 in paper Fig. 4).
    alpha_min : float
        Smallest alpha, in ``[0, 1)``; the band limit a' is a natural choice,
        since narrower lobes cannot be told apart from it.

    Returns
    -------
    tuple of numpy.ndarray
        ``ks_values`` (n_ks,) = ``k / n_ks`` for ``k = 1..n_ks`` (in (0, 1]),
        ``alpha_values`` (n_alpha,) evenly spaced in ``[alpha_min, 1]``.
    """
    n_ks = _check_int(n_ks, "n_ks", 1)
    n_alpha = _check_int(n_alpha, "n_alpha", 1)
    alpha_min = float(alpha_min)
    if not (0.0 <= alpha_min < 1.0):
        raise ValueError(f"alpha_min must be in [0, 1), got {alpha_min!r}")
    ks = np.arange(1, n_ks + 1) / n_ks
    alpha = np.linspace(alpha_min, 1.0, n_alpha) if n_alpha > 1 else np.array([alpha_min])
    return ks, alpha


def _check_grid_values(ks_values: np.ndarray, alpha_values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    ks = np.asarray(ks_values, dtype=np.float64)
    alpha = np.asarray(alpha_values, dtype=np.float64)
    for name, v in (("ks_values", ks), ("alpha_values", alpha)):
        _check_shape(v, name, (None,))
        if v.size == 0 or not np.all(np.isfinite(v)) or (v < 0).any():
            raise ValueError(f"{name} must be a non-empty 1-D array of finite values >= 0, got {v!r}")
    if ks.size * alpha.size < 2:
        raise ValueError(f"the grid needs at least 2 points, got {ks.size} x {alpha.size}")
    return ks, alpha


def residual_width(alpha: np.ndarray, a_prime: float) -> np.ndarray:
    """Lobe width that acts on a light already low-passed by ``exp(-(a' l)^2)``.

    Gaussian SH filters compose by adding squared widths, so the lobe
    ``exp(-(alpha l)^2)`` of the unfiltered light is ``exp(-(w l)^2)`` of the
    pre-filtered one with ``w = sqrt(alpha^2 - a'^2)`` (paper section 4.2: the
    pre-filter a' on the incoming light only). Widths at or below a' give 0:
    the pre-filtered light is itself the narrowest lobe the views resolve.

    Parameters
    ----------
    alpha : numpy.ndarray
        Lobe widths, any shape.
    a_prime : float
        Width of the pre-filter (>= 0).

    Returns
    -------
    numpy.ndarray
        Same shape, float64, in ``[0, alpha]``.
    """
    a = np.asarray(alpha, dtype=np.float64)
    return np.sqrt(np.maximum(a * a - float(a_prime) ** 2, 0.0))


def model_filters(ks_values: np.ndarray, alpha_values: np.ndarray, lmax: int) -> np.ndarray:
    """Spectral filters ``K_s^2 exp(-2 (alpha l)^2)`` of every grid point, degrees 1..lmax.

    Parameters
    ----------
    ks_values : numpy.ndarray
        Shape ``(n_ks,)``.
    alpha_values : numpy.ndarray
        Shape ``(n_alpha,)``.
    lmax : int
        Maximum degree, ``>= 1``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_ks, n_alpha, lmax)``, float64; last axis is l = 1..lmax.
    """
    ks, alpha = _check_grid_values(ks_values, alpha_values)
    lmax = _check_int(lmax, "lmax", 1)
    l = np.arange(1, lmax + 1, dtype=np.float64)
    return ks[:, None, None] ** 2 * np.exp(-2.0 * (alpha[None, :, None] * l) ** 2)


def _to_rows(a: np.ndarray) -> np.ndarray:
    """(T, L, C) -> (T C, L): one row per texel and channel, contiguous."""
    return a.transpose(0, 2, 1).reshape(-1, a.shape[1])


def _from_rows(a: np.ndarray, n_tex: int) -> np.ndarray:
    """(T C, L) -> (T, L, C), inverse of `_to_rows`."""
    return a.reshape(n_tex, -1, a.shape[1]).transpose(0, 2, 1)


def _normalise_rows(
    sb: np.ndarray, sl: np.ndarray, min_relative_power: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """`normalised_spectra` on (N, lmax+1) rows (one texel and channel per row)."""
    total = sl.sum(axis=1)
    varying = total - sl[:, 0]
    ok = np.isfinite(total) & (total > 0) & (varying > min_relative_power * total)
    ok &= np.isfinite(sb).all(axis=1)
    scale = np.where(ok, 1.0 / np.where(ok, total, 1.0), 0.0)[:, None]
    return sb[:, 1:] * scale, sl[:, 1:] * scale, ok


def _reference_rows(sb: np.ndarray, sl: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The authors' scaling of (N, lmax+1) spectra rows: per-degree power divided by (l + 1).

    Returns the rows at degrees 1..lmax, the weight ``S_B'(0)^2 / lmax`` that
    turns their sum of squared residuals into the reference code's D (the mean
    over degrees times the outgoing DC power squared), and the usable rows.
    """
    scale = 1.0 / np.arange(1, sb.shape[1] + 1)
    b, l = sb * scale, sl * scale
    ok = np.isfinite(b).all(axis=1) & np.isfinite(l).all(axis=1) & (l[:, 1:].sum(axis=1) > 0)
    weight = np.where(ok, b[:, 0] ** 2 / (sb.shape[1] - 1), 0.0)
    return np.where(ok[:, None], b[:, 1:], 0.0), np.where(ok[:, None], l[:, 1:], 0.0), weight, ok


def _check_min_relative_power(value: float) -> float:
    value = float(value)
    if not (np.isfinite(value) and 0.0 <= value < 1.0):
        raise ValueError(f"min_relative_power must be in [0, 1), got {value!r}")
    return value


def normalised_spectra(
    s_b: np.ndarray, s_l: np.ndarray, min_relative_power: float = 1e-9
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Spectra at degrees 1..lmax divided by the light's total power (degrees 0..lmax).

    Parameters
    ----------
    s_b, s_l : numpy.ndarray
        Shape ``(T, lmax+1, C)``: outgoing and incoming power spectra.
    min_relative_power : float
        A channel is identifiable only if the light's power at degrees >= 1
        exceeds this fraction of its total power (and the total is > 0).

    Returns
    -------
    tuple of numpy.ndarray
        ``b`` and ``l`` of shape ``(T, lmax, C)`` (degrees 1..lmax,
        dimensionless, 0 where not identifiable) and ``identifiable`` ``(T, C)`` bool.
    """
    sb = np.asarray(s_b, dtype=np.float64)
    sl = np.asarray(s_l, dtype=np.float64)
    _check_shape(sl, "s_l", (None, None, None))
    _check_shape(sb, "s_b", sl.shape)
    if sl.shape[1] < 2:
        raise ValueError(f"spectra need degrees 0..lmax with lmax >= 1, got shape {sl.shape}")
    min_relative_power = _check_min_relative_power(min_relative_power)
    n_tex, _, n_ch = sl.shape
    b, l, ok = _normalise_rows(_to_rows(sb), _to_rows(sl), min_relative_power)
    return _from_rows(b, n_tex), _from_rows(l, n_tex), ok.reshape(n_tex, n_ch)


_SINGLE_THREAD_GEMM = 1 << 17  # M*N*K under which OpenBLAS runs a product on one thread


def _objective_rows(b: np.ndarray, l: np.ndarray, ks: np.ndarray, alpha: np.ndarray) -> np.ndarray:
    """D of (N, lmax) normalised spectra rows on the grid, (N, n_ks * n_alpha), float64.

    The square is expanded, ``D = sum_l b_l^2 + sum_l [b_l s_l, s_l^2] . [-2 m_gl, m_gl^2]``
    with ``m_gl = K_s^2 exp(-2 (alpha l)^2)``, so the grid costs one product
    with a (2 lmax, G) matrix. The product runs in row blocks small enough for
    OpenBLAS to stay on one thread: its worker threads keep spinning after a
    threaded call and slowed the following elementwise work several times on
    2 cores. float64 keeps the cancellation error far below 2 sigma^2.
    """
    lmax = b.shape[1]
    m = model_filters(ks, alpha, lmax).reshape(-1, lmax)
    a = np.concatenate([-2.0 * m, m * m], axis=1).T.copy()  # (2 lmax, G)
    u = np.concatenate([b * l, l * l], axis=1)  # (N, 2 lmax)
    n_rows, n_grid = u.shape[0], a.shape[1]
    d = np.empty((n_rows, n_grid))
    block = max(1, _SINGLE_THREAD_GEMM // (n_grid * a.shape[0]))
    for r in range(0, n_rows, block):
        np.matmul(u[r : r + block], a, out=d[r : r + block])
    d += np.einsum("nl,nl->n", b, b)[:, None]
    np.maximum(d, 0.0, out=d)
    return d


def spectrum_objective(b: np.ndarray, l: np.ndarray, ks_values: np.ndarray, alpha_values: np.ndarray) -> np.ndarray:
    """Objective ``D = sum_{l>=1} (b_l - K_s^2 exp(-2 (alpha l)^2) s_l)^2`` on the grid.

    Parameters
    ----------
    b, l : numpy.ndarray
        Shape ``(T, lmax, C)``: normalised outgoing and incoming spectra at
        degrees 1..lmax (`normalised_spectra`).
    ks_values, alpha_values : numpy.ndarray
        Grid axes ``(n_ks,)`` and ``(n_alpha,)``.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, n_ks, n_alpha, C)``, float64, ``>= 0``.
    """
    b = np.asarray(b, dtype=np.float64)
    l = np.asarray(l, dtype=np.float64)
    _check_shape(b, "b", (None, None, None))
    _check_shape(l, "l", b.shape)
    ks, alpha = _check_grid_values(ks_values, alpha_values)
    n_tex, _, n_ch = b.shape
    d = _objective_rows(_to_rows(b), _to_rows(l), ks, alpha)
    return d.reshape(n_tex, n_ch, ks.size, alpha.size).transpose(0, 2, 3, 1)


def _entropy_rows(d: np.ndarray, sigma: float, d_min: np.ndarray | None = None) -> np.ndarray:
    """Normalised entropy of ``p ~ exp(-d / (2 sigma^2))`` along the last axis of ``d``.

    ``d_min`` (``d.min(-1)``, if already known) saves a reduction.
    """
    if d_min is None:
        d_min = d.min(axis=-1)
    # x = log p + log z <= 0; float32 is ample once the minimum is subtracted.
    # Clipping at -1e4 (p < e^-10000, i.e. 0) keeps huge D from becoming -inf,
    # whose product with p = 0 would be NaN.
    with np.errstate(over="ignore"):
        x = (d_min[..., None] - d).astype(np.float32)
    x *= np.float32(0.5 / sigma**2)
    np.maximum(x, np.float32(-1e4), out=x)
    e = np.exp(x)
    z = e.sum(axis=-1).astype(np.float64)
    # sum p log p = sum p x - log z, with p = e / z and log p = x - log z
    ex = np.einsum("...g,...g->...", e, x).astype(np.float64)
    h = (np.log(z) - ex / z) / np.log(d.shape[-1])
    return np.where(np.isfinite(h), np.clip(h, 0.0, 1.0), 1.0)


def grid_entropy(objective: np.ndarray, sigma: float = 1e-2) -> np.ndarray:
    """Normalised entropy of the grid likelihood ``p_i ~ exp(-D_i / (2 sigma^2))``.

    Parameters
    ----------
    objective : numpy.ndarray
        Shape ``(T, n_ks, n_alpha, C)``, D from `spectrum_objective`.
    sigma : float
        Noise scale of the (normalised) objective (paper: 1e-2).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, in ``[0, 1]``: ``-(1/log n) sum_i p_i log p_i`` over
        the ``n = n_ks n_alpha`` grid points (uniform prior, log-sum-exp).
    """
    d = np.asarray(objective, dtype=np.float64)
    _check_shape(d, "objective", (None, None, None, None))
    sigma = _check_positive(sigma, "sigma")
    n_tex, n_ks, n_alpha, n_ch = d.shape
    if n_ks * n_alpha < 2:
        raise ValueError(f"the grid needs at least 2 points, got {n_ks} x {n_alpha}")
    rows = d.transpose(0, 3, 1, 2).reshape(n_tex, n_ch, n_ks * n_alpha)
    return _entropy_rows(rows, sigma)


def combine_entropy(entropy_rgb: np.ndarray, combine: str = "min") -> np.ndarray:
    """One entropy per texel from per-channel entropies.

    Parameters
    ----------
    entropy_rgb : numpy.ndarray
        Shape ``(T, 3)``.
    combine : {"min", "luminance"}
        ``min``: the most certain channel (authors' code); ``luminance``:
        Rec. 709 weighted mean of the channel entropies.

    Returns
    -------
    numpy.ndarray
        Shape ``(T,)``, in ``[0, 1]``.
    """
    h = np.asarray(entropy_rgb, dtype=np.float64)
    _check_shape(h, "entropy_rgb", (None, 3))
    _check_choice(combine, "combine", COMBINE_MODES)
    if combine == "min":
        return h.min(axis=1)
    return h @ LUMINANCE


@dataclass(frozen=True)
class SpectrumSearch:
    """Result of `spectrum_search` (T texels, C channels).

    Attributes
    ----------
    ks_index, alpha_index : numpy.ndarray
        ``(T, C)`` int: per-channel argmin of D on the grid.
    ks : numpy.ndarray
        ``(T, C)``: K_s per channel at the joint alpha (argmin of D_c(., alpha)).
    alpha : numpy.ndarray
        ``(T,)``: joint alpha, argmin over the grid of ``sum_c min_ks D_c(ks, alpha)``
        over the identifiable channels (profile likelihood; one lobe width per texel).
    entropy_rgb : numpy.ndarray
        ``(T, C)`` in [0, 1]; exactly 1 where not identifiable or unobserved.
    entropy : numpy.ndarray
        ``(T,)`` in [0, 1], combined over channels (`combine_entropy`; for
        ``C != 3`` the minimum); exactly 1 for unobserved texels.
    identifiable : numpy.ndarray
        ``(T, C)`` bool: the light has power at degrees >= 1 (`normalised_spectra`).
    unobserved : numpy.ndarray
        ``(T,)`` bool: no view observes the texel.
    objective : numpy.ndarray or None
        ``(T, n_ks, n_alpha, C)`` normalised D if requested, else None.

    Where a channel is not identifiable (or the texel unobserved) its D is 0
    everywhere and its estimates are the first grid point: meaningless, see
    the flags.
    """

    ks_index: np.ndarray
    alpha_index: np.ndarray
    ks: np.ndarray
    alpha: np.ndarray
    entropy_rgb: np.ndarray
    entropy: np.ndarray
    identifiable: np.ndarray
    unobserved: np.ndarray
    objective: np.ndarray | None = None


def spectrum_search(
    s_b: np.ndarray,
    s_l: np.ndarray,
    ks_values: np.ndarray,
    alpha_values: np.ndarray,
    sigma: float = 1e-2,
    combine: str = "min",
    observed: np.ndarray | None = None,
    min_relative_power: float = 1e-9,
    chunk: int = 2048,
    workers: int = 1,
    return_objective: bool = False,
    normalise: str = "light",
) -> SpectrumSearch:
    """Spectrum-only estimate of (K_s, alpha) and its entropy (METHOD section 6).

    Parameters
    ----------
    s_b, s_l : numpy.ndarray
        Shape ``(T, lmax+1, C)``, lmax >= 1: outgoing and incoming power
        spectra (`spectra`) of the same texels, same parametrisation.
    ks_values, alpha_values : numpy.ndarray
        Grid axes ``(n_ks,)`` and ``(n_alpha,)`` (e.g. `default_grid`).
    sigma : float
        ``normalise="light"``: noise scale of the normalised D, ``p ~ exp(-D / (2 sigma^2))``
        (paper Eq. 23: 1e-2). ``"reference"``: the reference code's temperature,
        ``p ~ exp(-(D - D_min) / sigma)`` (1e-5 there).
    combine : {"min", "luminance"}
        How channel entropies are combined (`combine_entropy`; needs C == 3
        for "luminance").
    observed : numpy.ndarray, optional
        ``(T,)`` bool (`observed_texels`); unobserved texels get entropy 1.
        Default: every texel is observed.
    min_relative_power : float
        See `normalised_spectra`.
    chunk : int
        Texels processed at once (bounds memory: about 1 KB per texel and
        channel on an 8 x 8 grid).
    workers : int
        Threads processing chunks concurrently (numpy releases the GIL).
    return_objective : bool
        Also return the full normalised D (``T n_ks n_alpha C`` float64 values).
    normalise : {"light", "reference"}
        ``light`` (default): both spectra divided by the light's total power
        (module docstring), so D is free of the light's intensity.
        ``reference``: the authors' code (svbrdf_uncertainty,
        ``uncertainty/entropy.py``): per-degree power divided by ``l + 1``,
        D the mean squared residual over degrees times the outgoing DC power
        squared, so bright texels are more certain than dark ones in absolute
        radiance units.

    Returns
    -------
    SpectrumSearch
    """
    sb = np.asarray(s_b)
    sl = np.asarray(s_l)
    _check_shape(sl, "s_l", (None, None, None))
    _check_shape(sb, "s_b", sl.shape)
    n_tex, n_deg, n_ch = sl.shape
    if n_deg < 2:
        raise ValueError(f"spectra need degrees 0..lmax with lmax >= 1, got shape {sl.shape}")
    ks, alpha = _check_grid_values(ks_values, alpha_values)
    sigma = _check_positive(sigma, "sigma")
    _check_choice(combine, "combine", COMBINE_MODES)
    if combine == "luminance" and n_ch != 3:
        raise ValueError(f"combine='luminance' needs 3 channels, got {n_ch}")
    chunk = _check_int(chunk, "chunk", 1)
    workers = _check_int(workers, "workers", 1)
    min_relative_power = _check_min_relative_power(min_relative_power)
    _check_choice(normalise, "normalise", NORMALISATIONS)
    # the reference code's temperature as the sigma of exp(-D / (2 sigma^2))
    sigma_eff = np.sqrt(sigma / 2.0) if normalise == "reference" else sigma
    if observed is None:
        seen = np.ones(n_tex, bool)
    else:
        seen = np.asarray(observed)
        _check_shape(seen, "observed", (n_tex,))
        seen = seen.astype(bool)
    n_ks, n_alpha = ks.size, alpha.size

    ks_idx = np.zeros((n_tex, n_ch), np.int64)
    alpha_idx = np.zeros((n_tex, n_ch), np.int64)
    ks_at = np.zeros((n_tex, n_ch))
    alpha_joint = np.zeros(n_tex)
    h_rgb = np.ones((n_tex, n_ch))
    ident = np.zeros((n_tex, n_ch), bool)
    objective = np.empty((n_tex, n_ks, n_alpha, n_ch)) if return_objective else None

    def search(start: int) -> None:
        stop = min(n_tex, start + chunk)
        t = stop - start
        # one row per (texel, channel): reductions run along contiguous rows
        rows_b, rows_l = _to_rows(sb[start:stop].astype(np.float64)), _to_rows(sl[start:stop].astype(np.float64))
        if normalise == "reference":
            b, l, weight, ok = _reference_rows(rows_b, rows_l)
        else:
            b, l, ok = _normalise_rows(rows_b, rows_l, min_relative_power)
        ok = ok.reshape(t, n_ch) & seen[start:stop, None]
        d = _objective_rows(b, l, ks, alpha)
        if normalise == "reference":
            d *= weight[:, None]
        d = d.reshape(t, n_ch, n_ks * n_alpha)
        if not ok.all():
            d[~ok] = 0.0  # flat (uniform) likelihood where nothing is identifiable
        d4 = d.reshape(t, n_ch, n_ks, n_alpha)
        best = d.argmin(axis=2)
        ks_idx[start:stop], alpha_idx[start:stop] = np.divmod(best, n_alpha)
        d_min = np.take_along_axis(d, best[..., None], axis=2)[..., 0]
        h_rgb[start:stop] = np.where(ok, _entropy_rows(d, sigma_eff, d_min), 1.0)
        ident[start:stop] = ok
        # Profile likelihood over channels: one alpha per texel, K_s per channel.
        # The min over K_s runs as a loop of elementwise minima because numpy
        # reduces a short middle axis slowly.
        prof = d4[:, :, 0, :].copy()
        for k in range(1, n_ks):
            np.minimum(prof, d4[:, :, k, :], out=prof)
        a_best = prof.sum(axis=1).argmin(axis=1)  # (t,)
        k_best = d4[np.arange(t), :, :, a_best].argmin(axis=2)  # (t, C)
        alpha_joint[start:stop] = alpha[a_best]
        ks_at[start:stop] = ks[k_best]
        if objective is not None:
            objective[start:stop] = d4.transpose(0, 2, 3, 1)

    starts = range(0, n_tex, chunk)
    if workers == 1 or len(starts) <= 1:
        for start in starts:
            search(start)
    else:
        # chunks write disjoint slices of the outputs, so threads need no locking
        with ThreadPoolExecutor(max_workers=workers) as pool:
            list(pool.map(search, starts))
    if combine == "luminance":
        h_tex = combine_entropy(h_rgb, "luminance")
    else:
        h_tex = h_rgb.min(axis=1)
    h_tex = np.where(seen, h_tex, 1.0)
    return SpectrumSearch(
        ks_index=ks_idx,
        alpha_index=alpha_idx,
        ks=ks_at,
        alpha=alpha_joint,
        entropy_rgb=h_rgb,
        entropy=h_tex,
        identifiable=ident,
        unobserved=~seen,
        objective=objective,
    )


# --------------------------------------------------------------------------
# degree 0: irradiance and diffuse albedo
# --------------------------------------------------------------------------
def _clamped_cosine_gains(lmax: int) -> np.ndarray:
    """``2 pi g_l`` with ``g_l = int_0^1 t P_l(t) dt`` for l = 0..lmax, shape (lmax+1,).

    Funk-Hecke: the clamped cosine about ``n`` has SH coefficients
    ``2 pi g_l Y_lm(n)`` (``g_0 = 1/2``, ``g_1 = 1/3``, 0 for odd ``l > 1``).
    ``t P_l(t)`` is a polynomial, so Gauss-Legendre quadrature is exact.
    """
    x, w = np.polynomial.legendre.leggauss(lmax // 2 + 2)  # exact up to degree lmax + 3
    t, w = 0.5 * (x + 1.0), 0.5 * w  # nodes on [0, 1]
    g = np.array([w @ (t * np.polynomial.legendre.Legendre.basis(l)(t)) for l in range(lmax + 1)])
    return 2.0 * np.pi * g


def _check_normals(normal: np.ndarray, name: str) -> np.ndarray:
    n = np.asarray(normal, dtype=np.float64)
    if n.ndim not in (1, 2) or n.shape[-1] != 3:
        raise ValueError(f"{name} must have shape (3,) or (T, 3), got shape {n.shape}")
    norm = np.linalg.norm(n, axis=-1, keepdims=True)
    if not (np.all(np.isfinite(norm)) and np.all(norm > 0)):
        raise ValueError(f"{name} must be non-zero finite vectors, got {n!r}")
    return n / norm


def clamped_cosine_sh(lmax: int, normal: np.ndarray = _LOCAL_NORMAL) -> np.ndarray:
    """SH coefficients of ``max(n . w, 0)``, the irradiance kernel.

    Parameters
    ----------
    lmax : int
        Maximum degree.
    normal : numpy.ndarray
        Shape ``(3,)`` or ``(T, 3)``: kernel axis in the frame of the SH
        (default local +z, the texel normal).

    Returns
    -------
    numpy.ndarray
        Shape ``((lmax+1)**2,)`` or ``(T, (lmax+1)**2)``, float64:
        ``2 pi g_l Y_lm(n)``, ``g_l = int_0^1 t P_l(t) dt``.
    """
    lmax = _check_int(lmax, "lmax", 0)
    n = _check_normals(normal, "normal")
    return _clamped_cosine_gains(lmax)[sh_degrees(lmax)] * real_sh(n, lmax)


def irradiance_from_coeffs(coeffs: np.ndarray, normal: np.ndarray = _LOCAL_NORMAL) -> np.ndarray:
    """Irradiance ``E = int_{n.w>0} L(w) (n . w) dw`` of per-texel SH radiance.

    Parameters
    ----------
    coeffs : numpy.ndarray
        Shape ``(T, (lmax+1)**2, C)``: SH of the incoming radiance L, e.g. the
        fit of ``incoming`` at `mirror_directions` (texel frame).
    normal : numpy.ndarray
        Shape ``(3,)`` or ``(T, 3)``: the normal in that frame (default local +z).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, radiance times sr (``pi L`` for constant L).
    """
    c = np.asarray(coeffs, dtype=np.float64)
    _check_shape(c, "coeffs", (None, None, None))
    lmax = _lmax_of(c.shape[1], f"coeffs of shape {c.shape} (axis 1)")
    a = clamped_cosine_sh(lmax, normal)
    if a.ndim == 2:
        _check_shape(a, "normal", (c.shape[0], None))
        return np.einsum("ti,tic->tc", a, c)
    return np.einsum("i,tic->tc", a, c)


def irradiance_at_normals(env_coeffs: np.ndarray, normals: np.ndarray) -> np.ndarray:
    """Irradiance of one distant environment at many surface normals.

    Unlike a per-texel fit of the mirror-direction samples (which only sees
    the light at K directions and misestimates E by a few percent with 24
    views), this uses the whole environment; like the paper's model it ignores
    occlusion by the object itself.

    Parameters
    ----------
    env_coeffs : numpy.ndarray
        Shape ``((lmax+1)**2, C)``: SH of the environment radiance in the frame
        of ``normals`` (e.g. :func:`freqbrdf.sh.project_equirect`, world frame).
    normals : numpy.ndarray
        Shape ``(T, 3)``, surface normals.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, radiance times sr.
    """
    c = np.asarray(env_coeffs, dtype=np.float64)
    _check_shape(c, "env_coeffs", (None, None))
    lmax = _lmax_of(c.shape[0], f"env_coeffs of shape {c.shape} (axis 0)")
    n = np.asarray(normals)
    _check_shape(n, "normals", (None, 3))
    return clamped_cosine_sh(lmax, n) @ c


def diffuse_albedo(
    b00: np.ndarray, l00: np.ndarray, ks: np.ndarray, irradiance: np.ndarray, unit_dc: np.ndarray | None = None
) -> np.ndarray:
    """Diffuse albedo K_d from degree 0 once K_s is known.

    A Lambertian texel reflects the constant radiance ``K_d E / pi``; the
    specular lobe adds ``K_s L_00`` at degree 0 (its filter is 1 there). So
    ``B_00 = u K_d E / pi + K_s L_00``, where ``u`` is the degree-0 coefficient
    of the constant 1: ``sqrt(4 pi)`` for an exact transform, which is METHOD's
    ``B_00 = pi^(-1/2) K_d E' + K_s L_00`` with the paper's hemispherical
    normalisation ``E' = 2 E``. But samples of reflected light cover one
    hemisphere at most, and a fit does not extend constant data on it to a
    constant on the sphere (measured at lmax 6: DC = 0.86 sqrt(4 pi) for 24
    views and ``exp``, 0.97 sqrt(4 pi) for 400 views and ``none``). So pass
    ``unit_dc``, the DC that the same fit gives a channel of ones (append it
    to the B and L channels of `fit_sh`; the fit is linear, so the diffuse
    part is then undone exactly).

    Parameters
    ----------
    b00, l00 : numpy.ndarray
        Shape ``(T, C)``: degree-0 coefficients of the fits of B and L.
    ks : numpy.ndarray
        Shape ``(T,)`` or ``(T, C)``: specular reflectance.
    irradiance : numpy.ndarray
        Shape ``(T, C)``: E (`irradiance_at_normals` or `irradiance_from_coeffs`).
    unit_dc : numpy.ndarray, optional
        Shape ``(T,)``: fitted degree-0 coefficient of the constant 1 (default
        ``sqrt(4 pi)``).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, C)``, float64, unclipped; 0 where ``u E`` is not positive.
    """
    b = np.asarray(b00, dtype=np.float64)
    _check_shape(b, "b00", (None, None))
    lc = np.asarray(l00, dtype=np.float64)
    _check_shape(lc, "l00", b.shape)
    e = np.asarray(irradiance, dtype=np.float64)
    _check_shape(e, "irradiance", b.shape)
    k = np.asarray(ks, dtype=np.float64)
    if k.ndim == 1:
        _check_shape(k, "ks", (b.shape[0],))
        k = k[:, None]
    else:
        _check_shape(k, "ks", b.shape)
    if unit_dc is None:
        u = np.full((b.shape[0], 1), np.sqrt(4.0 * np.pi))
    else:
        u = np.asarray(unit_dc, dtype=np.float64)
        _check_shape(u, "unit_dc", (b.shape[0],))
        u = u[:, None]
    denom = u * e / np.pi
    ok = np.isfinite(denom) & (denom > 0)
    return np.where(ok, (b - k * lc) / np.where(ok, denom, 1.0), 0.0)


# --------------------------------------------------------------------------
# principled parameters
# --------------------------------------------------------------------------
def lobes_from_principled(
    base: np.ndarray, roughness: np.ndarray, metallic: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Diffuse albedo, specular reflectance and lobe width of principled parameters.

    Parameters
    ----------
    base : numpy.ndarray
        Shape ``(T, 3)``, linear base colour in [0, 1].
    roughness, metallic : numpy.ndarray
        Shape ``(T,)``, in [0, 1].

    Returns
    -------
    tuple of numpy.ndarray
        ``kd`` (T, 3) ``= (1 - m) base``; ``ks`` (T, 3) ``= R0 = 0.04 (1 - m) + m base``;
        ``alpha`` (T,) ``= roughness^2``.
    """
    b = np.asarray(base, dtype=np.float64)
    _check_shape(b, "base", (None, 3))
    r = np.asarray(roughness, dtype=np.float64)
    m = np.asarray(metallic, dtype=np.float64)
    _check_shape(r, "roughness", (b.shape[0],))
    _check_shape(m, "metallic", (b.shape[0],))
    m = m[:, None]
    return (1.0 - m) * b, R0_DIELECTRIC * (1.0 - m) + m * b, r**2


def principled_from_lobes(
    kd: np.ndarray, ks: np.ndarray, alpha: np.ndarray
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Principled (base colour, roughness, metallic) from (K_d, K_s, alpha).

    Approximations: K_s is taken as the normal-incidence reflectance R0 (the
    spectrum-only K_s also absorbs the Fresnel rise at grazing angles, so it
    overestimates R0 and hence metallic); the Torrance-Sparrow lobe width
    alpha is taken as the GGX alpha, ``roughness = sqrt(alpha)``. Metallic m
    solves the luminance (Rec. 709) relations ``Y(kd) = (1 - m) Y(base)`` and
    ``Y(ks) = 0.04 (1 - m) + m Y(base)``, i.e. with ``u = 1 - m``
    ``0.04 u^2 - (Y(ks) + Y(kd)) u + Y(kd) = 0``: the smaller root, which lies
    in [0, 1) whenever ``Y(ks) > 0.04``; m = 0 if there is no real root or
    the root exceeds 1 (K_s at or below a dielectric's 0.04). For a base
    colour darker than 0.04 the relations have a second exact solution; the
    more metallic one is returned. The base
    colour is then the per-channel least-squares solution of
    ``(1 - m) base = kd`` and ``m base = ks - 0.04 (1 - m)``, so it comes from
    the diffuse lobe for dielectrics and from the specular lobe for metals
    (grey for metals if ``ks`` is a scalar). Everything is clipped to [0, 1].

    Parameters
    ----------
    kd : numpy.ndarray
        Shape ``(T, 3)``, diffuse albedo.
    ks : numpy.ndarray
        Shape ``(T,)`` (luminance) or ``(T, 3)``, specular reflectance.
    alpha : numpy.ndarray
        Shape ``(T,)``, lobe width.

    Returns
    -------
    tuple of numpy.ndarray
        ``base`` (T, 3), ``roughness`` (T,), ``metallic`` (T,), float64 in [0, 1].
    """
    d = np.asarray(kd, dtype=np.float64)
    _check_shape(d, "kd", (None, 3))
    k = np.asarray(ks, dtype=np.float64)
    if k.ndim == 1:
        _check_shape(k, "ks", (d.shape[0],))
        k = k[:, None]
    else:
        _check_shape(k, "ks", (d.shape[0], 3))
    a = np.asarray(alpha, dtype=np.float64)
    _check_shape(a, "alpha", (d.shape[0],))
    for name, v in (("kd", d), ("ks", k), ("alpha", a)):
        if not np.all(np.isfinite(v)):
            raise ValueError(f"{name} must be finite, got {v[~np.isfinite(v)][0]!r}")
    d = np.clip(d, 0.0, 1.0)
    k = np.clip(k, 0.0, 1.0)
    y_d = d @ LUMINANCE
    y_s = k[:, 0] if k.shape[1] == 1 else k @ LUMINANCE
    s = y_s + y_d
    disc2 = s * s - 4.0 * R0_DIELECTRIC * y_d
    real = (disc2 >= 0.0) & (s > 0.0)
    # smaller root u = 2 y_d / (s + sqrt(disc2)), free of cancellation; no real
    # root (K_s below a dielectric's, diffuse too bright) or black -> dielectric
    u = np.where(real, 2.0 * y_d / np.where(real, s + np.sqrt(np.maximum(disc2, 0.0)), 1.0), 1.0)
    m = np.clip(1.0 - u, 0.0, 1.0)
    mm = m[:, None]
    base = ((1.0 - mm) * d + mm * (k - R0_DIELECTRIC * (1.0 - mm))) / ((1.0 - mm) ** 2 + mm**2)
    roughness = np.sqrt(np.clip(a, 0.0, 1.0))
    return np.clip(base, 0.0, 1.0), roughness, m
