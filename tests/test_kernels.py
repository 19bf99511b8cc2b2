"""The compiled kernels against their NumPy definitions (freqbrdf.estimate.optimise.kernels)."""

import numpy as np
import pytest

from freqbrdf.estimate.optimise import compiled, compiled_lanes, compiled_light, compiled_steps, kernels
from freqbrdf.sphere.sh import real_sh, recurrence_tables, sh_degrees


@pytest.mark.parametrize("lmax", [0, 1, 2, 7, 20])
def test_degree_sums_are_per_degree_sums_of_the_expansion_times_real_sh(lmax: int) -> None:
    rng = np.random.default_rng(lmax)
    n_pairs, n_exp, n = 700, 40, (lmax + 1) ** 2
    mirror = rng.normal(size=(n_pairs, 3)) * rng.uniform(0.5, 2.0, (n_pairs, 1))  # not unit: normalised inside
    lg = rng.normal(size=(3, n, n_exp)).astype(np.float32).transpose(2, 1, 0)  # any strides
    rows = rng.integers(0, n_exp, n_pairs)
    pairs = rng.permutation(n_pairs)[:500]
    out = np.full((n_pairs, lmax + 1, 3), np.nan, np.float32)
    kernels.degree_sums(lg, rows[:500], pairs, mirror, *recurrence_tables(lmax), out)
    y = real_sh(mirror[pairs], lmax)  # (500, n)
    terms = y[:, :, None] * lg[rows[:500]].astype(np.float64)
    expected = np.stack([terms[:, sh_degrees(lmax) == l].sum(axis=1) for l in range(lmax + 1)], axis=1)
    np.testing.assert_allclose(out[pairs], expected, rtol=1e-5, atol=1e-5 * np.abs(expected).max())
    untouched = np.setdiff1d(np.arange(n_pairs), pairs)
    assert np.isnan(out[untouched]).all()


def test_small_cholesky_solve_matches_numpy() -> None:
    rng = np.random.default_rng(12)
    for _ in range(20):
        m = rng.normal(size=(5, 5))
        a = m @ m.T + 0.1 * np.eye(5)
        rhs = rng.normal(size=5)
        out = np.empty(5)
        assert compiled._solve_spd5(a.copy(), rhs, out)
        np.testing.assert_allclose(out, np.linalg.solve(a, rhs), rtol=1e-9, atol=1e-12)
    assert not compiled._solve_spd5(-np.eye(5), rhs, out)  # not positive definite


def test_the_light_kernels_compile_with_the_model_kernels_settings() -> None:
    # each file keeps its own copy: numba's cache would not see a change to the other file's
    assert compiled_light._FAST == compiled._FAST == compiled_lanes._FAST
    assert compiled_light._TEXELS == compiled_steps._TEXELS  # the model's blocks (`compiled_steps.block_bounds`)


def test_the_lanes_hermite_is_the_model_kernels_own() -> None:
    """`compiled_lanes._hermite` is a copy (numba's cache follows the defining file only): the same
    code, docstring aside, and the same flags."""
    import ast
    import inspect

    def body(function) -> str:
        tree = ast.parse(inspect.getsource(function.py_func))
        tree.body[0].body = tree.body[0].body[1:]  # the docstring
        tree.body[0].decorator_list = []
        return ast.dump(tree)

    assert body(compiled_lanes._hermite) == body(compiled._hermite)
    assert compiled_lanes._hermite.targetoptions == compiled._hermite.targetoptions


def test_the_model_kernels_see_one_type_of_view_table_whether_empty_or_tabled() -> None:
    """numba compiles a kernel once per type of its arguments, and a read-only array is another
    type than a writable one: the paper's empty view table and a cached, read-only `view_table`
    both reach the kernels read-only, so the model kernels compile once per dtype, not twice."""
    from freqbrdf.sphere.lobes import lobe_table, view_table

    n = 2
    pairs = kernels.PairData(np.arange(n + 1), np.zeros((n, 3)), np.zeros(n), np.zeros(n), np.ones((n, 3)))
    for view in (None, view_table("paper", "principled", "ggx", 4)):
        kernels.l1_loss_gradient(np.full((n, 5), 0.5), np.zeros((n, 5, 3)), pairs,
                                 kernels.KernelModel(True, lobe=lobe_table("ggx", 4), view=view))
    # every signature compiled in this process so far (the others' too, where other tests ran them)
    for kernel in (compiled.l1_kernel, compiled.lm_kernel, compiled.grid_kernel):
        views = [t for signature in kernel.signatures for t in signature if getattr(t, "ndim", 0) == 4]
        assert not any(t.mutable for t in views), (kernel.__name__, views)
        assert views or kernel is not compiled.l1_kernel


def test_every_compiled_helper_fixes_its_own_fast_math_flags() -> None:
    # numba compiles a helper that is neither inlined nor a kernel once per signature, with the
    # fast-math flags of the kernel that first calls it unless it sets its own: l1_kernel's grid
    # start gave other gradients (sphere/sky: 1.3e-5 of their sum) when l1_kernel, not
    # grid_kernel, was the first to compile _hermite in a process, and the cache kept that order's code
    from freqbrdf.capture import kernels as capture_kernels
    from freqbrdf.studies import expected_entropy

    helpers = {f"{module.__name__}.{name}": value.targetoptions
               for module in (compiled, compiled_lanes, compiled_light, compiled_steps, capture_kernels, expected_entropy)
               for name, value in vars(module).items()
               if hasattr(value, "targetoptions") and name not in module.__all__  # kernels: called from Python
               and not value.targetoptions.get("parallel") and value.targetoptions.get("inline", "never") == "never"}
    assert "freqbrdf.estimate.optimise.compiled._hermite" in helpers
    assert [name for name, options in helpers.items() if "fastmath" not in options] == []


def test_tv_kernel_matches_the_sparse_difference_operator() -> None:
    rng = np.random.default_rng(3)
    x = rng.uniform(0.0, 1.0, (40, 5))
    x[7] = x[8]  # a flat edge: sign 0
    edges = np.concatenate([rng.integers(0, 40, (120, 2)), [[7, 8]]])
    edges = edges[edges[:, 0] != edges[:, 1]]
    op = np.zeros((edges.shape[0], 40))
    op[np.arange(edges.shape[0]), edges[:, 0]] = 1.0
    op[np.arange(edges.shape[0]), edges[:, 1]] = -1.0
    tv, grad = kernels.tv_loss_gradient(x, edges)
    assert tv == pytest.approx(np.abs(op @ x).sum() / edges.shape[0], rel=1e-14)
    np.testing.assert_allclose(grad, op.T @ np.sign(op @ x) / edges.shape[0], atol=1e-15)
    with pytest.raises(ValueError, match=r"edges \(M >= 1, 2\)"):
        kernels.tv_loss_gradient(x, np.zeros((0, 2), np.int64))
    with pytest.raises(ValueError, match="edges must index the 40 rows"):
        kernels.tv_loss_gradient(x, np.array([[0, 40]]))


def test_adam_update_is_the_numpy_adam_step_bit_for_bit_then_floored() -> None:
    from freqbrdf.estimate.optimise.solve import adam_step

    rng = np.random.default_rng(4)
    x = rng.uniform(0.0, 1.0, (300, 5))
    x[:5] = [0.0, 1.0, 0.5, 0.001, 1.0]  # at the bounds: the clamp and the roughness floor act
    m1, m2 = rng.normal(0.0, 0.1, x.shape), rng.uniform(0.0, 0.01, x.shape)
    x_ref, m1_ref, m2_ref = x.copy(), m1.copy(), m2.copy()
    floor = np.array([0.0, 0.0, 0.0, 0.05, 0.0])
    for step in (1, 2, 37):
        grad = rng.normal(0.0, 1.0, x.shape)
        x_ref, m1_ref, m2_ref = adam_step(x_ref, grad, m1_ref, m2_ref, step, 0.05)
        x_ref[:, 3] = np.maximum(x_ref[:, 3], floor[3])
        kernels.adam_update(x, grad, m1, m2, step, 0.05, (0.9, 0.999), 1e-8, floor)
        np.testing.assert_array_equal(x, x_ref)
        np.testing.assert_array_equal(m1, m1_ref)
        np.testing.assert_array_equal(m2, m2_ref)
    assert x[:, 3].min() == 0.05 and x.max() <= 1.0
    with pytest.raises(ValueError, match=r"adam_update: m2 must be C-contiguous float64 of shape \(300, 5\)"):
        kernels.adam_update(x, grad, m1, m2[:, :4], 1, 0.05, (0.9, 0.999), 1e-8, floor)


def test_the_model_kernels_blocks_are_contiguous_and_split_the_work_evenly_between_threads() -> None:
    """Texels sorted by pair count, most first, as a problem stores them: equal texel counts per block
    would give the first half of the blocks (one thread's share) most of the pairs."""
    counts = np.sort(np.random.default_rng(5).integers(1, 16, 5000))[::-1]
    start = np.concatenate([[0], np.cumsum(counts)])
    for texels in (np.arange(5000), np.arange(0, 5000, 2)):  # every texel, one checkerboard colour
        bounds = compiled_steps.block_bounds(start, texels)
        assert bounds[0] == 0 and bounds[-1] == texels.size and np.all(np.diff(bounds) >= 0)
        assert len(bounds) - 1 == -(-texels.size // compiled_steps._TEXELS)
        cum = np.concatenate([[0], np.cumsum(counts[texels] + compiled_steps._TEXEL_WORK)])
        half = (len(bounds) - 1) // 2
        first, second = cum[bounds[half]], cum[-1] - cum[bounds[half]]
        assert abs(first - second) <= 1.5 * cum[-1] / (len(bounds) - 1)  # within a block's share (an odd count)
        assert cum[texels.size // 2] / cum[-1] > 0.6  # what equal texel counts would have given the first thread
