"""SH fits of the outgoing radiance B and incoming light L of every texel (rule fit_sh).

Wiersma et al. 2024, section 4.2 (Eq. 12, Fig. 3): the per-texel observations (``radiance``
B, ``weight``, ``wo_local``, ``incoming`` L; :class:`freqbrdf.artefacts.Observations`)
are sparse, irregular and weighted samples on the hemisphere; `fit_sh` fits
their SH coefficients by regularised least squares (regulariser
``W = diag(e^l)``), and :func:`freqbrdf.sphere.sh.power_spectrum` gives the power per degree.

Parametrisation
---------------
B and L are both fitted as functions of the local mirror direction
``w_r = (-x, -y, z)`` of ``wo_local`` (`mirror_directions`), fed to
:func:`freqbrdf.sphere.sh.real_sh` as if the texel frame were the SH frame. The SH
polar axis is then the texel's local +y (a tangent direction), not the normal
(+z). This is harmless for the spectra: a rotation of the sample directions
rotates each degree's coefficients by an orthogonal matrix, the regulariser
``W = diag(e^l)`` is constant within a degree, so the regularised fit is
rotation-equivariant and the power spectra are rotation invariant. The only
place the normal matters is the irradiance (degree 0 analysis), where
`clamped_cosine_sh` evaluates the clamped-cosine kernel about local +z
explicitly.
Notes
-----
*The DC penalty.* ``penalise_dc=False`` sets ``W_00 = 0`` (not in the paper):
the constant then costs nothing, so constant data are fitted exactly by a
constant. With the paper's ``W_00 = 1`` and fewer samples than coefficients,
the smoothest interpolant of constant data is NOT constant (its DC is 0.67
sqrt(4 pi) at the median texel of the 24-view sphere/studio capture), so a
diffuse texel's constant radiance leaks into degrees >= 1, where the spectrum
search reads it as specular reflection (median K_s of the dielectric texels
0.75 instead of 0.125 without the DC penalty).

*The dual solver.* For ``exp`` and ``constant`` the solution of
``(Y^T S Y + lam W) c = Y^T S f`` is also ``W^-1 Z^T (Z W^-1 Z^T + lam I)^-1 g``
with ``Z = S^1/2 Y``, ``g = S^1/2 f`` (push-through identity), a K x K system
per texel: cheaper when there are fewer samples than coefficients (24 views
at lmax 6: 24 vs 49).
"""

from __future__ import annotations

from collections.abc import Mapping
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from freqbrdf.artefacts import Observations, ShFit
from freqbrdf.sphere.sh import n_coeffs, real_sh, sh_degrees
from freqbrdf.sphere.sampling import fibonacci_hemisphere
from freqbrdf.util.validation import check_choice, check_int, check_positive, check_shape

REGULARISERS = ("exp", "constant", "none")
_FILL_DIRECTION = (0.0, 0.0, 1.0)  # any unit vector: stands in for unobserved samples
_NONE_RIDGE = 1e-9  # relative ridge of regulariser "none" (see fit_sh)
_FIT_CHUNK_VALUES = 1 << 22  # float64 values of one chunk's design matrix (32 MB)


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
    lmax = check_int(lmax, "lmax", 0)
    check_choice(regulariser, "regulariser", REGULARISERS)
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
    d = np.where(valid[..., None], d, np.asarray(_FILL_DIRECTION))
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


def _check_samples(d: np.ndarray, f: np.ndarray, w: np.ndarray) -> None:
    """Shapes of directions (T, K, 3), values (T, K, C) and weights (T, K); finite values and
    non-zero directions wherever the weight is positive."""
    check_shape(d, "directions", (None, None, 3))
    check_shape(f, "values", (d.shape[0], d.shape[1], None))
    check_shape(w, "weights", (d.shape[0], d.shape[1]))
    if not np.all(np.isfinite(w)) or (w < 0).any():
        bad = w[~(np.isfinite(w) & (w >= 0))][0]
        raise ValueError(f"weights must be finite and >= 0, got {bad!r}")
    used = w > 0
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


def _solver_method(regulariser: str, solver: str, n_obs: int, n: int) -> str:
    """``ridge`` (regulariser none), ``dual`` or ``primal`` (see `fit_sh`)."""
    check_choice(solver, "solver", ("auto", "primal", "dual"))
    dual_ok = regulariser != "none"
    if solver == "dual" and not dual_ok:
        raise ValueError("solver='dual' needs regulariser 'exp' or 'constant', got 'none'")
    if regulariser == "none":
        return "ridge"
    if solver == "dual" or (solver == "auto" and dual_ok and n_obs < n):
        return "dual"
    return "primal"


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

    ``penalise_dc`` and the ``dual`` solver: see the module's Notes.

    Texels with no sample of positive weight get zero coefficients; samples
    of zero weight are ignored (even NaN). Fit B and L of the same texels in
    one call by concatenating their channels: they share the normal matrix.

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
        scale as :func:`freqbrdf.sphere.sh.project_equirect` of the same function.
    """
    d, f, w64 = np.asarray(directions), np.asarray(values), np.asarray(weights, dtype=np.float64)
    lmax = check_int(lmax, "lmax", 0)
    check_choice(regulariser, "regulariser", REGULARISERS)
    lam = float(lam)
    if regulariser != "none" and not (np.isfinite(lam) and lam > 0.0):
        raise ValueError(f"lam must be a finite number > 0 for regulariser {regulariser!r}, got {lam!r}")
    _check_samples(d, f, w64)
    n_tex, n_obs = w64.shape
    n = n_coeffs(lmax)
    if chunk is None:
        chunk = max(1, _FIT_CHUNK_VALUES // max(1, n * (n_obs + n)))
    chunk = check_int(chunk, "chunk", 1)
    method = _solver_method(regulariser, solver, n_obs, n)
    reg = regulariser_diagonal(lmax, regulariser, bool(penalise_dc))
    return _solve_chunks(d, f, w64, lmax, reg, lam, method, chunk, check_int(workers, "workers", 1))


def _solve_chunks(
    d: np.ndarray, f: np.ndarray, w: np.ndarray, lmax: int, reg: np.ndarray, lam: float, method: str, chunk: int,
    workers: int,
) -> np.ndarray:
    """`fit_sh`'s coefficients (T, n, C), ``chunk`` texels at a time on ``workers`` threads."""
    n_tex = w.shape[0]
    out = np.zeros((n_tex, n_coeffs(lmax), f.shape[2]))

    def solve(start: int) -> None:
        stop = min(n_tex, start + chunk)
        out[start:stop] = _fit_chunk(d[start:stop].astype(np.float64), f[start:stop].astype(np.float64),
                                     w[start:stop], lmax, reg, lam, method)

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
    check_shape(d, "directions", (None, None, 3))
    check_shape(f, "values", (d.shape[0], d.shape[1], None))
    check_shape(w, "weights", (d.shape[0], d.shape[1]))
    n_pad = check_int(n_pad, "n_pad", 1)
    pad_weight = check_positive(pad_weight, "pad_weight")
    n_tex = d.shape[0]
    pad = np.broadcast_to(_lower_hemisphere_points(n_pad), (n_tex, n_pad, 3))
    return (
        np.concatenate([d, pad], axis=1),
        np.concatenate([f, np.zeros((n_tex, n_pad, f.shape[2]))], axis=1),
        np.concatenate([w, np.full((n_tex, n_pad), pad_weight)], axis=1),
    )


# --------------------------------------------------------------------------
# paper Fig. 3 on a capture's own samples
# --------------------------------------------------------------------------
FIT_OPTIONS = ("exp", "constant", "none", "zero_pad")
"""The fits of paper Fig. 3: the two regularisers, none, and zero-padding the lower hemisphere."""


def fit_option(option: str, directions: np.ndarray, values: np.ndarray, weights: np.ndarray, lmax: int,
               lam: float = 1e-3, penalise_dc: bool = True) -> np.ndarray:
    """`fit_sh` as one of `FIT_OPTIONS` (``zero_pad``: the unregularised fit of the samples
    plus as many zeros on the lower hemisphere as there are samples)."""
    check_choice(option, "option", FIT_OPTIONS)
    if option == "zero_pad":
        padded = zero_pad_lower_hemisphere(directions, values, weights, np.shape(weights)[1])
        return fit_sh(*padded, lmax, "none")
    return fit_sh(directions, values, weights, lmax, option, lam, penalise_dc=penalise_dc)


def spectrum_log_ratio(fitted: np.ndarray, truth: np.ndarray) -> np.ndarray:
    """``log(S_fit(l) / S_true(l))`` per texel, degree 1..lmax and channel: below 0 where a fit
    damps a degree, above where it invents power.

    Parameters
    ----------
    fitted, truth : numpy.ndarray
        Shape ``(T, (lmax+1)^2, C)``.

    Returns
    -------
    numpy.ndarray
        Shape ``(T, lmax, C)``; NaN where either power is 0.
    """
    from freqbrdf.sphere.sh import power_spectrum

    s_fit, s_true = power_spectrum(fitted)[:, 1:], power_spectrum(truth)[:, 1:]
    ok = (s_fit > 0) & (s_true > 0)
    return np.where(ok, np.log(np.where(ok, s_fit, 1.0) / np.where(ok, s_true, 1.0)), np.nan)


def fit_observations(obs: Observations, settings: Mapping[str, object], workers: int = 1) -> ShFit:
    """SH fits of a capture's B and L per texel with config ``sh`` settings (rule fit_sh).

    B, L and a channel of ones share directions and weights, so one fit serves all three;
    the ones give the DC the fit assigns to a constant (:func:`freqbrdf.estimate.spectrum.diffuse_albedo`).

    Parameters
    ----------
    obs : Observations
        T texels x K views.
    settings : mapping
        ``lmax``, ``regulariser``, ``lambda``, ``penalise_dc`` (config ``sh``).
    workers : int
        Threads.
    """
    from freqbrdf.sphere.sh import power_spectrum

    n_tex, n_views = obs.weight.shape
    values = np.concatenate([obs.radiance, obs.incoming, np.ones((n_tex, n_views, 1), np.float32)], axis=-1)
    coeffs = fit_sh(mirror_directions(np.asarray(obs.wo_local)), values, np.asarray(obs.weight), settings["lmax"],
                    regulariser=settings["regulariser"], lam=settings["lambda"],
                    penalise_dc=settings["penalise_dc"], workers=workers)
    return ShFit(coeffs_outgoing=coeffs[..., 0:3], coeffs_incoming=coeffs[..., 3:6], unit_dc=coeffs[:, 0, 6],
                 spectra_outgoing=power_spectrum(coeffs[..., 0:3]), spectra_incoming=power_spectrum(coeffs[..., 3:6]),
                 meta={"settings": dict(settings), "texels": n_tex, "observed_texels": int(obs.observed.sum()),
                       "a_prime": obs.a_prime})
