"""Mitsuba 3 scenes and rendering for the synthetic benchmark.

Every function takes the ``mitsuba`` module as its first argument instead of
importing it, so the variant is chosen once by the entry script
(:func:`freqbrdf.util.mitsuba_setup.setup_mitsuba`) and importing this module has
no side effect.
"""

from __future__ import annotations

from collections.abc import Iterator, Sequence
from pathlib import Path
from types import ModuleType

import numpy as np

from freqbrdf.scene.cameras import Cameras, mitsuba_to_world
from freqbrdf.sphere.sh import angles_to_directions
from freqbrdf.sphere.sampling import equirect_directions


def bitmap_texture(mi: ModuleType, array: np.ndarray) -> dict:
    """Mitsuba ``bitmap`` texture dictionary holding ``array`` as float32.

    The data are passed raw (no sRGB decoding, no spectral upsampling):
    textures hold linear values, and an 8-bit conversion would quantise them.

    Parameters
    ----------
    mi : module
        Mitsuba, with a variant set.
    array : ndarray, shape (H, W) or (H, W, 3)
        Texel values; row 0 is v = 0.

    Returns
    -------
    dict
    """
    data = np.asarray(array, dtype=np.float32)
    if data.ndim == 2:
        data = data[..., None]
    return {
        "type": "bitmap",
        "bitmap": mi.Bitmap(np.ascontiguousarray(data)),
        "raw": True,
        "filter_type": "bilinear",
        "wrap_mode": "repeat",
    }


def principled_bsdf(mi: ModuleType, base_color: np.ndarray, roughness: np.ndarray, metallic: np.ndarray,
                    clearcoat: float = 0.0, clearcoat_gloss: float = 0.0) -> dict:
    """Mitsuba ``principled`` BSDF driven by SVBRDF textures.

    Parameters
    ----------
    base_color : ndarray, shape (H, W, 3)
    roughness, metallic : ndarray, shape (H, W)
        All in [0, 1]; Mitsuba uses ``alpha = roughness**2``.
    clearcoat, clearcoat_gloss : float
        Weight and gloss of the principled model's clear-coat lobe, which the
        estimators do not model (0: none, as in the benchmark captures).

    Returns
    -------
    dict
    """
    bsdf = {
        "type": "principled",
        "base_color": bitmap_texture(mi, base_color),
        "roughness": bitmap_texture(mi, roughness),
        "metallic": bitmap_texture(mi, metallic),
    }
    if clearcoat > 0.0:
        bsdf |= {"clearcoat": float(clearcoat), "clearcoat_gloss": float(clearcoat_gloss)}
    return bsdf


def blend_bsdf(mi: ModuleType, base_color: np.ndarray, roughness: np.ndarray, metallic: np.ndarray,
               distribution: str) -> dict:
    """The principled BSDF's two lobes rebuilt from Mitsuba's rough conductor, with a chosen
    microfacet distribution (``principled`` is GGX only).

    A ``metallic`` blend of a dielectric (Lambertian ``base_color`` plus a specular lobe
    with the Fresnel term of index 1.5, which a conductor of eta 1.5, k 0 has) and a
    metal (specular lobe tinted by ``base_color``, no Fresnel falloff). With
    ``distribution="beckmann"`` the captures break the GGX assumption of every
    estimator; ``"ggx"`` is the control that isolates the distribution from the
    other differences to ``principled`` (its diffuse and Fresnel models).

    Parameters
    ----------
    base_color : ndarray, shape (H, W, 3)
    roughness, metallic : ndarray, shape (H, W)
        In [0, 1]; ``alpha = roughness**2`` as in :func:`principled_bsdf`.
    distribution : {"ggx", "beckmann"}

    Returns
    -------
    dict
    """
    if distribution not in ("ggx", "beckmann"):
        raise ValueError(f"blend_bsdf: distribution must be 'ggx' or 'beckmann', got {distribution!r}")
    alpha = np.maximum(np.asarray(roughness, dtype=np.float32) ** 2, 1e-3)  # Mitsuba's principled clamps alike
    lobe = {"type": "roughconductor", "distribution": distribution}
    # blendbsdf is a convex combination: each half of the dielectric is doubled to sum the two lobes.
    dielectric = {
        "type": "blendbsdf",
        "weight": 0.5,
        "diffuse": {"type": "diffuse", "reflectance": bitmap_texture(mi, 2.0 * np.asarray(base_color))},
        "specular": lobe | {"alpha": bitmap_texture(mi, alpha), "eta": 1.5, "k": 0.0, "specular_reflectance": 2.0},
    }
    metal = lobe | {"alpha": bitmap_texture(mi, alpha), "material": "none",
                    "specular_reflectance": bitmap_texture(mi, base_color)}
    return {"type": "blendbsdf", "weight": bitmap_texture(mi, metallic), "dielectric": dielectric, "metal": metal}


BSDF_MODELS = ("principled", "ggx_blend", "beckmann_blend")
"""Ground-truth BSDFs of a capture: `principled_bsdf` (the estimators' model), or `blend_bsdf`
with a GGX (control) or Beckmann (mismatched) distribution."""


def capture_bsdf(mi: ModuleType, textures: dict, model: str = "principled", clearcoat: float = 0.0,
                 clearcoat_gloss: float = 0.0) -> dict:
    """The BSDF a capture is rendered with, by name (:data:`BSDF_MODELS`).

    Parameters
    ----------
    textures : dict
        ``base_color`` (H, W, 3), ``roughness`` and ``metallic`` (H, W).
    model : str
        One of :data:`BSDF_MODELS`.
    clearcoat, clearcoat_gloss : float
        Clear coat of the ``principled`` model (:func:`principled_bsdf`).

    Returns
    -------
    dict
    """
    if model not in BSDF_MODELS:
        raise ValueError(f"BSDF model must be one of {BSDF_MODELS}, got {model!r}")
    if model == "principled":
        return principled_bsdf(mi, **textures, clearcoat=clearcoat, clearcoat_gloss=clearcoat_gloss)
    if clearcoat > 0.0:
        raise ValueError(f"a clear coat needs the principled model, not {model!r}")
    return blend_bsdf(mi, **textures, distribution=model.removesuffix("_blend"))


def occluder_disk(mi: ModuleType, height: float, radius: float) -> dict:
    """A black horizontal disk centred under the object at ``y = height``: it shadows light
    from below for the object's lower part and, lying below the object, never hides the
    object from a camera on the upper hemisphere (issue 17's unseen occluder).

    Parameters
    ----------
    height : float
        Plane of the disk (object radius 1; must be below the object's lowest point).
    radius : float
        Disk radius (> 0).

    Returns
    -------
    dict
    """
    if not radius > 0.0:
        raise ValueError(f"occluder radius must be > 0, got {radius}")
    to_world = mi.ScalarTransform4f().translate([0.0, float(height), 0.0]) @ mi.ScalarTransform4f().rotate(
        [1.0, 0.0, 0.0], -90.0) @ mi.ScalarTransform4f().scale(float(radius))
    return {"type": "disk", "to_world": to_world, "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}}}


def _sensor(mi: ModuleType, width: int, height: int, fov_x_deg: float, spp: int) -> dict:
    return {
        "type": "perspective",
        "fov": float(fov_x_deg),
        "fov_axis": "x",
        "near_clip": 0.01,
        "to_world": mi.ScalarTransform4f(),
        # A box filter makes each pixel the mean radiance over its footprint,
        # which is what the per-texel observations sample later.
        "film": {"type": "hdrfilm", "width": int(width), "height": int(height), "rfilter": {"type": "box"}, "pixel_format": "rgb"},
        "sampler": {"type": "independent", "sample_count": int(spp)},
    }


def capture_scene(
    mi: ModuleType,
    mesh: str | Path,
    bsdf: dict,
    envmap: np.ndarray,
    *,
    width: int,
    height: int,
    fov_x_deg: float,
    spp: int,
    max_depth: int,
    integrator: str = "path",
    occluders: Sequence[dict] = (),
):
    """The object lit by an environment map, seen by one movable camera.

    Parameters
    ----------
    mesh : path-like
        PLY mesh with normals and uvs.
    bsdf : dict
        Mitsuba BSDF dictionary (e.g. :func:`principled_bsdf`).
    envmap : ndarray, shape (H, 2H, 3)
        Equirectangular radiance.
    width, height : int
        Image size in pixels.
    fov_x_deg : float
        Horizontal field of view.
    spp : int
        Samples per pixel.
    max_depth : int
        Path length limit of the integrator (-1: unlimited).
    integrator : {"path", "prb"}
        ``path`` renders the captures; ``prb`` (path replay backpropagation)
        renders the same light transport and also differentiates it, for
        inverse rendering (:mod:`freqbrdf.estimate.mitsuba`).
    occluders : sequence of dict
        Further Mitsuba shapes in the scene, e.g. :func:`occluder_disk`.

    Returns
    -------
    mitsuba.Scene
    """
    if integrator not in ("path", "prb"):
        raise ValueError(f"capture_scene: integrator must be 'path' or 'prb', got {integrator!r}")
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": integrator, "max_depth": int(max_depth)},
            "emitter": {"type": "envmap", "bitmap": mi.Bitmap(np.ascontiguousarray(envmap, dtype=np.float32))},
            "object": {"type": "ply", "filename": str(mesh), "bsdf": bsdf},
            "sensor": _sensor(mi, width, height, fov_x_deg, spp),
        }
        | {f"occluder_{k}": shape for k, shape in enumerate(occluders)}
    )


def mask_scene(mi: ModuleType, mesh: str | Path, *, width: int, height: int, fov_x_deg: float, spp: int):
    """A scene whose render is the object's pixel coverage in [0, 1].

    The object is a unit-radiance area emitter seen directly (path length 1):
    each pixel's value is the fraction of its footprint the object covers.
    (With an environment map, Mitsuba's film alpha is 1 everywhere, so it
    cannot serve as a mask.)
    """
    return mi.load_dict(
        {
            "type": "scene",
            "integrator": {"type": "path", "max_depth": 1},
            "object": {
                "type": "ply",
                "filename": str(mesh),
                "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": 0.0}},
                "emitter": {"type": "area", "radiance": {"type": "rgb", "value": 1.0}},
            },
            "sensor": _sensor(mi, width, height, fov_x_deg, spp),
        }
    )


def render_views(mi: ModuleType, scene, to_world: np.ndarray, seed: int) -> Iterator[np.ndarray]:
    """Render ``scene`` from each camera pose in turn.

    The sensor pose is updated in place, so Dr.Jit compiles the render kernel
    once and reuses it for every view.

    Parameters
    ----------
    scene : mitsuba.Scene
        Scene with a sensor named ``sensor``.
    to_world : ndarray, shape (N, 4, 4)
        Mitsuba camera-to-world matrices (:func:`freqbrdf.scene.cameras.mitsuba_to_world`).
    seed : int
        Base seed (32-bit); view ``k`` mixes ``k`` into it, so every view has
        its own deterministic noise.

    Yields
    ------
    ndarray, shape (H, W, 3), float32
        Linear radiance.
    """
    params = mi.traverse(scene)
    for k, matrix in enumerate(np.asarray(to_world, dtype=np.float64)):
        params["sensor.to_world"] = mi.ScalarTransform4f(matrix)
        params.update()
        # Mitsuba seeds are uint32; the golden-ratio stride decorrelates views.
        view_seed = (int(seed) + k * 0x9E3779B1) & 0xFFFFFFFF
        image = mi.render(scene, params=params, seed=view_seed)
        yield np.array(image, dtype=np.float32)


def relit_views(
    mi: ModuleType,
    mesh: str | Path,
    textures: dict[str, np.ndarray],
    envmap: np.ndarray,
    cameras: Cameras,
    *,
    fov_x_deg: float,
    spp: int,
    max_depth: int,
    seed: int,
) -> Iterator[np.ndarray]:
    """SVBRDF textures on the mesh under an environment, rendered from every camera.

    The scene and sample sequence of the reference views (rule
    ``render_capture``) when given their settings and seed, so that the true
    textures reproduce the reference images, noise and all.

    Parameters
    ----------
    textures : dict
        ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R), in [0, 1].
    envmap : ndarray, shape (H, 2H, 3)
        Equirectangular radiance.
    cameras : Cameras
        Poses (OpenCV convention) and image size of the views.
    fov_x_deg, spp, max_depth, seed
        As for :func:`capture_scene` and :func:`render_views`.

    Yields
    ------
    ndarray, shape (H, W, 3), float32
        Linear radiance of each view in turn.
    """
    scene = capture_scene(mi, mesh, principled_bsdf(mi, **textures), envmap, width=cameras.width,
                          height=cameras.height, fov_x_deg=fov_x_deg, spp=spp, max_depth=max_depth)
    to_world = np.stack([mitsuba_to_world(m) for m in cameras.world_to_camera])
    yield from render_views(mi, scene, to_world, seed)


def _cell_directions(height: int, width: int, rows: np.ndarray, cols: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Stratified sub-pixel directions and sin(theta) weights for the given pixels.

    Returns directions (P, s*s, 3) and weights (P, s*s) for the pixels (rows[p], cols[p]).
    """
    dtheta = np.pi / (height - 1)
    dphi = 2.0 * np.pi / width
    offs = (np.arange(s) + 0.5) / s - 0.5
    theta = np.clip(np.pi * rows[:, None, None] / (height - 1) + dtheta * offs[None, :, None], 0.0, np.pi)
    phi = 2.0 * np.pi * (cols[:, None, None] + 0.5) / width + dphi * offs[None, None, :]
    dirs = angles_to_directions(theta, phi)
    st = np.broadcast_to(np.sin(theta), dirs.shape[:-1])
    return dirs.reshape(len(rows), s * s, 3), np.maximum(st, 1e-12).reshape(len(rows), s * s)


def eval_environment(mi: ModuleType, scene, dirs: np.ndarray) -> np.ndarray:
    """Radiance of the scene's environment emitter seen along ``dirs`` (P, 3) -> (P, 3)."""
    # Rays that escape an empty scene give exactly the interaction records the
    # integrators pass to the emitter; a hand-made SurfaceInteraction does not
    # (sunsky then misplaces the sun).
    rays = mi.Ray3f(mi.Point3f(0.0, 0.0, 0.0), mi.Vector3f(dirs[:, 0], dirs[:, 1], dirs[:, 2]))
    values = np.array(scene.environment().eval(scene.ray_intersect(rays)), dtype=np.float64)
    return (values if values.shape[0] == len(dirs) else values.T)[:, :3]


def bake_emitter(
    mi: ModuleType,
    emitter: dict,
    height: int,
    *,
    supersample: int = 2,
    hotspot: np.ndarray | None = None,
    hotspot_pixels: int = 3,
    hotspot_supersample: int = 48,
) -> np.ndarray:
    """Bake an environment emitter (e.g. ``sunsky``) into an equirect map.

    Each pixel holds the solid-angle weighted mean radiance over its cell, so
    a light smaller than a pixel (the sun) keeps its energy. Pixels within
    ``hotspot_pixels`` of ``hotspot`` are sampled much more densely.

    Parameters
    ----------
    emitter : dict
        Mitsuba emitter dictionary.
    height : int
        Map height H (width 2H).
    supersample : int
        Samples per pixel along each axis.
    hotspot : ndarray, shape (3,), optional
        Unit direction of a small, very bright feature.

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    width = 2 * height
    scene = mi.load_dict({"type": "scene", "environment": emitter})
    out = np.empty((height, width, 3))
    rows_all, cols_all = np.divmod(np.arange(height * width), width)
    for start in range(0, height * width, 65536):
        rows, cols = rows_all[start : start + 65536], cols_all[start : start + 65536]
        dirs, w = _cell_directions(height, width, rows, cols, supersample)
        values = eval_environment(mi, scene, dirs.reshape(-1, 3)).reshape(len(rows), -1, 3)
        out[rows, cols] = np.einsum("ps,psc->pc", w, values) / w.sum(axis=1, keepdims=True)
    if hotspot is not None:
        grid = equirect_directions(height, width)
        angle = np.arccos(np.clip(grid @ np.asarray(hotspot, dtype=np.float64), -1.0, 1.0))
        rows, cols = np.nonzero(angle < hotspot_pixels * np.pi / (height - 1))
        dirs, w = _cell_directions(height, width, rows, cols, hotspot_supersample)
        values = eval_environment(mi, scene, dirs.reshape(-1, 3)).reshape(len(rows), -1, 3)
        out[rows, cols] = np.einsum("ps,psc->pc", w, values) / w.sum(axis=1, keepdims=True)
    return out


def sunsky(mi: ModuleType, height: int, sun_direction: np.ndarray, turbidity: float) -> np.ndarray:
    """Mitsuba's ``sunsky`` emitter (sky plus sun) baked to an equirect map.

    Parameters
    ----------
    height : int
        Map height H (width 2H).
    sun_direction : ndarray, shape (3,)
        Unit world direction toward the sun (world +Y up).
    turbidity : float
        Atmospheric turbidity (2: very clear, 10: hazy).

    Returns
    -------
    ndarray, shape (H, 2H, 3), float64
    """
    sun = np.asarray(sun_direction, dtype=np.float64)
    emitter = {
        "type": "sunsky",
        "sun_direction": sun.tolist(),
        "turbidity": float(turbidity),
        # sunsky's local frame is Z-up (measured: it puts any sun with z < 0
        # below the horizon); rotate it into our Y-up world. sun_direction is
        # read in world coordinates.
        "to_world": mi.ScalarTransform4f().rotate(axis=[1.0, 0.0, 0.0], angle=-90.0),
    }
    return bake_emitter(mi, emitter, height, hotspot=sun)

