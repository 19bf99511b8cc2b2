"""Camera poses by structure from motion (COLMAP through pycolmap 4.x, CPU).

The capture's HDR views are tone-mapped to 8-bit PNGs, SIFT features are
extracted (optionally only on the object, through COLMAP's per-image masks),
matched exhaustively and geometrically verified, and COLMAP's incremental
mapper reconstructs the views. The largest model is then aligned to the
reference camera centres by a 3D similarity, so its poses can be compared with
the rendered ground truth (:mod:`freqbrdf.capture.sfm_alignment`). The settings
are :class:`freqbrdf.capture.sfm_options.SfmOptions`.

Conventions: COLMAP's camera frame is OpenCV's (x right, y down, z forward)
and its pixel (0, 0) is the top-left corner of the top-left pixel, exactly as
in :mod:`freqbrdf.scene.cameras`, so ``K`` and ``world_to_camera`` carry over as they
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
corners. Without the textures' grain (:func:`freqbrdf.scene.textures.grain`; about
10 smooth Voronoi cells per object, 24 views about 30 degrees apart) a
neighbouring pair of views shares only 1-2 correct SIFT matches (checked
against the true epipolar geometry), far below the 15 that two-view
verification needs, so no setting registers them; relaxing every threshold
"registers" all views with rotation errors of 60-120 degrees.
:func:`freqbrdf.capture.sfm_alignment.pose_errors` is therefore the check to
trust, not the registered fraction alone
(:func:`freqbrdf.capture.sfm_alignment.check_accuracy`).
"""

from __future__ import annotations

import contextlib
import logging
import os
import shutil
import sys
import time
from collections.abc import Iterator
from pathlib import Path
from typing import TYPE_CHECKING, NamedTuple

import numpy as np

from freqbrdf.capture.sfm_options import CONFIG_PREFIX, SfmOptions, extraction_options, mapping_options, matching_options
from freqbrdf.scene.cameras import Cameras, cameras_from_json
from freqbrdf.util.io import read_exr, read_json, read_png, write_png
from freqbrdf.util.colour import tonemap

if TYPE_CHECKING:  # pragma: no cover
    import pycolmap

IMAGE_SUFFIX = ".png"


class TooFewRegisteredError(RuntimeError):
    """COLMAP registered fewer views than the pipeline needs."""


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
        Radiance multiplier before :func:`freqbrdf.util.colour.tonemap`.
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


def _advice() -> str:
    keys = [f"{CONFIG_PREFIX}{k}" for k in ("max_num_features", "peak_threshold", "init_min_num_inliers", "abs_pose_min_num_inliers", "use_mask")]
    return (
        f"to register more views, raise {keys[0]}, lower {keys[1]} (more SIFT features), "
        f"lower {keys[2]} or {keys[3]} (accept weaker image pairs), or toggle {keys[4]}"
    )


def check_registration(n_registered: int, n_views: int, min_fraction: float, log: logging.Logger | None = None) -> bool:
    """Raise :class:`TooFewRegisteredError` unless ``n_registered / n_views >= min_fraction``.

    Poses that no estimate uses (SfM only scored) are a result either way: given
    ``log``, too few views is a warning there instead, unless fewer than 3 are
    registered (a similarity to the reference needs 3 centres).

    Parameters
    ----------
    n_registered, n_views : int
        Views in the reconstruction and in the capture.
    min_fraction : float
        Required fraction, in [0, 1].
    log : logging.Logger, optional
        Where to warn instead of raising.

    Returns
    -------
    bool
        Whether the fraction is reached.
    """
    if n_views < 1:
        raise ValueError(f"n_views must be >= 1, got {n_views}")
    if not 0 <= n_registered <= n_views:
        raise ValueError(f"n_registered {n_registered} must be in [0, n_views={n_views}]")
    if not 0.0 <= min_fraction <= 1.0:
        raise ValueError(f"min_fraction {min_fraction} must be in [0, 1]")
    fraction = n_registered / n_views
    if fraction >= min_fraction:
        return True
    error = TooFewRegisteredError(
        f"COLMAP registered only {n_registered} of {n_views} views ({fraction:.0%}, "
        f"at least {min_fraction:.0%} needed); {_advice()}"
    )
    if n_registered < 3:
        raise error
    return raise_or_warn(error, log)


def raise_or_warn(error: Exception, log: logging.Logger | None) -> bool:
    """Raise ``error``; or, given ``log``, warn with it there and return False.

    A check of poses that no estimate uses (SfM only scored) is given a log: such poses are a
    result even when they fail the check.
    """
    if log is None:
        raise error
    log.warning("%s; kept, since no estimate uses these poses", error)
    return False
