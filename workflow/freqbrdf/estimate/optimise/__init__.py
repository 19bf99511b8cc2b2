"""Gradient-descent SVBRDF estimator: the "mixed" pipeline (paper sections 4.1 and 4.3, Eqs. 11 and 13).

Per texel p the parameters are the base colour (RGB), roughness r and
metallic m, all in [0, 1]; ``alpha = max(r^2, 1e-3)`` as in Mitsuba's
``principled`` BSDF. For every observation (p, w_o) the model predicts

    B(p, w_o) = (1 - m) base d E(p) / pi + F(theta_o) G1m(theta_o) Spec(p, w_r)

- ``E(p)``: irradiance at the texel normal from the whole environment
  (an input, e.g. :func:`freqbrdf.estimate.light.irradiance`);
- ``F = R0 + (1 - R0)(1 - cos theta_o)^5``, ``R0 = 0.04 (1 - m) + m base``;
- ``G1(theta) = 2 / (1 + sqrt(1 + alpha^2 tan^2 theta))`` (GGX Smith); the
  masking term ``G1m = G1(theta_o)``;
- ``Spec = sum_{l <= l*} exp(-(alpha l)^2) sum_m Lg_lm Y_lm(w_r)``: the
  specular lobe as an SH filter at the world mirror direction ``w_r``, where
  ``Lg`` is the shadowed light ``G1(theta_i) L`` over the texel's upper
  hemisphere, integrated from the known environment map per texel normal
  and roughness (:func:`freqbrdf.estimate.light.shadowed_light`; paper section 4.2);
- ``d = 1`` (the paper's Lambertian term), or with ``diffuse="principled"`` the view
  dependence of the principled BSDF's diffuse lobe; ``view_weight="albedo"`` replaces
  ``F G1m`` by GGX's directional albedo (both: :func:`freqbrdf.sphere.lobes.view_table`).

Beyond the paper, the map's compact bright sources can leave ``Lg`` (`model_light`,
:func:`freqbrdf.estimate.light.extract_point_sources`): each adds the exact GGX microfacet term
``D G1(theta_i) G1m F(h.w_o) P / (4 cos theta_o)`` of its direction and power ``P`` to the
specular part (`point_terms`, ``freqbrdf.estimate.optimise.kernels._point_source``), which the SH at degree l*
would blur.

``Lg`` depends on alpha, so it is refitted every ``refit_every`` iterations
(for the texels whose roughness moved by more than ``refit_tolerance``)
and held constant in between (no gradient through the refit, as in the
authors' code). After a refit, `light_terms` stores the per-degree
contributions ``P[n, l, c] = sum_m Lg_lm,c Y_lm(w_r,n)`` of every observation
n, so ``Spec = sum_l exp(-(alpha l)^2) P[n, l]`` is cheap to evaluate and to
differentiate with respect to alpha.

Methods (the ``optimise_svbrdf`` entries of :data:`freqbrdf.methods.METHODS`):
``freq`` (shadowing and masking), ``freq_paper``
(the same on the light pre-filtered by the views' band limit a', as the
paper does: the fitted lobe then has width ``sqrt(alpha^2 + a'^2)``),
``freq_noshadow`` (``G1(theta_i) = 1``: the environment's own SH),
``freq_nomask`` (``G1m = 1``) and ``rh2001`` (neither: Ramamoorthi and
Hanrahan 2001).

Objective
---------
``loss = mean_{observed (p, k), c} |B_model - B_observed| + tv_weight * TV``:
the L1 data term is a plain mean over observed pairs (``weight > 0``) and the
three colour channels (observations are not weighted by cos theta_o). TV is the
anisotropic total variation of the parameter textures in UV space,

    TV = (1 / M) sum_{(i, j)} sum_q |x_iq - x_jq|,

over the M pairs of horizontally or vertically adjacent atlas texels that are
both among the T texels (flat index ``i * R + j``), summed over the five
parameter channels q (base R, G, B, roughness, metallic). Dividing by M makes
TV a mean absolute step per adjacency, like the data term a mean, so
``tv_weight`` keeps its meaning across texture resolutions and atlas
coverage. Both absolute values use ``sign(0) = 0`` as their derivative.

Gradients are analytic (see `loss_and_gradient`). Two solvers minimise the
objective (``OptimiseSettings.solver``):

- ``adam`` (default, as the authors' code): Adam (`adam_step`) updates all
  texels and views in one batch and clamps the parameters to [0, 1] after
  each step;
- ``lm``: per-texel Levenberg-Marquardt (:func:`freqbrdf.estimate.optimise.kernels.lm_sweep`).
  The 5 unknowns of a texel couple to other texels only through TV, so
  each sweep updates one colour of the atlas's checkerboard with the other
  held fixed, then the other colour (block coordinate descent); both
  absolute values are reweighted into least squares (IRLS), and a step is
  kept only if it lowers the texel's objective. On the tuning set it
  reaches a lower objective in 12 sweeps than Adam in 150 steps, but a
  higher parameter error (docs/estimator.md, "Second-order solver").

Without shadowing the fitted light does not depend on alpha, so
``freq_noshadow`` and ``rh2001`` fit it once.

Layout and cost
---------------
Only observed pairs are stored (`build_problem`; a 24-view capture observes
about 30% of its texel-view pairs), sorted by texel, so a texel's pairs are
one contiguous run. The per-pair work (light terms, loss, gradient, grid
start) runs in compiled kernels (:mod:`freqbrdf.estimate.optimise.kernels`) over texels on
``workers`` threads; each texel's sums are its own and the per-texel results
are summed in texel order, so results do not depend on the number of
threads. Timings are measured by ``bench/optimise_bench.py``.
"""
