"""The shadowed light of every texel from one table per environment, instead of a fit per texel.

The mixed model's light (paper section 4.2, Eq. 11) is the SH expansion of
``Lg(n, alpha) = G1(n . w, alpha) L(w)`` over the upper hemisphere of each
texel normal ``n``, refitted as the texel's roughness moves
(`freqbrdf.estimate.light.shadowed_light`: one quadrature of the whole map per
texel and fit). Two facts make it tabulable:

- Smith's ``G1(mu, alpha(r))`` is close to a sum of a few separable terms
  ``sum_k u_k(mu) v_k(r)`` (`ShadowingBasis`: the leading singular vectors of
  ``G1`` sampled evenly in ``mu = cos theta`` and in roughness), so
  ``Lg(n, r) = sum_k v_k(r) Lg_k(n)`` with ``Lg_k`` the light times ``u_k(n . w)``,
  independent of the roughness;
- ``Lg_k(n)`` varies smoothly with the normal, so it is fitted once on an
  equirectangular grid of normals and interpolated bilinearly
  (`ShadowedLightTable`).

The table costs ``rank x 2 rows^2`` fits once per environment, where the
per-texel fits cost one per observed texel at every refit; a refit then only
interpolates. Its accuracy against the per-texel fits: docs/estimator.md.

A table depends on the environment's light only, not on the capture, so rule ``light_table``
fits it once per map (`write_light_table`) and every estimate under that map reads it
(`read_light_table`), which checks that it was fitted from the same light and size.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from freqbrdf.capture.observations import equirect_corners
from freqbrdf.estimate.light import LightQuadrature, project_factors
from freqbrdf.estimate.optimise.kernels import basis_factors
from freqbrdf.sphere.brdf import alpha_from_roughness, smith_g1, tan2_theta
from freqbrdf.sphere.sampling import equirect_directions
from freqbrdf.util.io import read_json, write_json
from freqbrdf.util.validation import check_finite, check_int, check_shape

__all__ = ["TableSize", "ShadowingBasis", "shadowing_basis", "ShadowedLightTable", "shadowed_light_table",
           "light_signature", "write_light_table", "read_light_table"]

LIGHT_TABLE_FORMAT = "freqbrdf-light-table/2"

_MU_SAMPLES = 1025  # samples of each u_k in cos theta: linear interpolation within 1e-5 of G1's own
_ROUGHNESS_SAMPLES = 257


@dataclass(frozen=True)
class TableSize:
    """Size of a `ShadowedLightTable`: ``rows`` of its grid of normals (0: no table, a fit per
    texel) and the ``rank`` of its shadowing basis."""

    rows: int
    rank: int

    def __post_init__(self) -> None:
        if check_int(self.rows, "light_table.rows", 0) == 1:
            raise ValueError("light_table.rows must be 0 (no table) or >= 2, got 1")
        check_int(self.rank, "light_table.rank", 1)


@dataclass(frozen=True)
class ShadowingBasis:
    """``G1(mu, alpha(r)) ~ sum_k u_k(mu) v_k(r)``, both factors sampled on even grids of [0, 1].

    Attributes
    ----------
    u : numpy.ndarray
        Shape ``(R, P)``, float32: ``u_k`` at ``mu = i / (P - 1)``.
    v : numpy.ndarray
        Shape ``(R, Q)``, float64: ``v_k`` at roughness ``j / (Q - 1)``.
    """

    u: np.ndarray
    v: np.ndarray

    @property
    def rank(self) -> int:
        """Number of separable terms R."""
        return int(self.u.shape[0])

    def weights(self, roughness: np.ndarray) -> np.ndarray:
        """``v_k`` at each roughness (T,), linear between samples: shape ``(T, R)``."""
        grid = np.linspace(0.0, 1.0, self.v.shape[1])
        return np.stack([np.interp(roughness, grid, vk) for vk in self.v], axis=1)


def shadowing_basis(rank: int) -> ShadowingBasis:
    """The ``rank`` leading singular terms of Smith's ``G1`` over ``mu`` and roughness in [0, 1].

    Sampled evenly in ``mu`` (so the error is weighted by solid angle) and in
    roughness (``alpha = max(r^2, ALPHA_MIN)``, `freqbrdf.sphere.brdf.alpha_from_roughness`).
    The truncation's largest error is at grazing angles, where the horizon cuts the light anyway.

    Parameters
    ----------
    rank : int
        Number of terms, >= 1.

    Returns
    -------
    ShadowingBasis
    """
    rank = check_int(rank, "rank", 1)
    mu = np.linspace(0.0, 1.0, _MU_SAMPLES)
    alpha = alpha_from_roughness(np.linspace(0.0, 1.0, _ROUGHNESS_SAMPLES))[0]
    g1 = np.where(mu[:, None] > 0, smith_g1(tan2_theta(np.maximum(mu, 1e-6))[:, None], alpha[None, :]), 0.0)
    u, s, vt = np.linalg.svd(g1, full_matrices=False)
    if rank > s.shape[0]:
        raise ValueError(f"rank must be at most {s.shape[0]}, got {rank}")
    sign = np.where(u[_MU_SAMPLES - 1, :rank] < 0, -1.0, 1.0)  # u_k(1) >= 0: a reproducible sign
    return ShadowingBasis(u=np.ascontiguousarray((u[:, :rank] * s[:rank] * sign).T, dtype=np.float32),
                          v=vt[:rank] * sign[:, None])


@dataclass(frozen=True)
class ShadowedLightTable:
    """``Lg_k`` of one environment on a grid of normals (module docstring).

    Attributes
    ----------
    basis : ShadowingBasis
        The separable terms of ``G1``.
    rows : int
        The grid of normals is equirectangular, ``rows x 2 rows`` pixel centres
        (`freqbrdf.sphere.sampling.equirect_directions`).
    coefficients : numpy.ndarray
        Shape ``(2 rows^2, R, (lmax+1)^2, C)``, float32: ``Lg_k`` at each grid normal.
    light : numpy.ndarray
        Shape ``((lmax+1)^2, C)``: `light_signature` of the light it was fitted from.
    """

    basis: ShadowingBasis
    rows: int
    coefficients: np.ndarray
    light: np.ndarray

    def check_fits(self, light: LightQuadrature, size: TableSize) -> None:
        """Raise ValueError unless this table was fitted from ``light`` at ``size``."""
        have = (self.rows, self.basis.rank, self.coefficients.shape[2])
        want = (size.rows, size.rank, (light.lmax + 1) ** 2)
        if have != want:
            raise ValueError(f"table of rows {have[0]}, rank {have[1]} and {have[2]} SH coefficients, but "
                             f"optimise.light_table asks rows {want[0]}, rank {want[1]} and the light has {want[2]}")
        signature = light_signature(light)
        # a tolerance, not equality: the table may come from another machine, whose vector maths
        # and BLAS round the same light differently in the last bits
        if self.light.shape != signature.shape or not np.allclose(
                self.light, signature, rtol=_SIGNATURE_RTOL, atol=_SIGNATURE_RTOL * np.abs(signature).max()):
            raise ValueError("table fitted from another light than this estimate's (another map, optimise.lmax "
                             "or optimise.point_sources)")

    def weights(self, normals: np.ndarray, roughness: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """How the table combines into the shadowed light of texels with these normals and roughness.

        Parameters
        ----------
        normals : numpy.ndarray
            Shape ``(T, 3)``, unit texel normals (world frame).
        roughness : numpy.ndarray
            Shape ``(T,)``, in [0, 1].

        Returns
        -------
        corner, corner_weight, v : numpy.ndarray
            Shapes ``(T, 4)`` (int64), ``(T, 4)`` and ``(T, R)``: the grid normals around each
            normal with their bilinear weights, and the basis weights at each roughness
            (`freqbrdf.estimate.optimise.kernels.table_sums`).
        """
        n = np.asarray(normals, dtype=np.float64)
        check_shape(n, "normals", (None, 3))
        r = np.asarray(roughness, dtype=np.float64)
        check_shape(r, "roughness", (n.shape[0],))
        check_finite(r, "roughness")
        corner, weight = equirect_corners(n, self.rows, 2 * self.rows)
        return corner, weight, self.basis.weights(r)  # np.interp holds the ends outside [0, 1]

    def at(self, normals: np.ndarray, roughness: np.ndarray) -> np.ndarray:
        """The shadowed light of texels with these normals and roughness (as `weights`).

        Returns
        -------
        numpy.ndarray
            Shape ``(T, (lmax+1)^2, C)``, float32, as `freqbrdf.estimate.light.shadowed_light`'s.
        """
        corner, weight, v = self.weights(normals, roughness)
        out = np.zeros((corner.shape[0],) + self.coefficients.shape[2:], np.float32)
        for j in range(corner.shape[1]):  # a texel at a time would be slow; the estimator uses table_sums
            out += np.einsum("tk,tkqc->tqc", weight[:, j, None] * v, self.coefficients[corner[:, j]]).astype(np.float32)
        return out


def shadowed_light_table(quadrature: LightQuadrature, rows: int, rank: int, workers: int = 1) -> ShadowedLightTable:
    """Fit `ShadowedLightTable` of an environment: ``rank x 2 rows^2`` quadratures of the map.

    Parameters
    ----------
    quadrature : LightQuadrature
        Nodes of the environment (`freqbrdf.estimate.light.light_quadrature`).
    rows : int
        Rows of the grid of normals (>= 2).
    rank : int
        Terms of the shadowing basis (`shadowing_basis`).
    workers : int
        Threads.

    Returns
    -------
    ShadowedLightTable
    """
    rows = check_int(rows, "rows", 2)
    basis = shadowing_basis(rank)
    grid = equirect_directions(rows, 2 * rows).reshape(-1, 3).astype(np.float32)
    r = basis.rank

    def factors(a: int, b: int, dirs: np.ndarray, out: np.ndarray) -> None:
        basis_factors(grid[a // r : b // r], dirs, basis.u, out)

    lg = project_factors(quadrature, grid.shape[0] * r, factors, workers, multiple=r)
    coefficients = lg.reshape(grid.shape[0], r, *lg.shape[1:])
    return ShadowedLightTable(basis=basis, rows=rows, coefficients=coefficients, light=light_signature(quadrature))


def light_signature(quadrature: LightQuadrature) -> np.ndarray:
    """The unshadowed light's SH coefficients, by which a table knows the light it was fitted from
    (another map, degree, pre-filter or set of point sources taken out of it changes them).

    Returns
    -------
    numpy.ndarray
        Shape ``((lmax+1)^2, C)``, float64: ``sum_q Y_lm(w_q) weighted_radiance_q``.
    """
    return quadrature.basis.T.astype(np.float64) @ np.asarray(quadrature.weighted_radiance, dtype=np.float64)


_SIGNATURE_RTOL = 1e-6  # above rounding (the SH at the nodes are float32), below any other map or sources
_TABLE_ARRAYS = ("coefficients", "u", "v", "light")


def write_light_table(directory: str | os.PathLike, table: ShadowedLightTable) -> None:
    """Write ``table`` into ``directory`` (its arrays as ``.npy``, ``table.json`` with its format
    and rows), as `freqbrdf.artefacts.write_sh_fit` writes a fit: the rule makes the directory
    whole or not at all (`freqbrdf.util.io.atomic_directory`)."""
    directory = Path(directory)
    arrays = {"coefficients": table.coefficients, "u": table.basis.u, "v": table.basis.v, "light": table.light}
    directory.mkdir(parents=True, exist_ok=True)
    for name in _TABLE_ARRAYS:
        np.save(directory / f"{name}.npy", arrays[name])
    write_json(directory / "table.json", {"format": LIGHT_TABLE_FORMAT, "rows": table.rows})


def read_light_table(directory: str | os.PathLike, light: LightQuadrature, size: TableSize) -> ShadowedLightTable:
    """Read a table of `write_light_table`, checking that it was fitted from ``light`` at ``size``.

    Raises
    ------
    ValueError
        Naming ``directory``: another format, arrays that disagree, or a table of another light
        or size (`ShadowedLightTable.check_fits`).
    """
    directory = Path(directory)
    meta = read_json(directory / "table.json")
    if meta.get("format") != LIGHT_TABLE_FORMAT:
        raise ValueError(f"{directory / 'table.json'}: format is {meta.get('format')!r}, expected "
                         f"{LIGHT_TABLE_FORMAT!r} (rerun rule light_table)")
    arrays = {name: np.load(directory / f"{name}.npy") for name in _TABLE_ARRAYS}
    rank, n_normals = arrays["u"].shape[0], 2 * int(meta["rows"]) ** 2
    if arrays["coefficients"].shape[:2] != (n_normals, rank) or arrays["v"].shape[0] != rank:
        raise ValueError(f"{directory}: arrays disagree with rows {meta['rows']} and rank {rank} "
                         f"(coefficients {arrays['coefficients'].shape}, v {arrays['v'].shape})")
    table = ShadowedLightTable(basis=ShadowingBasis(u=arrays["u"], v=arrays["v"]), rows=int(meta["rows"]),
                               coefficients=arrays["coefficients"], light=arrays["light"])
    try:
        table.check_fits(light, size)
    except ValueError as error:
        raise ValueError(f"{directory}: {error} (rerun rule light_table)") from None
    return table
