"""Error metrics of recovered SVBRDFs against ground truth."""

from __future__ import annotations

import numpy as np

PARAMETERS = ("base_color", "roughness", "metallic")


def parameter_mse(truth: dict[str, np.ndarray], estimate: dict[str, np.ndarray], texels: np.ndarray) -> dict[str, float]:
    """Mean squared error per parameter group over selected texels, and their average.

    Parameters
    ----------
    truth, estimate : dict
        ``base_color`` (R, R, 3), ``roughness`` (R, R), ``metallic`` (R, R) in [0, 1].
    texels : ndarray, shape (N,), int
        Flat indices ``i * R + j`` of the texels to score (e.g. the observed ones).

    Returns
    -------
    dict
        ``base_color``, ``roughness``, ``metallic`` (base colour averaged over
        its channels) and ``average`` (mean of the three, as in the paper's Table 2).
    """
    if len(texels) == 0:
        raise ValueError("parameter_mse: no texels to score")
    out = {}
    for name in PARAMETERS:
        if truth[name].shape != estimate[name].shape:
            raise ValueError(f"parameter_mse: {name} is {estimate[name].shape}, ground truth {truth[name].shape}")
        n = truth[name].shape[0] * truth[name].shape[1]
        t = truth[name].reshape(n, -1)[texels].astype(np.float64)
        e = estimate[name].reshape(n, -1)[texels].astype(np.float64)
        out[name] = float(np.mean((t - e) ** 2))
    out["average"] = float(np.mean([out[name] for name in PARAMETERS]))
    return out
