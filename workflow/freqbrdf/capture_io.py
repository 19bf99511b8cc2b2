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
  mesh.ply                the object's mesh with normals and UVs (freqbrdf.meshes layout)
  envmap.exr              equirect environment map (freqbrdf.envmaps convention, world +Y up)
```

Camera axes: OpenGL/Blender cameras look down -z with y up, so their
camera-to-world is the OpenCV one with the y and z axes negated. Optional
per-file intrinsics ``fl_x``, ``fl_y``, ``cx``, ``cy`` (instant-ngp style) are
honoured on import; otherwise ``camera_angle_x`` and a centred principal point.
"""

from __future__ import annotations

import math
import shutil
from pathlib import Path

import numpy as np

from .cameras import Cameras, cameras_to_json
from .io import read_exr, read_json, write_json

SPLITS = ("train", "test")
_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])


def blender_transforms(cameras: Cameras, split: str) -> dict:
    """``transforms_{split}.json`` content for ``cameras`` (frames ``./{split}/0000``...).

    Raises
    ------
    ValueError
        If the cameras do not share one focal length with a centred principal
        point, which ``camera_angle_x`` cannot express.
    """
    K = cameras.K
    if not (np.allclose(K[:, 0, 0], K[0, 0, 0]) and np.allclose(K[:, 1, 1], K[:, 0, 0])
            and np.allclose(K[:, 0, 2], cameras.width / 2) and np.allclose(K[:, 1, 2], cameras.height / 2)):
        raise ValueError("blender layout needs one square-pixel focal length and a centred principal point")
    frames = []
    for k in range(len(cameras)):
        c2w_gl = np.linalg.inv(cameras.world_to_camera[k]) @ _GL_FROM_CV
        frames.append({"file_path": f"./{split}/{k:04d}", "transform_matrix": c2w_gl.tolist()})
    return {"camera_angle_x": 2.0 * math.atan(cameras.width / (2.0 * K[0, 0, 0])), "frames": frames}


def cameras_from_blender(transforms: dict, width: int, height: int, source: str | Path) -> tuple[Cameras, list[str]]:
    """Cameras (OpenCV) and frame file paths from a ``transforms_*.json`` dictionary.

    Parameters
    ----------
    transforms : dict
        Parsed ``transforms_{split}.json``.
    width, height : int
        Image size (the file does not store it).
    source : path-like
        Name used in error messages.

    Returns
    -------
    cameras : Cameras
        Views named ``0000``, ``0001``... in file order.
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
    w2c = np.linalg.inv(c2w @ _GL_FROM_CV)
    K = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]])
    cameras = Cameras(K=np.repeat(K[None], len(frames), 0), world_to_camera=w2c, width=width, height=height,
                      names=tuple(f"{k:04d}" for k in range(len(frames))))
    return cameras, paths


def _frame_files(root: Path, split: str, file_path: str) -> tuple[Path, Path]:
    """Image and mask files of one frame: ``{file_path}.exr`` and ``{split}_mask/{stem}.png``."""
    image = root / (file_path if file_path.endswith(".exr") else f"{file_path}.exr")
    return image, root / f"{split}_mask" / f"{Path(file_path).stem}.png"


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
    from .cameras import cameras_from_json

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


def import_capture(source: Path, splits: dict[str, Path], mesh: Path, envmap: Path) -> dict[str, int]:
    """Convert an exchange-layout capture into native capture directories.

    Parameters
    ----------
    source : Path
        Capture in the exchange layout.
    splits : dict
        ``{"train": dir, "test": dir}`` native directories to create.
    mesh, envmap : Path
        Where to copy the mesh and the environment map.

    Returns
    -------
    dict
        Number of views per split.

    Raises
    ------
    FileNotFoundError, ValueError
        One line naming the missing or inconsistent file.
    """
    if not source.is_dir():
        raise FileNotFoundError(f"{source}: capture directory not found")
    counts = {}
    for split, out in splits.items():
        transforms_file = source / f"transforms_{split}.json"
        transforms = read_json(transforms_file)
        paths = [str(f.get("file_path", "")) for f in transforms.get("frames", [])] if isinstance(transforms, dict) else []
        if not paths:
            raise ValueError(f"{transforms_file}: no frames")
        first_image, _ = _frame_files(source, split, paths[0])
        height, width = read_exr(first_image, allow_nonfinite=True).shape[:2]
        cameras, paths = cameras_from_blender(transforms, width, height, transforms_file)
        (out / "images").mkdir(parents=True, exist_ok=True)
        (out / "masks").mkdir(parents=True, exist_ok=True)
        for name, file_path in zip(cameras.names, paths):
            image, mask = _frame_files(source, split, file_path)
            for f in (image, mask):
                if not f.is_file():
                    raise FileNotFoundError(f"{f}: frame {file_path!r} of {transforms_file.name} is missing")
            shape = read_exr(image, allow_nonfinite=True).shape
            if shape[:2] != (height, width):
                raise ValueError(f"{image}: image is {shape[:2]}, the first {split} view is {(height, width)}")
            shutil.copyfile(image, out / "images" / f"{name}.exr")
            shutil.copyfile(mask, out / "masks" / f"{name}.png")
        write_json(out / "cameras.json", cameras_to_json(cameras))
        counts[split] = len(cameras)
    for name, dest in (("mesh.ply", mesh), ("envmap.exr", envmap)):
        if not (source / name).is_file():
            raise FileNotFoundError(f"{source / name}: the capture's {name} is missing")
        shutil.copyfile(source / name, dest)
    return counts
