"""The training views as the Mitsuba baseline renders them: the sensor of each view, the window
of it that a step renders, and the captured images and weights checked and cut to that window
(`freqbrdf.estimate.mitsuba`)."""

from __future__ import annotations

from dataclasses import dataclass
from types import ModuleType

import numpy as np

from freqbrdf.scene.cameras import Cameras, mitsuba_to_world

__all__ = ["CropWindows", "TrainingViews", "check_captures", "crop_windows", "sensor_intrinsics", "sensor_views"]


def sensor_intrinsics(cameras: Cameras) -> tuple[np.ndarray, np.ndarray]:
    """Mitsuba ``perspective`` settings that reproduce each view's intrinsics K.

    Mitsuba's pinhole has square pixels and no skew; the principal point is
    an offset from the image centre in units of the image size, with the
    sign measured by rendering (an offset of +0.1 moves the image of the
    optical axis by -0.1 W).

    Parameters
    ----------
    cameras : Cameras

    Returns
    -------
    x_fov_deg : ndarray, shape (N,)
        Horizontal field of view.
    principal_offset : ndarray, shape (N, 2)
        ``principal_point_offset_x``, ``principal_point_offset_y``.

    Raises
    ------
    ValueError
        Naming the first view whose K has non-square pixels or skew.
    """
    K = np.asarray(cameras.K, dtype=np.float64)
    fx, fy = K[:, 0, 0], K[:, 1, 1]
    bad = np.nonzero(~np.isclose(fx, fy, rtol=1e-4) | (np.abs(K[:, 0, 1]) > 1e-6 * fx))[0]
    if len(bad):
        raise ValueError(
            f"view {cameras.names[bad[0]]}: K {K[bad[0]].tolist()} has non-square pixels or skew, "
            "which Mitsuba's perspective sensor cannot reproduce"
        )
    x_fov = np.degrees(2.0 * np.arctan(cameras.width / (2.0 * fx)))
    offset = np.stack([(cameras.width / 2.0 - K[:, 0, 2]) / cameras.width,
                       (cameras.height / 2.0 - K[:, 1, 2]) / cameras.height], axis=-1)
    return x_fov, offset


def sensor_views(mi: ModuleType, cameras: Cameras) -> list[dict[str, object]]:
    """Sensor parameters of every view, to assign to ``mi.traverse(scene)``.

    Moving the one sensor of the scene (rather than holding a sensor per
    view) lets Dr.Jit compile the render kernels once for all views.

    Returns
    -------
    list of dict
        Per view: ``sensor.to_world``, ``sensor.x_fov``,
        ``sensor.principal_point_offset_x`` and ``_y``.
    """
    x_fov, offset = sensor_intrinsics(cameras)
    views = []
    for k, w2c in enumerate(np.asarray(cameras.world_to_camera, dtype=np.float64)):
        views.append({
            "sensor.to_world": mi.ScalarTransform4f(mitsuba_to_world(w2c)),
            "sensor.x_fov": float(x_fov[k]),
            "sensor.principal_point_offset_x": float(offset[k, 0]),
            "sensor.principal_point_offset_y": float(offset[k, 1]),
        })
    return views


def check_captures(cameras: Cameras, images: np.ndarray, weights: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Captured views with NaN/Inf pixels zeroed and given weight 0."""
    n, h, w = len(cameras), cameras.height, cameras.width
    images = np.asarray(images, dtype=np.float32)
    weights = np.asarray(weights, dtype=np.float32)
    if images.shape != (n, h, w, 3):
        raise ValueError(f"images are {images.shape}, cameras say ({n}, {h}, {w}, 3)")
    if weights.shape != (n, h, w):
        raise ValueError(f"masks are {weights.shape}, cameras say ({n}, {h}, {w})")
    if not np.isfinite(weights).all() or weights.min() < 0.0:
        raise ValueError("masks must hold finite weights >= 0")
    bad = ~np.isfinite(images).all(axis=-1)
    images = np.where(bad[..., None], 0.0, images).astype(np.float32)
    weights = np.where(bad, 0.0, weights).astype(np.float32)
    empty = np.nonzero(weights.reshape(n, -1).sum(axis=1) <= 0.0)[0]
    if len(empty):
        raise ValueError(f"view {cameras.names[empty[0]]}: the mask covers no pixel")
    return images, weights


@dataclass(frozen=True)
class CropWindows:
    """The window of each view that a step renders: one size for every view, so that Dr.Jit
    compiles the render kernels once, and an offset per view.

    Attributes
    ----------
    offsets : ndarray, shape (K, 2), int
        Column and row of each window's first pixel.
    size : tuple of int
        Width and height of the windows, pixels.
    """

    offsets: np.ndarray
    size: tuple[int, int]

    def sensor(self, mi: ModuleType, k: int) -> dict[str, object]:
        """Mitsuba's film crop of view k, to assign to ``mi.traverse(scene)`` with its sensor."""
        x, y = (int(v) for v in self.offsets[k])
        return {"sensor.film.crop_offset": mi.ScalarPoint2u(x, y),
                "sensor.film.crop_size": mi.ScalarVector2u(*self.size)}

    def take(self, images: np.ndarray) -> np.ndarray:
        """Each view's window of ``images`` (K, H, W, ...) -> (K, h, w, ...), contiguous."""
        w, h = self.size
        return np.stack([images[k, y:y + h, x:x + w] for k, (x, y) in enumerate(self.offsets)])


def crop_windows(weights: np.ndarray) -> CropWindows:
    """The smallest window size that holds every view's pixels of weight > 0, and each view's offset.

    The size is the largest bounding box's width and height over the views; each window is
    centred on its view's box and moved inside the image where it would cross an edge (it
    still holds the box, which is no larger than it).

    Parameters
    ----------
    weights : ndarray, shape (K, H, W)
        Per-pixel loss weights (`freqbrdf.estimate.mitsuba.optimise_textures`); every view has some weight > 0.

    Returns
    -------
    CropWindows
    """
    weights = np.asarray(weights)
    boxes = []
    for k, view in enumerate(weights):
        rows, cols = np.nonzero(np.any(view > 0, axis=1))[0], np.nonzero(np.any(view > 0, axis=0))[0]
        if not len(rows):
            raise ValueError(f"crop_windows: view {k} has no pixel of weight > 0")
        boxes.append((cols[0], rows[0], cols[-1] + 1 - cols[0], rows[-1] + 1 - rows[0]))
    boxes = np.asarray(boxes, dtype=np.int64)
    height, width = weights.shape[1:3]
    w, h = int(boxes[:, 2].max()), int(boxes[:, 3].max())
    x = np.clip(boxes[:, 0] - (w - boxes[:, 2]) // 2, 0, width - w)
    y = np.clip(boxes[:, 1] - (h - boxes[:, 3]) // 2, 0, height - h)
    return CropWindows(offsets=np.stack([x, y], axis=1), size=(w, h))


@dataclass(frozen=True)
class TrainingViews:
    """The training views as the steps use them: sensor parameters (the film's crop among them
    when cropped), images and weights (K, h, w, 3 and K, h, w: the rendered windows)."""

    sensors: list[dict[str, object]]
    images: np.ndarray
    weights: np.ndarray

    @classmethod
    def of(cls, mi: ModuleType, cameras: Cameras, images: np.ndarray, weights: np.ndarray, crop: bool) -> TrainingViews:
        """The views of ``cameras`` with their images and weights (`check_captures`), cut to their
        windows (`crop_windows`) if ``crop``."""
        images, weights = check_captures(cameras, images, weights)
        sensors = sensor_views(mi, cameras)
        if not crop:
            return cls(sensors, images, weights)
        windows = crop_windows(weights)
        return cls([view | windows.sensor(mi, k) for k, view in enumerate(sensors)], windows.take(images),
                   windows.take(weights))
