"""Captures in the NeRF-Blender / Stanford-ORB layout, to and from the native layout.

The exchange layout (Stanford-ORB's ``blender_HDR`` plus the two files this
method needs):

```
{capture}/
  transforms_train.json   {"camera_angle_x": radians, "frames": [{"file_path": "./train/0000",
  transforms_test.json     "transform_matrix": 4x4 camera-to-world, OpenGL/Blender axes}]}
  train/0000.exr ...      linear HDR views
  train_mask/0000.png     8-bit object masks (255 = object)
  test/, test_mask/       the held-out split
  mesh.ply or mesh.obj     the object's mesh with UVs (any common layout, freqbrdf.capture.mesh_io)
  envmap.exr              equirect environment map lighting the train views
  test_env/0000.exr       optional: the environment of each test view (Stanford-ORB
                          relights every test view under its own); default envmap.exr
```

Axes, named per capture in config (``up_axis``, ``camera``):

- World: ``y`` (this project, Mitsuba) or ``z`` (Blender, Stanford-ORB) up.
  A Z-up capture is turned into Y-up by ``(x, y, z) -> (x, z, -y)``, a proper
  rotation, applied to the mesh and the cameras. An equirect map's top row is
  the up axis whatever the frame, so the map is kept as it is; its azimuth
  origin may differ from this project's, which :mod:`freqbrdf.capture.orientation`
  detects (rule ``env_orientation``).
- Cameras: ``opengl`` (Blender, NeRF: looking down -z with y up, so the
  camera-to-world is the OpenCV one with the y and z axes negated) or
  ``opencv`` (looking down +z with y down, e.g. COLMAP-derived files).

Optional per-file intrinsics ``fl_x``, ``fl_y``, ``cx``, ``cy`` (instant-ngp
style) are honoured on import; otherwise ``camera_angle_x`` and a centred
principal point.
"""

from __future__ import annotations

import hashlib
import logging
import math
import os
import shutil
from pathlib import Path

import numpy as np

from freqbrdf.scene.cameras import Cameras, cameras_to_json
from freqbrdf.scene.hdri import clean_envmap
from freqbrdf.scene.scans import AtlasSettings
from freqbrdf.util.io import read_exr, read_json, read_png, write_exr, write_json, write_png
from freqbrdf.scene.meshes import Mesh
from freqbrdf.scene.ply import write_ply

SPLITS = ("train", "test")
UP_AXES = ("y", "z")
CAMERA_CONVENTIONS = ("opengl", "opencv")
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])
# World rotation of a Z-up capture into this project's Y-up frame: (x, y, z) -> (x, z, -y).
Y_UP_FROM_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
# Written beside an imported split's cameras.json: the user's transforms file and, per
# view name, the frame's file_path, so later stages name the user's files, not the copy.
SOURCE_RECORD = "source.json"


def blender_transforms(cameras: Cameras, split: str) -> dict:
    """``transforms_{split}.json`` content for ``cameras`` (frames ``./{split}/0000``...).

    Raises
    ------
    ValueError
        If the cameras do not share one focal length with a centred principal
        point, which ``camera_angle_x`` cannot express.
    """
    fov_x = math.radians(pinhole_fov_deg(cameras, "blender layout"))
    frames = []
    for k in range(len(cameras)):
        c2w_gl = np.linalg.inv(cameras.world_to_camera[k]) @ _GL_FROM_CV
        frames.append({"file_path": f"./{split}/{k:04d}", "transform_matrix": c2w_gl.tolist()})
    return {"camera_angle_x": fov_x, "frames": frames}


def pinhole_fov_deg(cameras: Cameras, source: str | os.PathLike) -> float:
    """Horizontal field of view (degrees) of cameras that one fov can describe.

    Raises
    ------
    ValueError
        Naming ``source`` unless every camera has the same square-pixel focal
        length and a centred principal point (what ``camera_angle_x`` and
        Mitsuba's ``fov`` express).
    """
    K = cameras.K
    if not (np.allclose(K[:, 0, 0], K[0, 0, 0]) and np.allclose(K[:, 1, 1], K[:, 0, 0])
            and np.allclose(K[:, 0, 2], cameras.width / 2) and np.allclose(K[:, 1, 2], cameras.height / 2)):
        raise ValueError(f"{source}: needs one square-pixel focal length and a centred principal point")
    return math.degrees(2.0 * math.atan(cameras.width / (2.0 * K[0, 0, 0])))


def cameras_from_blender(transforms: dict, width: int, height: int, source: str | Path,
                         camera: str = "opengl", up_axis: str = "y") -> tuple[Cameras, list[str]]:
    """Cameras (OpenCV) and frame file paths from a ``transforms_*.json`` dictionary.

    Parameters
    ----------
    transforms : dict
        Parsed ``transforms_{split}.json``.
    width, height : int
        Image size (the file does not store it).
    source : path-like
        Name used in error messages.
    camera : {"opengl", "opencv"}
        Convention of the ``transform_matrix`` camera axes.
    up_axis : {"y", "z"}
        World up axis of the file; a Z-up world is turned into Y-up.

    Returns
    -------
    cameras : Cameras
        OpenCV, Y-up world; views named ``0000``, ``0001``... in file order.
    file_paths : list of str
        The frames' ``file_path`` entries.
    """
    try:
        frames = transforms["frames"]
        if not frames:
            raise ValueError("no frames")
        fx = float(transforms["fl_x"]) if "fl_x" in transforms else width / (2.0 * math.tan(float(transforms["camera_angle_x"]) / 2.0))
        fy = float(transforms.get("fl_y", fx))
        cx, cy = float(transforms.get("cx", width / 2.0)), float(transforms.get("cy", height / 2.0))
        c2w = np.array([f["transform_matrix"] for f in frames], dtype=np.float64).reshape(len(frames), 4, 4)
        paths = [str(f["file_path"]) for f in frames]
    except (KeyError, TypeError, ValueError) as exc:
        raise ValueError(f"{source}: malformed transforms ({exc!r})") from None
    rotation = c2w[:, :3, :3]
    if not np.isfinite(c2w).all() or not np.allclose(np.einsum("kji,kjl->kil", rotation, rotation), np.eye(3), atol=1e-4):
        bad = next(k for k in range(len(frames)) if not (np.isfinite(c2w[k]).all() and np.allclose(
            rotation[k].T @ rotation[k], np.eye(3), atol=1e-4)))
        raise ValueError(f"{source}: frame {bad} transform_matrix is not a rigid camera-to-world transform")
    if up_axis == "z":
        world = np.eye(4)
        world[:3, :3] = Y_UP_FROM_Z_UP
        c2w = world @ c2w
    w2c = np.linalg.inv(c2w @ _GL_FROM_CV if camera == "opengl" else c2w)
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    cameras = Cameras(K=np.repeat(K[None], len(frames), 0), world_to_camera=w2c, width=width, height=height,
                      names=tuple(f"{k:04d}" for k in range(len(frames))))
    return cameras, paths



def inside(root: Path, path: Path, what: str) -> Path:
    """``path`` if it lies inside ``root`` once ``..`` and symbolic links are resolved.

    A capture received from someone else must only ever read its own files: a frame whose
    ``file_path`` is ``../elsewhere/x``, an absolute path or a link out of the capture is refused.

    Raises
    ------
    ValueError
        One line naming ``what`` (e.g. the frame and its transforms file) and where the path leads.
    """
    target = path.resolve()
    if not target.is_relative_to(root.resolve()):
        raise ValueError(f"{root}: {what} leads to {target}, outside the capture's directory "
                         "(a capture may only name files inside it)")
    return path


def _frame_files(root: Path, split: str, file_path: str, what: str) -> tuple[Path, Path]:
    """Image and mask files of one frame: ``{file_path}.exr`` and ``{split}_mask/{stem}.png``, both
    inside ``root`` (:func:`inside`; ``what`` names the frame)."""
    image = root / (file_path if file_path.endswith(".exr") else f"{file_path}.exr")
    mask = root / f"{split}_mask" / f"{Path(file_path).stem}.png"
    return inside(root, image, what), inside(root, mask, f"the mask of {what}")


def export_capture(splits: dict[str, Path], mesh: Path, envmap: Path, out: Path) -> None:
    """Write native capture directories, mesh and environment in the exchange layout.

    Parameters
    ----------
    splits : dict
        ``{"train": dir, "test": dir}`` native capture directories
        (``cameras.json``, ``images/``, ``masks/``).
    mesh, envmap : Path
        The object's PLY mesh and the environment EXR.
    out : Path
        Destination directory (created).
    """
    from freqbrdf.scene.cameras import cameras_from_json

    out.mkdir(parents=True, exist_ok=True)
    for split, capture in splits.items():
        cameras = cameras_from_json(read_json(capture / "cameras.json"), source=capture / "cameras.json")
        (out / split).mkdir(exist_ok=True)
        (out / f"{split}_mask").mkdir(exist_ok=True)
        for k, name in enumerate(cameras.names):
            shutil.copyfile(capture / "images" / f"{name}.exr", out / split / f"{k:04d}.exr")
            shutil.copyfile(capture / "masks" / f"{name}.png", out / f"{split}_mask" / f"{k:04d}.png")
        write_json(out / f"transforms_{split}.json", blender_transforms(cameras, split))
    shutil.copyfile(mesh, out / "mesh.ply")
    shutil.copyfile(envmap, out / "envmap.exr")


def source_checksum(source: str | os.PathLike) -> str:
    """SHA-256 of the names and contents of every file under a capture directory.

    Snakemake sees only a directory's own timestamp, which does not change when
    a file inside is rewritten; the import's params carry this checksum, so
    replacing any mask, image, mesh or map re-imports the capture. Hidden files
    (``.DS_Store``, editors' swap files) are left out.

    Returns
    -------
    str
        Hex digest; ``"absent"`` if the directory does not exist (yet).
    """
    root = Path(source)
    if not root.is_dir():
        return "absent"
    digest = hashlib.sha256()
    files = sorted(p for p in root.rglob("*") if p.is_file() and not any(
        part.startswith(".") for part in p.relative_to(root).parts))
    for path in files:
        digest.update(str(path.relative_to(root)).encode() + b"\0")
        with open(path, "rb") as handle:
            for block in iter(lambda: handle.read(1 << 22), b""):
                digest.update(block)
        digest.update(b"\0")
    return digest.hexdigest()


def checked_view(path: Path, shape: tuple[int, int] | None = None) -> np.ndarray:
    """An HDR view read and checked: an RGB(A) EXR of the expected size (NaN pixels allowed).

    Returns
    -------
    ndarray, shape (H, W, 3), float32

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming ``path``.
    """
    image = read_exr(path, allow_nonfinite=True)
    if image.ndim != 3 or image.shape[2] < 3:
        raise ValueError(f"{path}: image has shape {image.shape}; an RGB or RGBA view is needed")
    if shape is not None and image.shape[:2] != shape:
        raise ValueError(f"{path}: image is {image.shape[:2]}, the first view of its split is {shape}")
    return image[..., :3]


def checked_mask(path: Path, shape: tuple[int, int]) -> np.ndarray:
    """An object mask read and checked, as 8-bit coverage (255 = object).

    Accepts 8- or 16-bit, grey, RGB or RGBA PNGs (the first channel is the mask).

    Returns
    -------
    ndarray, shape (H, W), uint8
    """
    if not path.is_file():
        raise FileNotFoundError(f"{path}: mask file not found")
    mask = read_png(path)
    if mask.ndim == 3:
        mask = mask[..., 0]
    if mask.shape != shape:
        raise ValueError(f"{path}: mask is {mask.shape}, its image is {shape}")
    if mask.dtype == np.bool_:
        return mask.astype(np.uint8) * 255
    if mask.dtype == np.uint16:
        return np.round(mask / 257.0).astype(np.uint8)
    if mask.dtype != np.uint8:
        raise ValueError(f"{path}: mask has pixel type {mask.dtype}; an 8- or 16-bit PNG is needed")
    return mask


def checked_envmap(path: Path, log: logging.Logger | None = None) -> np.ndarray:
    """An environment map read and checked: equirect (H, 2H), RGB, not black; a few negative
    or non-finite texels (a lossy EXR's ringing) are cleaned (:func:`freqbrdf.scene.hdri.clean_envmap`)
    with a warning giving their count and the power it changed.

    Returns
    -------
    ndarray, shape (H, 2H, 3), float32

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming ``path``: not an RGB equirect map, black, or more than 10% of its
        texels negative or non-finite.
    """
    env = read_exr(path, allow_nonfinite=True)
    if env.ndim != 3 or env.shape[2] < 3 or env.shape[1] != 2 * env.shape[0]:
        raise ValueError(f"{path}: environment map has shape {env.shape}; an RGB equirect map of (H, 2H) is needed")
    env, cleaning = clean_envmap(env[..., :3], source=str(path))
    if cleaning:
        (log or logging.getLogger(__name__)).warning("%s: %s", path, cleaning.describe())
    if not env.max() > 0:
        raise ValueError(f"{path}: environment map is black")
    return env


def orient_mesh(mesh: Mesh, up_axis: str) -> Mesh:
    """The mesh in the Y-up world: unchanged for ``y``, turned by :data:`Y_UP_FROM_Z_UP` for ``z``."""
    if up_axis == "y":
        return mesh
    return Mesh(vertices=mesh.vertices @ Y_UP_FROM_Z_UP.T, normals=mesh.normals @ Y_UP_FROM_Z_UP.T,
                uvs=mesh.uvs, faces=mesh.faces)


def find_mesh(source: Path) -> Path:
    """The capture's mesh file: ``mesh.ply`` or ``mesh.obj`` (exactly one of them)."""
    found = [source / name for name in ("mesh.ply", "mesh.obj") if (source / name).is_file()]
    if len(found) != 1:
        what = "both mesh.ply and mesh.obj" if found else "no mesh.ply or mesh.obj"
        raise FileNotFoundError(f"{source}: the capture has {what} (exactly one is needed)")
    return found[0]


def _frame_paths(source: Path, split: str) -> tuple[Path, dict, list[str]]:
    """The transforms file of a split, its contents and its frames' ``file_path``, every frame's
    files checked to lie inside ``source`` (:func:`inside`)."""
    transforms_file = inside(source, source / f"transforms_{split}.json", f"transforms_{split}.json")
    transforms = read_json(transforms_file)
    paths = [str(f.get("file_path", "")) for f in transforms.get("frames", [])] if isinstance(transforms, dict) else []
    if not paths:
        raise ValueError(f"{transforms_file}: no frames")
    for file_path in paths:
        _frame_files(source, split, file_path, f"frame {file_path!r} of {transforms_file.name}")
    return transforms_file, transforms, paths


def import_capture(source: Path, splits: dict[str, Path], mesh: Path, envmap: Path, *,
                   up_axis: str = "y", camera: str = "opengl", atlas: AtlasSettings | None = None,
                   log: logging.Logger | None = None) -> dict[str, int]:
    """Convert an exchange-layout capture into native capture directories, reading every file.

    Every view, mask, the mesh and the environment maps are read and checked
    here, so a bad file fails the import naming the user's file, not a copy.

    Parameters
    ----------
    source : Path
        Capture in the exchange layout.
    splits : dict
        ``{"train": dir, "test": dir}`` native directories to create. A test
        split with per-view environments (``test_env/``) gets ``envmaps/{name}.exr``;
        each gets a :data:`SOURCE_RECORD` naming the user's files (:func:`capture_source`).
    mesh, envmap : Path
        Where to write the mesh (pipeline PLY layout, Y-up) and the environment map.
    atlas, log : AtlasSettings, logging.Logger, optional
        Unwrap a mesh without usable UVs (:func:`freqbrdf.capture.mesh_io.clean_mesh`) instead of
        refusing it; where that and an environment map's clean-up are reported.
    up_axis : {"y", "z"}
        World up axis of the capture.
    camera : {"opengl", "opencv"}
        Camera convention of the transforms.

    Returns
    -------
    dict
        Number of views per split.

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming the missing or inconsistent file.
    """
    if up_axis not in UP_AXES or camera not in CAMERA_CONVENTIONS:
        raise ValueError(f"up_axis must be one of {UP_AXES} and camera one of {CAMERA_CONVENTIONS}, "
                         f"got {up_axis!r}, {camera!r}")
    if not source.is_dir():
        raise FileNotFoundError(f"{source}: capture directory not found")
    from freqbrdf.capture.mesh_io import read_mesh

    # Every path the capture names stays inside it, checked before anything is read or written.
    frames = {split: _frame_paths(source, split) for split in splits}
    # Mesh and environment first: they are few and the most likely to be wrong.
    mesh_file = inside(source, find_mesh(source), "the mesh")
    oriented = orient_mesh(read_mesh(mesh_file, atlas, log), up_axis)
    if not (source / "envmap.exr").is_file():
        raise FileNotFoundError(f"{source / 'envmap.exr'}: the capture's envmap.exr is missing")
    train_env = checked_envmap(inside(source, source / "envmap.exr", "envmap.exr"), log)
    counts = {}
    for split, out in splits.items():
        transforms_file, transforms, paths = frames[split]
        first_image, _ = _frame_files(source, split, paths[0], f"frame {paths[0]!r} of {transforms_file.name}")
        if not first_image.is_file():
            raise FileNotFoundError(f"{first_image}: frame {paths[0]!r} of {transforms_file.name} is missing")
        height, width = checked_view(first_image).shape[:2]
        cameras, paths = cameras_from_blender(transforms, width, height, transforms_file, camera, up_axis)
        per_view_envs = split == "test" and (source / "test_env").is_dir()
        for sub in ("images", "masks") + (("envmaps",) if per_view_envs else ()):
            (out / sub).mkdir(parents=True, exist_ok=True)
        for name, file_path in zip(cameras.names, paths):
            image, mask = _frame_files(source, split, file_path, f"frame {file_path!r} of {transforms_file.name}")
            if not image.is_file():
                raise FileNotFoundError(f"{image}: frame {file_path!r} of {transforms_file.name} is missing")
            checked_view(image, (height, width))
            # Copied, not rewritten: NaN pixels are kept for extraction to mask and count.
            shutil.copyfile(image, out / "images" / f"{name}.exr")
            write_png(out / "masks" / f"{name}.png", checked_mask(mask, (height, width)))
            if per_view_envs:
                env_file = inside(source, source / "test_env" / f"{Path(file_path).stem}.exr",
                                  f"the environment of frame {file_path!r}")
                write_exr(out / "envmaps" / f"{name}.exr", checked_envmap(env_file, log))
        write_json(out / "cameras.json", cameras_to_json(cameras))
        write_json(out / SOURCE_RECORD, {"transforms": str(transforms_file), "frames": dict(zip(cameras.names, paths))})
        counts[split] = len(cameras)
    write_ply(mesh, oriented)
    write_exr(envmap, train_env)
    return counts


def capture_source(capture: str | os.PathLike, names: list[str] | tuple[str, ...]) -> tuple[str, list[str]]:
    """A native capture as its user knows it, for messages.

    Parameters
    ----------
    capture : path-like
        A native capture directory (``cameras.json``, ``images/``, ``masks/``).
    names : sequence of str
        Its view names.

    Returns
    -------
    source : str
        The user's ``transforms_{split}.json`` for a capture :func:`import_capture`
        wrote (its :data:`SOURCE_RECORD`), else the directory itself.
    labels : list of str
        Each view's frame ``file_path`` in that file, else its name.
    """
    record = Path(capture) / SOURCE_RECORD
    if not record.is_file():
        return str(capture), list(names)
    content = read_json(record)
    return str(content["transforms"]), [str(content["frames"].get(name, name)) for name in names]


def import_textures(source: Path, out: dict[str, Path], resolution: int) -> None:
    """Ground-truth SVBRDF textures of a real capture, read, checked and written.

    Parameters
    ----------
    source : Path
        Directory with ``base_color.exr``, ``roughness.exr``, ``metallic.exr``
        (:func:`freqbrdf.artefacts.read_svbrdf` layout, values in [0, 1]).
    out : dict
        Destination EXR per texture name.
    resolution : int
        The atlas size the estimates have (config ``textures.resolution``).

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming the user's file.
    """
    from freqbrdf.artefacts import read_svbrdf

    if not source.is_dir():
        raise FileNotFoundError(f"{source}: ground-truth texture directory not found")
    truth = read_svbrdf(source)
    for name, texture in truth.items():
        if texture.shape[:2] != (resolution, resolution):
            raise ValueError(f"{source / (name + '.exr')}: texture is {texture.shape[:2]}, the estimates are "
                             f"({resolution}, {resolution}) (config textures.resolution)")
        write_exr(out[name], texture)
