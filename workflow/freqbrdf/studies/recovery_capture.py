"""The synthetic capture of the recovery test (issue 12): 64 texels seen by 24 cameras, for tests and benches.

Four roughnesses (`ROUGHNESS`) x metallic 0 or 1 x random base colours, the
texel normals over the world's upper hemisphere, 24 cameras on a world
Fibonacci upper hemisphere (as the benchmark rig), a fifth of the
observations occluded at random (`recovery_texels`). Their radiance is
either the paper's model, integrated over the map's own pixels at degree 32
(`paper_model_radiance`, independent of the estimator's quadrature and
degree), or the principled BSDF's (`freqbrdf.sphere.reference.ggx_radiance`).
Used by ``tests/test_light.py`` (recovery), ``tests/test_lobes.py``,
``tests/test_point_sources.py`` and ``bench/lobe_bench.py``.
"""

from __future__ import annotations

from typing import Mapping

import numpy as np

from freqbrdf.artefacts import Observations
from freqbrdf.sphere.brdf import R0_DIELECTRIC
from freqbrdf.sphere.reference import smith_g1
from freqbrdf.sphere.sampling import equirect_directions, equirect_solid_angles, fibonacci_hemisphere
from freqbrdf.sphere.sh import real_sh, sh_degrees

__all__ = ["ORACLE_LMAX", "ROUGHNESS", "PER_VALUE", "N_VIEWS", "recovery_texels", "paper_model_radiance",
           "oracle_capture", "capture_observations"]

ORACLE_LMAX = 32  # degree of the paper's model in `paper_model_radiance`
ROUGHNESS = (0.35, 0.5, 0.7, 0.9)  # true roughness of each group of texels
PER_VALUE = 16  # texels per roughness: half dielectric, half metal
N_VIEWS = 24


def recovery_texels(seed: int) -> tuple[dict[str, np.ndarray | int], dict[str, np.ndarray]]:
    """Texels, frames, views and occlusions of the capture, and their true parameters.

    Parameters
    ----------
    seed : int
        Seed of the base colours, normals and occlusions.

    Returns
    -------
    capture : dict
        ``weight`` (T, K): ``cos theta_o`` where observed (``cos theta_o > 0.05``, 80% kept), else 0;
        ``wo_local`` (T, K, 3): unit directions to the cameras in the texel frames; ``frame``
        (T, 3, 3): rows tangent, bitangent, normal; ``texel`` (T,) atlas indices; ``resolution``
        (int) of the atlas. T = 64, K = 24.
    truth : dict
        ``roughness`` and ``metallic`` (T,), ``base_color`` (T, 3) in [0.15, 0.9].
    """
    rng = np.random.default_rng(seed)
    t = len(ROUGHNESS) * PER_VALUE
    truth = {
        "roughness": np.repeat(ROUGHNESS, PER_VALUE),
        "metallic": np.tile(np.repeat([0.0, 1.0], PER_VALUE // 2), len(ROUGHNESS)),
        "base_color": rng.uniform(0.15, 0.9, (t, 3)),
    }
    normal = rng.normal(size=(t, 3))
    normal[:, 1] = 0.5 * np.abs(normal[:, 1])
    normal /= np.linalg.norm(normal, axis=1, keepdims=True)
    helper = np.where(np.abs(normal[:, 1:2]) < 0.9, [[0.0, 1.0, 0.0]], [[1.0, 0.0, 0.0]])
    tangent = np.cross(helper, normal)
    tangent /= np.linalg.norm(tangent, axis=1, keepdims=True)
    frame = np.stack([tangent, np.cross(normal, tangent), normal], axis=1)
    wo = np.einsum("tij,kj->tki", frame, fibonacci_hemisphere(N_VIEWS))
    weight = np.where(wo[..., 2] > 0.05, wo[..., 2], 0.0) * (rng.random((t, N_VIEWS)) >= 0.2)
    capture = {"weight": weight, "wo_local": wo, "frame": frame, "texel": np.arange(t),
               "resolution": int(np.ceil(np.sqrt(t)))}
    return capture, truth


def paper_model_radiance(env: np.ndarray, capture: Mapping[str, np.ndarray],
                         truth: Mapping[str, np.ndarray]) -> np.ndarray:
    """Noise-free radiance of the paper's model on the unfiltered map at degree `ORACLE_LMAX`.

    The lobe ``exp(-(alpha l)^2)``, Schlick's Fresnel and Smith's masking at ``theta_o``, the
    Lambertian diffuse term; the shadowed light ``G1(theta_i) L`` is integrated over the map's
    own pixels per texel, not through the estimator's quadrature or its degree.

    Parameters
    ----------
    env : numpy.ndarray
        Shape ``(H, W, 3)``: equirectangular environment radiance.
    capture, truth : mapping
        As `recovery_texels` returns them (``frame``, ``wo_local``, ``weight``; the parameters).

    Returns
    -------
    numpy.ndarray
        Shape ``(T, K, 3)``, float64, radiance in the map's units; 0 where ``weight`` is 0.
    """
    frame, wo, weight = capture["frame"], capture["wo_local"], capture["weight"]
    normal = frame[:, 2]
    h, w = env.shape[:2]
    d = equirect_directions(h, w).reshape(-1, 3)
    power = (env * equirect_solid_angles(h, w)[:, None, None]).reshape(-1, 3)
    alpha = truth["roughness"] ** 2
    cos = normal @ d.T
    shadow = np.where(cos > 0, smith_g1(np.where(cos > 0, cos, 1.0), alpha[:, None]), 0.0)
    basis = real_sh(d, ORACLE_LMAX)
    lg = np.stack([(shadow * power[:, c]) @ basis for c in range(3)], axis=-1)
    mirror = np.einsum("tji,tkj->tki", frame, wo * np.array([-1.0, -1.0, 1.0]))  # reflected about the normal
    lobe = np.exp(-((alpha[:, None] * sh_degrees(ORACLE_LMAX)) ** 2))
    spec = np.einsum("tki,ti,tic->tkc", real_sh(mirror, ORACLE_LMAX), lobe, lg)
    cos_o = wo[..., 2:3]
    m, base = truth["metallic"][:, None, None], truth["base_color"][:, None, :]
    r0 = R0_DIELECTRIC * (1 - m) + m * base
    fresnel = r0 + (1 - r0) * (1 - np.clip(cos_o, 0, 1)) ** 5
    masking = smith_g1(np.clip(cos_o, 1e-6, 1), alpha[:, None, None])
    irradiance = np.maximum(cos, 0.0) @ power
    radiance = (1 - m) * base * irradiance[:, None, :] / np.pi + fresnel * masking * spec
    return np.where(weight[..., None] > 0, radiance, 0.0)


def oracle_capture(env: np.ndarray, seed: int) -> tuple[dict[str, np.ndarray | int], dict[str, np.ndarray]]:
    """`recovery_texels` with the radiance of `paper_model_radiance` under ``env`` (key ``radiance``).

    Parameters
    ----------
    env : numpy.ndarray
        Shape ``(H, W, 3)``: equirectangular environment radiance.
    seed : int
        Seed of `recovery_texels`.

    Returns
    -------
    capture, truth : dict
        As `recovery_texels`, ``capture`` with ``radiance`` (T, K, 3) added.
    """
    capture, truth = recovery_texels(seed)
    return {"radiance": paper_model_radiance(env, capture, truth)} | capture, truth


def capture_observations(capture: Mapping[str, np.ndarray | int]) -> Observations:
    """The capture as `freqbrdf.artefacts.Observations` (``radiance`` (T, K, 3) and the keys of
    `recovery_texels`)."""
    return Observations.from_arrays(*(capture[k] for k in ("radiance", "weight", "wo_local", "frame", "texel",
                                                           "resolution")))
