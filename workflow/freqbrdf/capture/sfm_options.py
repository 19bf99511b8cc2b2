"""Settings of the COLMAP reconstruction (config ``poses.colmap``) and the pycolmap option objects they fill."""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:  # pragma: no cover
    import pycolmap

CONFIG_PREFIX = "poses.colmap."
"""Prefix of :class:`SfmOptions` fields in the pipeline's configuration."""

CAMERA_MODELS = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")


@dataclass(frozen=True)
class SfmOptions:
    """Settings of the COLMAP reconstruction; every field is the config key ``poses.colmap.{field}``.

    The defaults are tuned on the default captures (24 views, 256 x 256,
    64 spp, sphere and torus with grained textures, studio and sunny light;
    docs/captures.md, "Poses"): more and affine-adapted SIFT features (lower
    ``peak_threshold``, ``estimate_affine_shape``), a looser ratio test with
    tighter geometric thresholds (``max_ratio`` 0.9, ``two_view_max_error``
    and ``filter_max_reproj_error`` 1 px: at 2 px the median errors double),
    a light denoise against Monte Carlo noise, image pairs verified from
    fewer inliers (``two_view_min_num_inliers``, ``min_num_matches`` 10),
    and a mapper that starts and grows from fewer inliers and tries harder
    (``init_min_num_inliers`` 30, ``abs_pose_min_num_inliers`` 10,
    ``abs_pose_min_inlier_ratio`` 0.15, ``max_reg_trials`` 10), which
    registers the near-horizon views that see the torus almost edge-on.

    Attributes
    ----------
    max_num_features : int
        SIFT features kept per image (largest scales first).
    first_octave : int
        First octave of the SIFT pyramid; -1 upsamples the image twice first,
        which finds the small-scale features of low-resolution views.
    num_octaves, octave_resolution : int
        Octaves of the SIFT pyramid and levels per octave.
    peak_threshold : float
        SIFT detection threshold on the difference of Gaussians (image values
        in [0, 1]); lower finds more, weaker features.
    edge_threshold : float
        SIFT edge-response rejection threshold; higher keeps more features on edges.
    estimate_affine_shape, domain_size_pooling : bool
        SIFT variants (affine-adapted regions; DSP-SIFT descriptors).
    max_ratio, max_distance : float
        Lowe's ratio test and the largest descriptor distance of a match.
    cross_check : bool
        Keep only mutual nearest-neighbour matches.
    guided_matching : bool
        Rematch with the estimated two-view geometry.
    two_view_min_num_inliers : int
        Inlier matches for an image pair to count as verified.
    two_view_max_error : float
        RANSAC threshold (pixels) of the two-view geometry.
    two_view_max_num_trials : int
        RANSAC iterations cap of the two-view geometry; pairs that do not
        overlap (only outlier matches) always run to this cap, so it sets
        the matching time.
    use_mask : bool
        Extract features on the object only (coverage > 0), masking the
        environment out; silhouette features are view dependent.
    mask_erosion_px : int
        Pixels by which the object mask is shrunk (removes silhouette features).
    exposure : float
        Multiplier of the HDR radiance before tone mapping (:func:`freqbrdf.util.colour.tonemap`).
    denoise_sigma : float
        Standard deviation (pixels) of a Gaussian blur of the HDR views before
        tone mapping, against Monte Carlo noise; 0 disables it.
    known_intrinsics : bool
        Use the reference ``K`` as a PINHOLE camera held fixed; otherwise
        a ``camera_model`` camera is self-calibrated (one per capture if all
        reference ``K`` are equal, else one per view).
    camera_model : str
        COLMAP camera model self-calibrated when ``known_intrinsics`` is off
        (``SIMPLE_PINHOLE``, ``PINHOLE``, ``SIMPLE_RADIAL``, ``RADIAL`` or ``OPENCV``).
    min_num_matches : int
        Verified matches for an image pair to be used by the mapper.
    init_min_num_inliers : int
        Inliers of the initial image pair.
    init_min_tri_angle : float
        Triangulation angle (degrees) of the initial pair.
    abs_pose_min_num_inliers : int
        2D-3D inliers to register a further view.
    abs_pose_min_inlier_ratio : float
        Inlier ratio to register a further view.
    abs_pose_max_error : float
        Reprojection threshold (pixels) of absolute pose RANSAC.
    filter_max_reproj_error : float
        Observations with a larger reprojection error (pixels) are removed.
    max_reg_trials : int
        Attempts to register each view.
    multiple_models : bool
        Let COLMAP start new models for views that do not connect (the
        largest is returned).
    seed : int
        Seed of every random choice (RANSAC, mapper), >= 0.
    num_threads : int
        Threads of extraction, matching, mapping and bundle adjustment.
    """

    max_num_features: int = 8192
    first_octave: int = -1
    num_octaves: int = 4
    octave_resolution: int = 3
    peak_threshold: float = 0.002
    edge_threshold: float = 10.0
    estimate_affine_shape: bool = True
    domain_size_pooling: bool = False
    max_ratio: float = 0.9
    max_distance: float = 0.7
    cross_check: bool = True
    guided_matching: bool = False
    two_view_min_num_inliers: int = 10
    two_view_max_error: float = 1.0
    two_view_max_num_trials: int = 2000
    use_mask: bool = False
    mask_erosion_px: int = 0
    exposure: float = 1.0
    denoise_sigma: float = 1.0
    known_intrinsics: bool = True
    camera_model: str = "SIMPLE_RADIAL"
    min_num_matches: int = 10
    init_min_num_inliers: int = 30
    init_min_tri_angle: float = 16.0
    abs_pose_min_num_inliers: int = 10
    abs_pose_min_inlier_ratio: float = 0.15
    abs_pose_max_error: float = 12.0
    filter_max_reproj_error: float = 1.0
    max_reg_trials: int = 10
    multiple_models: bool = True
    seed: int = 0
    num_threads: int = 2

    def __post_init__(self) -> None:
        for f in fields(self):
            value, kind = getattr(self, f.name), type(f.default)
            ok = (
                isinstance(value, bool) if kind is bool
                else isinstance(value, int) and not isinstance(value, bool) if kind is int
                else isinstance(value, (int, float)) and not isinstance(value, bool) and np.isfinite(value) if kind is float
                else isinstance(value, kind)
            )
            if not ok:
                wanted = {bool: "true or false", int: "an integer", float: "a finite number"}.get(kind, "a string")
                raise ValueError(f"{CONFIG_PREFIX}{f.name}: {value!r} must be {wanted}")
        positive = (
            "max_num_features", "num_octaves", "octave_resolution", "peak_threshold", "edge_threshold",
            "max_ratio", "max_distance", "two_view_min_num_inliers", "two_view_max_error", "two_view_max_num_trials", "exposure",
            "min_num_matches", "init_min_num_inliers", "init_min_tri_angle", "abs_pose_min_num_inliers",
            "abs_pose_max_error", "filter_max_reproj_error", "max_reg_trials", "num_threads",
        )
        for name in positive:
            value = getattr(self, name)
            if not value > 0:
                raise ValueError(f"{CONFIG_PREFIX}{name}: {value!r} must be a positive number")
        for name in ("max_ratio", "abs_pose_min_inlier_ratio"):
            value = getattr(self, name)
            if not 0.0 <= value <= 1.0:
                raise ValueError(f"{CONFIG_PREFIX}{name}: {value!r} must be in [0, 1]")
        if self.first_octave < -1:
            raise ValueError(f"{CONFIG_PREFIX}first_octave: {self.first_octave!r} must be >= -1")
        if self.denoise_sigma < 0:
            raise ValueError(f"{CONFIG_PREFIX}denoise_sigma: {self.denoise_sigma!r} must be >= 0")
        if self.mask_erosion_px < 0:
            raise ValueError(f"{CONFIG_PREFIX}mask_erosion_px: {self.mask_erosion_px!r} must be >= 0")
        if self.camera_model not in CAMERA_MODELS:
            raise ValueError(f"{CONFIG_PREFIX}camera_model: {self.camera_model!r} is not one of {', '.join(CAMERA_MODELS)}")
        if self.seed < 0:
            raise ValueError(f"{CONFIG_PREFIX}seed: {self.seed!r} must be >= 0 (COLMAP treats -1 as unseeded)")

    @classmethod
    def from_config(cls, config: Mapping[str, object]) -> SfmOptions:
        """Options from the ``poses.colmap`` mapping of the configuration.

        Raises
        ------
        ValueError
            Naming an unknown key (``poses.colmap.{key}``) or a bad value.
        """
        names = {f.name for f in fields(cls)}
        unknown = sorted(set(config) - names)
        if unknown:
            raise ValueError(f"{CONFIG_PREFIX}{unknown[0]}: unknown option (known: {', '.join(sorted(names))})")
        return cls(**config)

    @classmethod
    def colmap_defaults(cls, *, seed: int = 0, num_threads: int = 2, known_intrinsics: bool = True) -> SfmOptions:
        """COLMAP's own defaults, read from pycolmap's option objects (for comparison).

        Only ``seed``, ``num_threads`` and ``known_intrinsics`` (not COLMAP
        settings) are taken from the arguments; preprocessing is off (no mask,
        no denoising, exposure 1).
        """
        import pycolmap

        defaults = {owner: _new_colmap_object(owner) for owner in {_owner(name) for name in COLMAP_ATTRIBUTES}}
        copied = {}
        for name in COLMAP_ATTRIBUTES:
            holder, attribute = _attribute(defaults[_owner(name)], name)
            copied[name] = getattr(holder, attribute)
        return cls(
            **copied, use_mask=False, mask_erosion_px=0, exposure=1.0, denoise_sigma=0.0,
            known_intrinsics=known_intrinsics, camera_model=pycolmap.ImageReaderOptions().camera_model,
            seed=seed, num_threads=num_threads,
        )


# Each SfmOptions field that COLMAP takes unchanged -> where it lands,
# "{pycolmap option class}.{attribute path}"; _colmap_object copies them.
COLMAP_ATTRIBUTES: dict[str, str] = {
    "max_num_features": "FeatureExtractionOptions.sift.max_num_features",
    "first_octave": "FeatureExtractionOptions.sift.first_octave",
    "num_octaves": "FeatureExtractionOptions.sift.num_octaves",
    "octave_resolution": "FeatureExtractionOptions.sift.octave_resolution",
    "peak_threshold": "FeatureExtractionOptions.sift.peak_threshold",
    "edge_threshold": "FeatureExtractionOptions.sift.edge_threshold",
    "estimate_affine_shape": "FeatureExtractionOptions.sift.estimate_affine_shape",
    "domain_size_pooling": "FeatureExtractionOptions.sift.domain_size_pooling",
    "max_ratio": "FeatureMatchingOptions.sift.max_ratio",
    "max_distance": "FeatureMatchingOptions.sift.max_distance",
    "cross_check": "FeatureMatchingOptions.sift.cross_check",
    "guided_matching": "FeatureMatchingOptions.guided_matching",
    "two_view_min_num_inliers": "TwoViewGeometryOptions.min_num_inliers",
    "two_view_max_error": "TwoViewGeometryOptions.ransac.max_error",
    "two_view_max_num_trials": "TwoViewGeometryOptions.ransac.max_num_trials",
    "min_num_matches": "IncrementalPipelineOptions.min_num_matches",
    "init_min_num_inliers": "IncrementalPipelineOptions.mapper.init_min_num_inliers",
    "init_min_tri_angle": "IncrementalPipelineOptions.mapper.init_min_tri_angle",
    "abs_pose_min_num_inliers": "IncrementalPipelineOptions.mapper.abs_pose_min_num_inliers",
    "abs_pose_min_inlier_ratio": "IncrementalPipelineOptions.mapper.abs_pose_min_inlier_ratio",
    "abs_pose_max_error": "IncrementalPipelineOptions.mapper.abs_pose_max_error",
    "filter_max_reproj_error": "IncrementalPipelineOptions.mapper.filter_max_reproj_error",
    "max_reg_trials": "IncrementalPipelineOptions.mapper.max_reg_trials",
    "multiple_models": "IncrementalPipelineOptions.multiple_models",
}

# The other SfmOptions fields, which are no one-to-one copy onto a pycolmap option.
SET_EXPLICITLY = (
    "use_mask", "mask_erosion_px", "exposure", "denoise_sigma",  # our own preprocessing (sfm.sfm_images), not COLMAP's
    "known_intrinsics", "camera_model",  # pick the reader's camera and which intrinsics bundle adjustment refines
    "seed",  # also seeds COLMAP's global PRNG, and goes to two option objects
    "num_threads",  # goes to the extraction, matching and mapping options alike
)


def _owner(name: str) -> str:
    """Name of the pycolmap option class that :data:`COLMAP_ATTRIBUTES` puts field ``name`` on."""
    return COLMAP_ATTRIBUTES[name].partition(".")[0]


def _new_colmap_object(owner: str) -> object:
    """A new ``pycolmap.{owner}`` option object with COLMAP's defaults."""
    import pycolmap

    if not hasattr(pycolmap, owner):
        raise AttributeError(f"pycolmap {pycolmap.__version__} has no option class {owner} (see sfm_options.COLMAP_ATTRIBUTES)")
    return getattr(pycolmap, owner)()


def _attribute(target: object, name: str) -> tuple[object, str]:
    """Object holding the pycolmap attribute of field ``name`` within ``target``, and the attribute's name.

    Raises
    ------
    AttributeError
        Naming the field and the pycolmap attribute, if this pycolmap lacks it.
    """
    import pycolmap

    path = COLMAP_ATTRIBUTES[name]
    parent, *steps = path.split(".")
    for depth, step in enumerate(steps):
        if not hasattr(target, step):
            raise AttributeError(
                f"{CONFIG_PREFIX}{name} maps onto pycolmap.{path}, but pycolmap {pycolmap.__version__} "
                f"has no attribute {step!r} on {parent} (see sfm_options.COLMAP_ATTRIBUTES)"
            )
        if depth < len(steps) - 1:
            target, parent = getattr(target, step), f"{parent}.{step}"
    return target, steps[-1]


def _colmap_object(owner: str, options: SfmOptions) -> object:
    """A new ``pycolmap.{owner}`` option object carrying every field that :data:`COLMAP_ATTRIBUTES` puts on it."""
    target = _new_colmap_object(owner)
    for name in COLMAP_ATTRIBUTES:
        if _owner(name) == owner:
            holder, attribute = _attribute(target, name)
            value = getattr(options, name)
            try:
                setattr(holder, attribute, value)
            except TypeError as error:  # pybind11's own message names neither the field nor the attribute
                path = COLMAP_ATTRIBUTES[name]
                raise TypeError(f"{CONFIG_PREFIX}{name}: pycolmap.{path} does not take {value!r}") from error
    return target


def extraction_options(options: SfmOptions) -> pycolmap.FeatureExtractionOptions:
    """SIFT extraction options of ``options`` (CPU)."""
    extraction = _colmap_object("FeatureExtractionOptions", options)
    # Not SfmOptions fields: COLMAP runs on the CPU, on the views at their full size.
    extraction.use_gpu = False
    extraction.max_image_size = -1
    extraction.num_threads = options.num_threads
    return extraction


def matching_options(options: SfmOptions) -> tuple[pycolmap.FeatureMatchingOptions, pycolmap.TwoViewGeometryOptions]:
    """Exhaustive matching and two-view verification options of ``options`` (CPU)."""
    matching = _colmap_object("FeatureMatchingOptions", options)
    matching.use_gpu = False
    matching.num_threads = options.num_threads
    verification = _colmap_object("TwoViewGeometryOptions", options)
    # Derived: RANSAC's floor of trials may not exceed the cap two_view_max_num_trials.
    verification.ransac.min_num_trials = min(verification.ransac.min_num_trials, options.two_view_max_num_trials)
    verification.ransac.random_seed = options.seed
    return matching, verification


def mapping_options(options: SfmOptions, image_path: Path) -> pycolmap.IncrementalPipelineOptions:
    """Incremental mapping options of ``options`` for the views in ``image_path``."""
    mapping = _colmap_object("IncrementalPipelineOptions", options)
    mapping.num_threads = options.num_threads
    mapping.random_seed = options.seed
    mapping.image_path = image_path
    mapping.extract_colors = False
    fixed = options.known_intrinsics
    # COLMAP copies ba_refine_focal_length/extra_params into the mapper's
    # abs_pose_refine_* options, so these also fix intrinsics during registration.
    mapping.ba_refine_focal_length = not fixed
    mapping.ba_refine_principal_point = False
    mapping.ba_refine_extra_params = not fixed
    return mapping
