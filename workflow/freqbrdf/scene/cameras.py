"""Pinhole cameras in the OpenCV convention, Fibonacci rigs and their JSON format.

Conventions (shared by every stage):

- World: right-handed, +Y up; each object is centred at the origin inside the
  unit sphere.
- Camera: OpenCV axes, x right, y down, z forward. ``world_to_camera`` is a
  4x4 rigid transform, ``x_cam = R @ x_world + t``.
- Pixels: continuous coordinates with (0, 0) at the top-left corner of the
  top-left pixel, so the centre of pixel (row i, column j) is (j + 0.5, i + 0.5).
  ``K = [[f, 0, W/2], [0, f, H/2], [0, 0, 1]]`` with ``f = (W/2) / tan(fov_x/2)``.
- Mitsuba's camera frame has x pointing left and y up, so its ``to_world`` is
  the OpenCV camera-to-world with the first two axes negated
  (:func:`mitsuba_to_world`).
"""

from __future__ import annotations

import json

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from freqbrdf.sphere.sampling import fibonacci_hemisphere

CAMERAS_FORMAT = "freqbrdf-cameras/1"
CONVENTION = (
    "OpenCV: camera x right, y down, z forward; x_cam = world_to_camera @ [x_world, 1]; "
    "world +Y up, object inside the unit sphere at the origin; pixel centres at (j + 0.5, i + 0.5)"
)


@dataclass(frozen=True)
class Cameras:
    """A set of pinhole views sharing one image size.

    Attributes
    ----------
    K : ndarray, shape (N, 3, 3)
        Intrinsics in pixels.
    world_to_camera : ndarray, shape (N, 4, 4)
        Extrinsics (OpenCV axes).
    width, height : int
        Image size in pixels.
    names : tuple of str
        One name per view; image files are ``images/{name}.exr``.
    """

    K: np.ndarray
    world_to_camera: np.ndarray
    width: int
    height: int
    names: tuple[str, ...]

    def __post_init__(self) -> None:
        n = len(self.names)
        if self.K.shape != (n, 3, 3) or self.world_to_camera.shape != (n, 4, 4):
            raise ValueError(
                f"Cameras: {n} names but K {self.K.shape} and world_to_camera {self.world_to_camera.shape}"
            )

    def __len__(self) -> int:
        return len(self.names)

    @property
    def centres(self) -> np.ndarray:
        """Camera centres in world coordinates, shape (N, 3)."""
        R = self.world_to_camera[:, :3, :3]
        t = self.world_to_camera[:, :3, 3]
        return -np.einsum("nji,nj->ni", R, t)


def intrinsics(width: int, height: int, fov_x_deg: float) -> np.ndarray:
    """Pinhole intrinsics with square pixels and a centred principal point.

    Parameters
    ----------
    width, height : int
        Image size in pixels.
    fov_x_deg : float
        Horizontal field of view in degrees, in (0, 180).

    Returns
    -------
    ndarray, shape (3, 3)
    """
    if not 0.0 < fov_x_deg < 180.0:
        raise ValueError(f"fov_x_deg must be in (0, 180), got {fov_x_deg}")
    f = 0.5 * width / np.tan(np.radians(fov_x_deg) / 2.0)
    return np.array([[f, 0.0, width / 2.0], [0.0, f, height / 2.0], [0.0, 0.0, 1.0]])


def look_at(eye: np.ndarray, target: np.ndarray = np.zeros(3), up: np.ndarray = np.array([0.0, 1.0, 0.0])) -> np.ndarray:
    """World-to-camera transform (OpenCV axes) of a camera at ``eye`` looking at ``target``.

    Parameters
    ----------
    eye, target, up : ndarray, shape (3,)
        Camera centre, point on the optical axis, and the world direction
        that should appear upward in the image. When ``up`` is parallel to
        the viewing direction, world -Z is used instead.

    Returns
    -------
    ndarray, shape (4, 4)
    """
    eye = np.asarray(eye, dtype=np.float64)
    forward = np.asarray(target, dtype=np.float64) - eye
    forward /= np.linalg.norm(forward)
    up = np.asarray(up, dtype=np.float64)
    right = np.cross(forward, up)
    if np.linalg.norm(right) < 1e-6:
        right = np.cross(forward, np.array([0.0, 0.0, -1.0]))
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)
    R = np.stack([right, down, forward])  # rows: camera axes in world coordinates
    w2c = np.eye(4)
    w2c[:3, :3] = R
    w2c[:3, 3] = -R @ eye
    return w2c


def hemisphere_rig(n: int, distance: float, azimuth_deg: float = 0.0) -> np.ndarray:
    """Cameras on a Fibonacci upper hemisphere, all looking at the origin.

    Parameters
    ----------
    n : int
        Number of views.
    distance : float
        Distance of every camera from the origin (object radius is 1).
    azimuth_deg : float
        Rotation of the whole rig about +Y; test rigs use it so that their
        views differ from the training views.

    Returns
    -------
    ndarray, shape (n, 4, 4)
        World-to-camera transforms.
    """
    if distance <= 1.0:
        raise ValueError(f"camera distance must exceed the object radius 1, got {distance}")
    dirs = fibonacci_hemisphere(n)
    a = np.radians(azimuth_deg)
    rot_y = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
    eyes = distance * dirs @ rot_y.T
    return np.stack([look_at(eye) for eye in eyes])


def rig_cameras(n: int, size: int, fov_x_deg: float, distance: float, azimuth_deg: float = 0.0,
                prefix: str = "") -> Cameras:
    """A :func:`hemisphere_rig` of square views with the same intrinsics, named ``{prefix}000``, ...

    Parameters
    ----------
    n : int
        Number of views.
    size : int
        Width and height, pixels.
    fov_x_deg : float
        Horizontal field of view.
    distance, azimuth_deg : float
        As :func:`hemisphere_rig`.
    prefix : str
        Put before each view's three-digit number.

    Returns
    -------
    Cameras
    """
    w2c = hemisphere_rig(n, distance, azimuth_deg=azimuth_deg)
    return Cameras(K=np.repeat(intrinsics(size, size, fov_x_deg)[None], len(w2c), axis=0), world_to_camera=w2c,
                   width=size, height=size, names=tuple(f"{prefix}{k:03d}" for k in range(len(w2c))))


def project(points: np.ndarray, K: np.ndarray, world_to_camera: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Project world points into one view or several.

    Parameters
    ----------
    points : ndarray, shape (P, 3)
        World positions.
    K : ndarray, shape (..., 3, 3)
        Intrinsics of each view (``...``: none for one view, (V,) for V views).
    world_to_camera : ndarray, shape (..., 4, 4)

    Returns
    -------
    pixels : ndarray, shape (P, ..., 2)
        Continuous (x, y) pixel coordinates (inf/NaN where depth is 0).
    depth : ndarray, shape (P, ...)
        Camera-space z (positive in front of the camera).
    """
    cam = np.einsum("...ij,pj->p...i", world_to_camera[..., :3, :3], points) + world_to_camera[..., :3, 3]
    uvw = np.einsum("...ij,p...j->p...i", K, cam)
    with np.errstate(divide="ignore", invalid="ignore"):
        pixels = uvw[..., :2] / uvw[..., 2:3]
    return pixels, cam[..., 2]


def mitsuba_to_world(world_to_camera: np.ndarray) -> np.ndarray:
    """Mitsuba sensor ``to_world`` matrix of an OpenCV world-to-camera transform.

    Parameters
    ----------
    world_to_camera : ndarray, shape (4, 4)

    Returns
    -------
    ndarray, shape (4, 4)
        Camera-to-world with Mitsuba's axes (x left, y up, z forward).
    """
    c2w = np.linalg.inv(world_to_camera)
    c2w[:3, 0] *= -1.0
    c2w[:3, 1] *= -1.0
    return c2w


def cameras_to_json(cameras: Cameras) -> dict:
    """JSON-ready dictionary of ``cameras`` (format ``freqbrdf-cameras/1``)."""
    return {
        "format": CAMERAS_FORMAT,
        "convention": CONVENTION,
        "width": int(cameras.width),
        "height": int(cameras.height),
        "frames": [
            {
                "name": name,
                "image": f"images/{name}.exr",
                "mask": f"masks/{name}.png",
                "K": K.tolist(),
                "world_to_camera": w2c.tolist(),
            }
            for name, K, w2c in zip(cameras.names, cameras.K, cameras.world_to_camera)
        ],
    }


def cameras_from_json(data: dict, source: str | Path = "cameras.json") -> Cameras:
    """Parse the dictionary written by :func:`cameras_to_json`.

    Raises
    ------
    ValueError
        Naming ``source`` and the offending field.
    """
    if data.get("format") != CAMERAS_FORMAT:
        raise ValueError(f"{source}: format is {data.get('format')!r}, expected {CAMERAS_FORMAT!r}")
    try:
        frames = data["frames"]
        return Cameras(
            K=np.array([f["K"] for f in frames], dtype=np.float64).reshape(len(frames), 3, 3),
            world_to_camera=np.array([f["world_to_camera"] for f in frames], dtype=np.float64).reshape(
                len(frames), 4, 4
            ),
            width=int(data["width"]),
            height=int(data["height"]),
            names=tuple(str(f["name"]) for f in frames),
        )
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{source}: malformed cameras ({exc!r})") from None


def check_capture_files(directory: str | Path) -> None:
    """Check that a capture directory holds every image and mask its ``cameras.json`` lists.

    Run before a capture is moved into place, so a capture whose writing was cut short (or
    shared with another writer) can never look complete.

    Raises
    ------
    ValueError
        Naming the directory, how many files it lacks and the first of them.
    """
    directory = Path(directory)
    with open(directory / "cameras.json") as f:
        frames = json.load(f).get("frames", [])
    listed = [directory / f[key] for f in frames for key in ("image", "mask")]
    missing = [p for p in listed if not p.is_file()]
    if missing or not frames:
        first = missing[0].relative_to(directory) if missing else "any frame"
        raise ValueError(f"{directory}: cameras.json lists {len(frames)} views, but {len(missing)} of their "
                         f"{len(listed)} images and masks are missing (first: {first})")
