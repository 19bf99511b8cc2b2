"""Camera poses by structure from motion (COLMAP through pycolmap 4.x, CPU).

The capture's HDR views are tone-mapped to 8-bit PNGs, SIFT features are
extracted (optionally only on the object, through COLMAP's per-image masks),
matched exhaustively and geometrically verified, and COLMAP's incremental
mapper reconstructs the views. The largest model is then aligned to the
reference camera centres by a 3D similarity, so its poses can be compared with
the rendered ground truth (:func:`pose_errors`, :func:`summarise`).

Conventions: COLMAP's camera frame is OpenCV's (x right, y down, z forward)
and its pixel (0, 0) is the top-left corner of the top-left pixel, exactly as
in :mod:`freqbrdf.cameras`, so ``K`` and ``world_to_camera`` carry over as they
are. COLMAP image names are ``{view name}.png``.

Determinism (measured with pycolmap 4.2.1 on the CPU, 2 threads): two runs
with the same seed usually give bit-identical poses; in 3 of 17 repeated
runs (one of them beside a CPU-bound process) poses differed by up to 6e-3
in an entry of the unaligned world-to-camera matrix, and in one later run
of the test suite under load by 2.4e-2 in a translation entry (0.6% of the
camera distance, in part a change of gauge), so some thread-order
dependence inside COLMAP remains (the mapper on one thread did not differ in
7 loaded runs, but neither did 4 loaded runs of the default). Bit-identity
needs three things, all
done in :func:`reconstruct`: COLMAP's PRNG is seeded
(``pycolmap.set_random_seed``, and ``random_seed`` of the two-view RANSAC and
of ``IncrementalPipelineOptions``, which COLMAP forwards to the mapper and
triangulator); the images are imported into the database in name order
before the multi-threaded extraction, which otherwise numbers them in the
order its threads finish (image ids steer pair order and the mapper's
choices; without this, repeated runs differed by up to 1e-2 in pose); and
nothing else in the chain is random (SIFT, brute-force matching, and Ceres on
problems below ``ba_min_num_residuals_for_cpu_multi_threading``).

Texture matters more than any option: SIFT needs repeatable blobs and
corners. Without the textures' grain (:func:`freqbrdf.textures.grain`; about
10 smooth Voronoi cells per object, 24 views about 30 degrees apart) a
neighbouring pair of views shares only 1-2 correct SIFT matches (checked
against the true epipolar geometry), far below the 15 that two-view
verification needs, so no setting registers them; relaxing every threshold
"registers" all views with rotation errors of 60-120 degrees.
:func:`pose_errors` is therefore the check to trust, not the registered
fraction alone (:func:`check_accuracy`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
import time
from collections.abc import Iterator, Mapping
from dataclasses import dataclass, fields
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from .cameras import Cameras, cameras_from_json
from .io import read_exr, read_json, read_png, write_png
from .colour import tonemap

if TYPE_CHECKING:  # pragma: no cover
    import pandas
    import pycolmap

CONFIG_PREFIX = "poses.colmap."
"""Prefix of :class:`SfmOptions` fields in the pipeline's configuration."""

IMAGE_SUFFIX = ".png"
CAMERA_MODELS = ("SIMPLE_PINHOLE", "PINHOLE", "SIMPLE_RADIAL", "RADIAL", "OPENCV")


@dataclass(frozen=True)
class SfmOptions:
    """Settings of the COLMAP reconstruction; every field is the config key ``poses.colmap.{field}``.

    The defaults are tuned on the default captures (24 views, 256 x 256,
    64 spp, sphere and torus with grained textures, studio and sunny light;
    README "Poses"): more and affine-adapted SIFT features (lower
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
        Multiplier of the HDR radiance before tone mapping (:func:`freqbrdf.io.tonemap`).
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
    "use_mask", "mask_erosion_px", "exposure", "denoise_sigma",  # our own preprocessing (sfm_images), not COLMAP's
    "known_intrinsics", "camera_model",  # pick the reader's camera and which intrinsics bundle adjustment refines
    "seed",  # also seeds COLMAP's global PRNG, and goes to two option objects
    "num_threads",  # goes to the extraction, matching and mapping options alike
)


class TooFewRegisteredError(RuntimeError):
    """COLMAP registered fewer views than the pipeline needs."""


class InaccuratePosesError(RuntimeError):
    """The registered views' poses are further from the reference than the pipeline accepts."""


# --------------------------------------------------------------------------- images


def view_name(image_name: str) -> str:
    """View name of a COLMAP image name (``"007.png"`` -> ``"007"``)."""
    return image_name[: -len(IMAGE_SUFFIX)] if image_name.endswith(IMAGE_SUFFIX) else image_name


def object_mask(coverage: np.ndarray, erosion_px: int = 0) -> np.ndarray:
    """COLMAP feature mask of one view: 255 on the object, 0 elsewhere.

    Parameters
    ----------
    coverage : ndarray, shape (H, W), uint8
        Object coverage (255 = fully covered).
    erosion_px : int
        Shrink the object region by this many pixels (square structuring element).

    Returns
    -------
    ndarray, shape (H, W), uint8
    """
    inside = np.asarray(coverage) > 0
    if erosion_px > 0:
        from scipy.ndimage import binary_erosion

        inside = binary_erosion(inside, structure=np.ones((3, 3), bool), iterations=erosion_px)
    return np.where(inside, 255, 0).astype(np.uint8)


def sfm_images(
    capture_dir: str | os.PathLike,
    out_dir: str | os.PathLike,
    *,
    mask_background: bool,
    exposure: float = 1.0,
    mask_erosion_px: int = 0,
    denoise_sigma: float = 0.0,
) -> list[str]:
    """Write 8-bit tone-mapped copies of a capture's HDR views for COLMAP.

    Parameters
    ----------
    capture_dir : path-like
        Capture with ``cameras.json``, ``images/{name}.exr`` and ``masks/{name}.png``.
    out_dir : path-like
        Receives ``images/{name}.png`` and, if ``mask_background``,
        ``masks/{name}.png.png`` (COLMAP's layout: the image's name plus
        ``.png``; black = no features).
    mask_background : bool
        Write masks that restrict features to the object.
    exposure : float
        Radiance multiplier before :func:`freqbrdf.io.tonemap`.
    mask_erosion_px : int
        See :func:`object_mask`.
    denoise_sigma : float
        Gaussian blur (pixels) of the HDR view before tone mapping; 0 disables it.

    Returns
    -------
    list of str
        COLMAP image names (``{name}.png``), in the order of ``cameras.json``.
    """
    capture_dir, out_dir = Path(capture_dir), Path(out_dir)
    cameras = cameras_from_json(read_json(capture_dir / "cameras.json"), capture_dir / "cameras.json")
    names = []
    for name in cameras.names:
        hdr = read_exr(capture_dir / "images" / f"{name}.exr")
        if hdr.ndim != 3 or hdr.shape[2] < 3 or hdr.shape[:2] != (cameras.height, cameras.width):
            raise ValueError(
                f"{capture_dir / 'images' / f'{name}.exr'}: shape {hdr.shape}, "
                f"expected ({cameras.height}, {cameras.width}, 3) from cameras.json"
            )
        hdr = hdr[..., :3]
        if denoise_sigma > 0:
            from scipy.ndimage import gaussian_filter

            hdr = gaussian_filter(hdr, sigma=(denoise_sigma, denoise_sigma, 0.0), mode="nearest")
        ldr = np.round(tonemap(hdr, exposure=exposure) * 255.0).astype(np.uint8)
        image_name = f"{name}{IMAGE_SUFFIX}"
        write_png(out_dir / "images" / image_name, ldr)
        if mask_background:
            coverage = read_png(capture_dir / "masks" / f"{name}.png")
            if coverage.ndim == 3:
                coverage = coverage[..., 0]
            write_png(out_dir / "masks" / f"{image_name}.png", object_mask(coverage, mask_erosion_px))
        names.append(image_name)
    return names


# --------------------------------------------------------------------------- COLMAP


@contextlib.contextmanager
def _output_to_file(path: Path) -> Iterator[None]:
    """Send this process's stdout and stderr file descriptors to ``path`` (COLMAP's glog output)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    try:
        with open(path, "ab") as f:
            os.dup2(f.fileno(), 1)
            os.dup2(f.fileno(), 2)
            try:
                yield
            finally:
                sys.stdout.flush()
                sys.stderr.flush()
                os.dup2(saved[0], 1)
                os.dup2(saved[1], 2)
    finally:
        for fd in saved:
            os.close(fd)


def _camera_params(K: np.ndarray) -> str:
    """COLMAP PINHOLE parameters ``fx, fy, cx, cy`` of ``K``."""
    return ",".join(repr(float(v)) for v in (K[0, 0], K[1, 1], K[0, 2], K[1, 2]))


def _owner(name: str) -> str:
    """Name of the pycolmap option class that :data:`COLMAP_ATTRIBUTES` puts field ``name`` on."""
    return COLMAP_ATTRIBUTES[name].partition(".")[0]


def _new_colmap_object(owner: str) -> object:
    """A new ``pycolmap.{owner}`` option object with COLMAP's defaults."""
    import pycolmap

    if not hasattr(pycolmap, owner):
        raise AttributeError(f"pycolmap {pycolmap.__version__} has no option class {owner} (see sfm.COLMAP_ATTRIBUTES)")
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
                f"has no attribute {step!r} on {parent} (see sfm.COLMAP_ATTRIBUTES)"
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


def reconstruct(
    capture_dir: str | os.PathLike,
    work_dir: str | os.PathLike,
    reference: Cameras,
    options: SfmOptions,
    log: logging.Logger | None = None,
) -> pycolmap.Reconstruction:
    """Run COLMAP on a capture: features, exhaustive matching, incremental mapping.

    Parameters
    ----------
    capture_dir : path-like
        Capture directory (see :func:`sfm_images`).
    work_dir : path-like
        Scratch directory: ``images/``, ``masks/``, ``database.db``,
        ``sparse/{k}/`` (every model COLMAP made) and ``colmap.log`` (COLMAP's
        own log). Existing COLMAP outputs in it are replaced.
    reference : Cameras
        The capture's cameras; only the intrinsics are used (if
        ``options.known_intrinsics``) and the view names.
    options : SfmOptions
    log : logging.Logger, optional
        Receives one progress line per phase, with its duration.

    Returns
    -------
    pycolmap.Reconstruction
        The model with the most registered views (in COLMAP's normalised
        frame; see :func:`aligned_cameras`).

    Raises
    ------
    TooFewRegisteredError
        If COLMAP made no model at all (the message names ``colmap.log`` and
        the options to change).
    ValueError
        If ``work_dir`` is ``capture_dir`` or the capture's views do not match ``reference``.
    """
    import pycolmap  # noqa: F401  (first, so that a missing pycolmap fails before work_dir is cleared)

    log = log or logging.getLogger(__name__)
    capture_dir = Path(capture_dir)
    paths = _clear_work_dir(capture_dir, Path(work_dir))
    names = _write_views(capture_dir, paths, reference, options, log)
    _extract_features(paths, names, reference, options, log)
    _match_features(paths, options, log)
    return _map_views(paths, options, log, capture_dir=capture_dir, n_views=len(names))


class _WorkPaths(NamedTuple):
    """What :func:`reconstruct` keeps in its work directory."""

    root: Path
    images: Path
    masks: Path
    database: Path
    sparse: Path
    colmap_log: Path


def _clear_work_dir(capture_dir: Path, work_dir: Path) -> _WorkPaths:
    """Create ``work_dir``, or remove the COLMAP outputs of an earlier run from it."""
    if work_dir.resolve() == capture_dir.resolve():
        raise ValueError(f"work_dir {work_dir} is the capture directory; its images/ and masks/ would be replaced")
    work_dir.mkdir(parents=True, exist_ok=True)
    paths = _WorkPaths(
        root=work_dir,
        images=work_dir / "images",
        masks=work_dir / "masks",
        database=work_dir / "database.db",
        sparse=work_dir / "sparse",
        colmap_log=work_dir / "colmap.log",
    )
    for path in (paths.database, paths.colmap_log):
        path.unlink(missing_ok=True)
    for path in (paths.sparse, paths.images, paths.masks):
        shutil.rmtree(path, ignore_errors=True)
    paths.sparse.mkdir()
    return paths


def _write_views(
    capture_dir: Path, paths: _WorkPaths, reference: Cameras, options: SfmOptions, log: logging.Logger
) -> list[str]:
    """Write the capture's views for COLMAP (:func:`sfm_images`), checked against ``reference``; their image names."""
    start = time.perf_counter()
    names = sfm_images(
        capture_dir, paths.root, mask_background=options.use_mask,
        exposure=options.exposure, mask_erosion_px=options.mask_erosion_px, denoise_sigma=options.denoise_sigma,
    )
    if [view_name(n) for n in names] != list(reference.names):
        raise ValueError(f"{capture_dir}: views {names[:3]}... do not match the reference cameras {reference.names[:3]}...")
    log.info("sfm: %d tone-mapped views written (%.1f s)", len(names), time.perf_counter() - start)
    return names


def _reader_options(options: SfmOptions, reference: Cameras, mask_path: Path) -> pycolmap.ImageReaderOptions:
    """Image reader options of ``options``: masks, and the camera model (PINHOLE with the reference ``K`` if known)."""
    import pycolmap

    reader = pycolmap.ImageReaderOptions()
    if options.use_mask:
        reader.mask_path = mask_path
    if options.known_intrinsics:
        reader.camera_model = "PINHOLE"
        reader.camera_params = _camera_params(reference.K[0])
    else:
        reader.camera_model = options.camera_model
    return reader


def _extract_features(
    paths: _WorkPaths, names: list[str], reference: Cameras, options: SfmOptions, log: logging.Logger
) -> None:
    """Seed COLMAP, import the views into a new database and extract their SIFT features."""
    import pycolmap

    reader = _reader_options(options, reference, paths.masks)
    same_K = bool(np.all(reference.K == reference.K[0]))
    camera_mode = pycolmap.CameraMode.SINGLE if same_K else pycolmap.CameraMode.PER_IMAGE

    # Seeds COLMAP's global PRNG for the rest of the run too (module docstring, determinism).
    pycolmap.set_random_seed(options.seed)
    t = time.perf_counter()
    with _output_to_file(paths.colmap_log):
        # Import first, in name order: the multi-threaded extractor otherwise
        # numbers images in the order its threads finish, and image ids steer
        # pair ordering and the mapper's choices.
        pycolmap.Database.open(paths.database).close()
        pycolmap.import_images(paths.database, paths.images, camera_mode=camera_mode, image_names=names, options=reader)
        pycolmap.extract_features(
            paths.database, paths.images, image_names=names, camera_mode=camera_mode,
            reader_options=reader, extraction_options=extraction_options(options), device=pycolmap.Device.cpu,
        )
    # The reader gives all views of one import the same camera_params, so
    # differing reference intrinsics are written into the database afterwards.
    if options.known_intrinsics and not same_K:
        _set_known_cameras(paths.database, reference)
    log.info("sfm: SIFT features extracted (%.1f s)", time.perf_counter() - t)


def _match_features(paths: _WorkPaths, options: SfmOptions, log: logging.Logger) -> None:
    """Match the features of every pair of views and verify the pairs' two-view geometry."""
    import pycolmap

    t = time.perf_counter()
    matching, verification = matching_options(options)
    with _output_to_file(paths.colmap_log):
        pycolmap.match_exhaustive(
            paths.database, matching_options=matching, verification_options=verification, device=pycolmap.Device.cpu
        )
    log.info("sfm: exhaustive matching and verification done (%.1f s)", time.perf_counter() - t)


def _map_views(
    paths: _WorkPaths, options: SfmOptions, log: logging.Logger, *, capture_dir: Path, n_views: int
) -> pycolmap.Reconstruction:
    """Map the views incrementally into ``paths.sparse``; the model with the most registered views."""
    import pycolmap

    t = time.perf_counter()
    with _output_to_file(paths.colmap_log):
        models = pycolmap.incremental_mapping(paths.database, paths.images, paths.sparse, mapping_options(options, paths.images))
    if not models:
        raise TooFewRegisteredError(
            f"COLMAP registered 0 of {n_views} views of {capture_dir}: no model (see {paths.colmap_log}); {_advice()}"
        )
    # sorted: ties go to the lowest model index, whatever the dict's order.
    best = max(sorted(models), key=lambda k: models[k].num_reg_images())
    model = models[best]
    log.info(
        "sfm: incremental mapping done, %d model(s), largest %d of %d views registered (%.1f s)",
        len(models), model.num_reg_images(), n_views, time.perf_counter() - t,
    )
    return model


def _set_known_cameras(database: Path, reference: Cameras) -> None:
    """Give every image of ``database`` its own PINHOLE camera with the reference ``K``."""
    import pycolmap

    K_by_name = dict(zip(reference.names, reference.K))
    db = pycolmap.Database.open(database)
    try:
        for image in db.read_all_images():
            camera = db.read_camera(image.camera_id)
            K = K_by_name[view_name(image.name)]
            camera.params = [K[0, 0], K[1, 1], K[0, 2], K[1, 2]]
            camera.has_prior_focal_length = True
            db.update_camera(camera)
    finally:
        db.close()


# --------------------------------------------------------------------------- alignment and errors


def registered_poses(reconstruction: pycolmap.Reconstruction) -> dict[str, tuple[np.ndarray, np.ndarray]]:
    """World-to-camera transforms and intrinsics of the registered views.

    Returns
    -------
    dict
        View name -> (world_to_camera (4, 4) in the reconstruction's frame,
        K (3, 3) of the view's COLMAP camera).
    """
    poses = {}
    for image_id in reconstruction.reg_image_ids():
        image = reconstruction.image(image_id)
        w2c = np.eye(4)
        w2c[:3, :] = image.cam_from_world().matrix()
        poses[view_name(image.name)] = (w2c, np.asarray(image.camera.calibration_matrix(), dtype=np.float64))
    return poses


def transform_world_to_camera(world_to_camera: np.ndarray, similarity: np.ndarray) -> np.ndarray:
    """Express cameras in the frame that ``similarity`` maps the world into.

    Parameters
    ----------
    world_to_camera : ndarray, shape (N, 4, 4)
        Rigid transforms in the old world frame.
    similarity : ndarray, shape (4, 4)
        ``x_new = s R x_old + t``.

    Returns
    -------
    ndarray, shape (N, 4, 4)
        Rigid transforms from the new world frame; the camera axes are unchanged,
        camera-space lengths are multiplied by ``s``.
    """
    sR, t = similarity[:3, :3], similarity[:3, 3]
    s = np.cbrt(np.linalg.det(sR))
    if not s > 0:
        raise ValueError(f"similarity has a non-positive scale {s}")
    R = sR / s
    world_to_camera = np.asarray(world_to_camera, dtype=np.float64)
    R_new = world_to_camera[:, :3, :3] @ R.T
    out = np.zeros_like(world_to_camera)
    out[:, :3, :3] = R_new
    out[:, :3, 3] = s * world_to_camera[:, :3, 3] - R_new @ t
    out[:, 3, 3] = 1.0
    return out


def aligned_cameras(
    reconstruction: pycolmap.Reconstruction,
    reference: Cameras,
    *,
    max_error_rel: float = 0.02,
    seed: int = 0,
) -> tuple[Cameras, np.ndarray]:
    """Registered views of a reconstruction, similarity-aligned to the reference camera centres.

    COLMAP's LO-RANSAC on camera centres (``pycolmap.estimate_sim3d_robust``)
    separates well placed views from badly placed ones, so the latter do not
    pull the alignment off; the similarity is then the least-squares
    (Umeyama) fit to all inlier centres (``pycolmap.estimate_sim3d``), which
    is more accurate than the RANSAC's own model (measured: 0.65 instead of
    1.24 degrees median rotation error on one capture).

    Parameters
    ----------
    reconstruction : pycolmap.Reconstruction
    reference : Cameras
        Ground-truth cameras; every registered view must be named in it.
    max_error_rel : float
        RANSAC inlier threshold on a centre, relative to the median reference
        camera distance from the origin. Measured on the default sphere/studio
        capture: at 0.05 three views placed 4-7% off join the fit and turn
        every camera by about 1 degree (median 1.06 deg, 1.3%); at 0.02 the
        median errors are 0.40 deg and 0.5%.
    seed : int
        Seed of the RANSAC.

    Returns
    -------
    cameras : Cameras
        Registered views only, in reference order, OpenCV convention, in the
        reference world frame, ``K`` from COLMAP's cameras.
    similarity : ndarray, shape (4, 4)
        ``x_reference = S @ [x_reconstruction, 1]`` (scale times rotation, translation).

    Raises
    ------
    ValueError
        If a registered view is not in the reference, or fewer than 3 views
        are registered, or no similarity is found.
    """
    poses = registered_poses(reconstruction)
    names = _registered_names(poses, reference)
    index = {n: i for i, n in enumerate(reference.names)}
    ref_centres = reference.centres[[index[n] for n in names]]
    w2c = np.stack([poses[n][0] for n in names])
    est_centres = -np.einsum("nji,nj->ni", w2c[:, :3, :3], w2c[:, :3, 3])
    distance = float(np.median(np.linalg.norm(reference.centres, axis=1)))
    S = _centre_similarity(est_centres, ref_centres, max_error=max_error_rel * distance, seed=seed)
    w2c = transform_world_to_camera(w2c, S)
    cameras = Cameras(
        K=np.stack([poses[n][1] for n in names]),
        world_to_camera=w2c,
        width=reference.width,
        height=reference.height,
        names=tuple(names),
    )
    return cameras, S


def _registered_names(poses: Mapping[str, object], reference: Cameras) -> list[str]:
    """Names of the registered views in reference order, checked to be reference views and at least 3."""
    unknown = sorted(set(poses) - set(reference.names))
    if unknown:
        raise ValueError(f"registered view {unknown[0]!r} is not among the reference cameras")
    names = [n for n in reference.names if n in poses]
    if len(names) < 3:
        raise ValueError(f"only {len(names)} registered views; a similarity needs at least 3")
    return names


def _centre_similarity(source: np.ndarray, target: np.ndarray, *, max_error: float, seed: int) -> np.ndarray:
    """Similarity (4, 4) taking camera centres ``source`` (N, 3) onto ``target`` (N, 3), robust to misplaced views."""
    import pycolmap

    failure = f"no similarity aligns the {len(source)} registered camera centres to the reference"
    ransac = pycolmap.RANSACOptions()
    ransac.max_error = max_error
    ransac.random_seed = seed
    robust = pycolmap.estimate_sim3d_robust(source, target, ransac)
    if robust is None or int(robust["num_inliers"]) < 3:
        raise ValueError(failure)
    # COLMAP's LO-RANSAC picks the inliers; a least-squares (Umeyama) fit on all
    # of them is then more accurate than the model the RANSAC returns.
    inliers = np.asarray(robust["inlier_mask"], dtype=bool)
    sim = pycolmap.estimate_sim3d(source[inliers], target[inliers])
    if sim is None:
        raise ValueError(failure)
    S = np.eye(4)
    S[:3, :] = sim.matrix()
    return S


def rotation_angle_deg(R: np.ndarray) -> np.ndarray:
    """Rotation angles in degrees of rotation matrices, shape (..., 3, 3) -> (...)."""
    trace = np.trace(R, axis1=-2, axis2=-1)
    return np.degrees(np.arccos(np.clip((trace - 1.0) / 2.0, -1.0, 1.0)))


def reprojection_errors(reconstruction: pycolmap.Reconstruction) -> dict[str, float]:
    """Mean reprojection error (pixels) of each registered view's triangulated observations.

    Returns
    -------
    dict
        View name -> mean distance between observed and projected keypoints
        (NaN for a view without triangulated observations).
    """
    errors = {}
    points = reconstruction.points3D
    for image_id in reconstruction.reg_image_ids():
        image = reconstruction.image(image_id)
        observed = [p for p in image.points2D if p.has_point3D()]
        if not observed:
            errors[view_name(image.name)] = float("nan")
            continue
        xy = np.array([p.xy for p in observed], dtype=np.float64)
        xyz = np.array([points[p.point3D_id].xyz for p in observed], dtype=np.float64)
        cam_from_world = image.cam_from_world().matrix()
        cam = xyz @ cam_from_world[:, :3].T + cam_from_world[:, 3]
        projected = image.camera.img_from_cam(cam, check_cheirality=False)
        errors[view_name(image.name)] = float(np.mean(np.linalg.norm(projected - xy, axis=1)))
    return errors


def pose_errors(
    estimated: Cameras,
    reference: Cameras,
    reprojection: Mapping[str, float] | None = None,
) -> pandas.DataFrame:
    """Per-view pose errors of aligned estimated cameras against the reference.

    Parameters
    ----------
    estimated : Cameras
        Registered views in the reference frame (:func:`aligned_cameras`).
    reference : Cameras
        Ground truth; must name every estimated view.
    reprojection : mapping, optional
        View name -> mean reprojection error in pixels (:func:`reprojection_errors`).

    Returns
    -------
    pandas.DataFrame
        One row per estimated view: ``name``, ``rotation_error_deg`` (angle of
        ``R_est R_ref^T``), ``centre_error_rel`` (``|c_est - c_ref| / |c_ref|``)
        and, if given, ``reprojection_error_px``.
    """
    import pandas as pd

    index = {n: i for i, n in enumerate(reference.names)}
    missing = [n for n in estimated.names if n not in index]
    if missing:
        raise ValueError(f"estimated view {missing[0]!r} is not among the reference cameras")
    rows = [index[n] for n in estimated.names]
    R_est = estimated.world_to_camera[:, :3, :3]
    R_ref = reference.world_to_camera[rows, :3, :3]
    c_est = estimated.centres
    c_ref = reference.centres[rows]
    ref_distance = np.linalg.norm(c_ref, axis=1)
    if np.any(ref_distance <= 0):
        raise ValueError("a reference camera sits at the origin; relative centre errors are undefined")
    table = pd.DataFrame(
        {
            "name": list(estimated.names),
            "rotation_error_deg": rotation_angle_deg(R_est @ np.swapaxes(R_ref, 1, 2)),
            "centre_error_rel": np.linalg.norm(c_est - c_ref, axis=1) / ref_distance,
        }
    )
    if reprojection is not None:
        table["reprojection_error_px"] = [float(reprojection.get(n, np.nan)) for n in estimated.names]
    return table


def summarise(errors: pandas.DataFrame, n_views: int) -> dict[str, float | int]:
    """Summary of :func:`pose_errors` for a capture of ``n_views`` views.

    Returns
    -------
    dict
        ``n_views``, ``registered``, ``registered_fraction``,
        ``median_rotation_error_deg``, ``median_centre_error_rel`` and
        ``mean_reprojection_error_px`` (NaN where there is nothing to average).
    """
    registered = len(errors)
    if n_views < 1:
        raise ValueError(f"n_views must be >= 1, got {n_views}")
    if registered > n_views:
        raise ValueError(f"{registered} registered views but only {n_views} views in the capture")

    def stat(column: str, fn) -> float:
        if column not in errors or registered == 0:
            return float("nan")
        return float(fn(errors[column].to_numpy(dtype=np.float64)))

    return {
        "n_views": int(n_views),
        "registered": int(registered),
        "registered_fraction": registered / n_views,
        "median_rotation_error_deg": stat("rotation_error_deg", np.median),
        "median_centre_error_rel": stat("centre_error_rel", np.median),
        "mean_reprojection_error_px": stat("reprojection_error_px", np.nanmean),
    }


def _advice() -> str:
    keys = [f"{CONFIG_PREFIX}{k}" for k in ("max_num_features", "peak_threshold", "init_min_num_inliers", "abs_pose_min_num_inliers", "use_mask")]
    return (
        f"to register more views, raise {keys[0]}, lower {keys[1]} (more SIFT features), "
        f"lower {keys[2]} or {keys[3]} (accept weaker image pairs), or toggle {keys[4]}"
    )


def check_registration(n_registered: int, n_views: int, min_fraction: float) -> None:
    """Raise :class:`TooFewRegisteredError` unless ``n_registered / n_views >= min_fraction``.

    Parameters
    ----------
    n_registered, n_views : int
        Views in the reconstruction and in the capture.
    min_fraction : float
        Required fraction, in [0, 1].
    """
    if n_views < 1:
        raise ValueError(f"n_views must be >= 1, got {n_views}")
    if not 0 <= n_registered <= n_views:
        raise ValueError(f"n_registered {n_registered} must be in [0, n_views={n_views}]")
    if not 0.0 <= min_fraction <= 1.0:
        raise ValueError(f"min_fraction {min_fraction} must be in [0, 1]")
    fraction = n_registered / n_views
    if fraction < min_fraction:
        raise TooFewRegisteredError(
            f"COLMAP registered only {n_registered} of {n_views} views ({fraction:.0%}, "
            f"at least {min_fraction:.0%} needed); {_advice()}"
        )


def check_accuracy(summary: Mapping[str, float], max_rotation_deg: float, max_centre_rel: float) -> None:
    """Raise :class:`InaccuratePosesError` if the median pose errors exceed the limits.

    Loose matching thresholds can "register" every view with poses tens of
    degrees off, so the registered fraction alone does not show success.

    Parameters
    ----------
    summary : mapping
        :func:`summarise` output.
    max_rotation_deg : float
        Largest accepted median rotation error, degrees.
    max_centre_rel : float
        Largest accepted median camera-centre error, relative to the camera distance.
    """
    rotation, centre = summary["median_rotation_error_deg"], summary["median_centre_error_rel"]
    if not (rotation <= max_rotation_deg and centre <= max_centre_rel):
        raise InaccuratePosesError(
            f"COLMAP poses are off the reference: median rotation error {rotation:.2f} deg "
            f"(limit {max_rotation_deg}), median centre error {centre:.2%} of the camera distance "
            f"(limit {max_centre_rel:.2%}); lower {CONFIG_PREFIX}two_view_max_error or "
            f"{CONFIG_PREFIX}filter_max_reproj_error (stricter geometry), or raise the limits "
            "poses.max_median_rotation_deg / poses.max_median_centre_error"
        )
