"""Tests for freqbrdf.estimate.light_table: the shadowed light from one table per environment."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from freqbrdf.estimate import light as lt
from freqbrdf.estimate.light_table import (TableSize, light_signature, read_light_table, shadowed_light_table,
                                          shadowing_basis, write_light_table)
from freqbrdf.estimate.optimise.kernels import degree_sums, table_sums
from freqbrdf.scene import envmaps
from freqbrdf.sphere import sampling, sh
from freqbrdf.sphere.brdf import alpha_from_roughness, smith_g1, tan2_theta

LMAX = 8


@pytest.fixture(scope="module")
def studio() -> lt.LightQuadrature:
    return lt.light_quadrature(envmaps.normalise(envmaps.studio(128, seed=1), 1.0), LMAX)


def random_normals(n: int, seed: int) -> np.ndarray:
    v = np.random.default_rng(seed).normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def relative_error(approx: np.ndarray, exact: np.ndarray) -> float:
    return float(np.linalg.norm(approx - exact) / np.linalg.norm(exact))


@pytest.mark.parametrize(("rank", "bound"), [(2, 0.11), (4, 0.021), (6, 0.0056)])
def test_the_basis_is_within_its_truncation_error_of_smith_g1(rank: int, bound: float) -> None:
    """Away from grazing angles (cos theta > 0.05) the rank-R terms stay within the error the
    singular values allow; the error falls with the rank; the signs are fixed (u_k(1) >= 0)."""
    basis = shadowing_basis(rank)
    mu = np.linspace(0.05, 1.0, 301)
    roughness = np.linspace(0.0, 1.0, 101)
    u = np.stack([np.interp(mu, np.linspace(0.0, 1.0, basis.u.shape[1]), uk) for uk in basis.u])
    approx = basis.weights(roughness) @ u  # (roughness, mu)
    exact = smith_g1(tan2_theta(mu)[None, :], alpha_from_roughness(roughness)[0][:, None])
    assert np.abs(approx - exact).max() < bound
    assert (basis.u[:, -1] >= 0).all()


def test_size_is_checked_with_the_config_key_named() -> None:
    with pytest.raises(ValueError, match="light_table.rows must be 0 .* got 1"):
        TableSize(rows=1, rank=4)
    with pytest.raises(ValueError, match="light_table.rank"):
        TableSize(rows=32, rank=0)
    with pytest.raises(ValueError, match="rank must be at most"):
        shadowing_basis(10_000)


def test_at_the_grid_normals_the_table_is_the_per_texel_fit_up_to_the_basis(studio: lt.LightQuadrature) -> None:
    """No interpolation at the grid's own normals: what is left is the basis's truncation."""
    rows = 8
    table = shadowed_light_table(studio, rows, rank=6)
    grid = sampling.equirect_directions(rows, 2 * rows).reshape(-1, 3)[2 * rows : 4 * rows]  # off the poles
    roughness = np.random.default_rng(0).uniform(0.0, 1.0, grid.shape[0])
    exact = lt.shadowed_light(studio, grid, alpha_from_roughness(roughness)[0]).astype(np.float64)
    assert relative_error(table.at(grid, roughness), exact) < 0.003


def test_between_grid_normals_the_error_falls_as_the_grid_refines(studio: lt.LightQuadrature) -> None:
    normals = random_normals(400, seed=1)
    roughness = np.random.default_rng(2).uniform(0.0, 1.0, 400)
    exact = lt.shadowed_light(studio, normals, alpha_from_roughness(roughness)[0]).astype(np.float64)
    errors = [relative_error(shadowed_light_table(studio, rows, 4).at(normals, roughness), exact) for rows in (8, 16, 32)]
    assert errors[0] > errors[1] > errors[2]
    assert errors[2] < 0.02, errors


def test_table_sums_are_the_degree_sums_of_the_interpolated_light(studio: lt.LightQuadrature) -> None:
    """The fused kernel against `at` then the SH evaluated by `freqbrdf.sphere.sh.real_sh`; pairs of
    texels not refitted keep their values."""
    rng = np.random.default_rng(3)
    n_tex = 50
    counts = rng.integers(1, 6, n_tex)
    start = np.concatenate([[0], np.cumsum(counts)]).astype(np.int64)
    mirror = random_normals(int(start[-1]), seed=4)
    normals, roughness = random_normals(n_tex, seed=5), rng.uniform(0.0, 1.0, n_tex)
    table = shadowed_light_table(studio, 12, 4)
    slots = np.arange(0, n_tex, 2, dtype=np.int64)
    a, b = sh.recurrence_tables(LMAX)
    out = np.full((mirror.shape[0], LMAX + 1, 3), -7.0, np.float32)
    coefficients = table.coefficients.reshape(*table.coefficients.shape[:2], -1)
    table_sums(coefficients, *table.weights(normals[slots], roughness[slots]), slots, start, mirror, a, b, out)
    lg = table.at(normals[slots], roughness[slots]).astype(np.float64)
    y = sh.real_sh(mirror, LMAX)
    degree = np.floor(np.sqrt(np.arange((LMAX + 1) ** 2))).astype(int)
    for i, s in enumerate(slots):
        for p in range(start[s], start[s + 1]):
            expected = np.stack([(lg[i][degree == l] * y[p, degree == l, None]).sum(axis=0) for l in range(LMAX + 1)])
            np.testing.assert_allclose(out[p], expected, rtol=1e-4, atol=1e-5)
    skipped = np.concatenate([np.arange(start[s], start[s + 1]) for s in range(1, n_tex, 2)])
    assert (out[skipped] == -7.0).all()
    # and the same numbers as the general kernel on the same light
    rows = np.repeat(np.arange(slots.shape[0]), counts[slots])
    pairs = np.concatenate([np.arange(start[s], start[s + 1]) for s in slots])
    general = np.zeros_like(out)
    degree_sums(lg.astype(np.float32), rows, pairs, mirror, a, b, general)
    np.testing.assert_allclose(out[pairs], general[pairs], rtol=1e-4, atol=1e-5)


def test_a_written_table_reads_back_the_same(studio: lt.LightQuadrature, tmp_path) -> None:
    table = shadowed_light_table(studio, 6, 4)
    write_light_table(tmp_path / "t", table)
    back = read_light_table(tmp_path / "t", studio, TableSize(rows=6, rank=4))
    assert back.rows == 6
    np.testing.assert_array_equal(back.light, light_signature(studio))
    assert back.coefficients.dtype == np.float32
    np.testing.assert_array_equal(back.coefficients, table.coefficients)
    np.testing.assert_array_equal(back.basis.u, table.basis.u)
    np.testing.assert_array_equal(back.basis.v, table.basis.v)


def test_a_table_of_another_light_or_size_is_refused_naming_its_directory(studio: lt.LightQuadrature,
                                                                         tmp_path) -> None:
    """Another map, another degree, another size: each one line naming the table and the rule to
    rerun; the signature sees a change of the map's radiance alone, but not a rounding error."""
    write_light_table(tmp_path / "t", shadowed_light_table(studio, 6, 4))
    brighter = lt.light_quadrature(envmaps.normalise(envmaps.studio(128, seed=1), 1.5), LMAX)
    other_degree = lt.light_quadrature(envmaps.normalise(envmaps.studio(128, seed=1), 1.0), LMAX - 1)
    size = TableSize(rows=6, rank=4)
    with pytest.raises(ValueError, match=r"t: table fitted from another light .*rerun rule light_table"):
        read_light_table(tmp_path / "t", brighter, size)
    rounded = dataclasses.replace(studio, weighted_radiance=studio.weighted_radiance * (1.0 + 1e-9))
    assert read_light_table(tmp_path / "t", rounded, size).rows == 6
    with pytest.raises(ValueError, match=r"t: table of rows 6, rank 4 and 81 SH coefficients, .* the light has 64"):
        read_light_table(tmp_path / "t", other_degree, size)
    with pytest.raises(ValueError, match=r"asks rows 8, rank 4"):
        read_light_table(tmp_path / "t", studio, TableSize(rows=8, rank=4))
    (tmp_path / "t" / "table.json").write_text('{"format": "freqbrdf-light-table/1"}')
    with pytest.raises(ValueError, match=r"table.json: format is 'freqbrdf-light-table/1'"):
        read_light_table(tmp_path / "t", studio, size)
