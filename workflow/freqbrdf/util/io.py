"""File input and output: float EXR images, PNG previews and JSON, written atomically.

Every writer goes through :func:`atomic_path`, so a killed job never leaves a
half-written file that looks complete. Every reader fails with a one-line
message that names the file and what is wrong with it.
"""

from __future__ import annotations

import contextlib
import json
import os
import secrets
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

_CHANNELS_BY_DEPTH = {1: "Y", 3: "RGB", 4: "RGBA"}


@contextlib.contextmanager
def atomic_path(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path next to ``path``; move it into place on success.

    The parent directory is created. The file is created with the process's
    umask (like any other output, unlike ``mkstemp``'s owner-only mode) and
    flushed to disk before the rename, so a crash just after cannot leave an
    empty file behind a complete name. On an exception the temporary file is
    removed and ``path`` is left untouched.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp_path = path.with_name(f".{path.stem}.{secrets.token_hex(6)}{path.suffix or '.tmp'}")
    os.close(os.open(tmp_path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666))
    try:
        yield tmp_path
        with open(tmp_path, "rb") as written:
            os.fsync(written.fileno())
        os.replace(tmp_path, path)
    finally:
        tmp_path.unlink(missing_ok=True)


class WriterLockError(RuntimeError):
    """Another live process is writing the same output."""


@contextlib.contextmanager
def writer_lock(path: str | os.PathLike) -> Iterator[None]:
    """Hold an exclusive lock on writing ``path`` (a hidden ``.{name}.lock`` beside it, naming the holder).

    Two writers of one output (a job orphaned by a killed Snakemake and its rerun) would mix
    their files; the second stops instead. The kernel releases the lock when its process
    dies, however it dies, so a dead writer never blocks a rerun; the file is removed on release.
    On a file system without ``flock`` (NFS mounted ``nolock``) it warns and writes unguarded,
    as the run lock does.

    Raises
    ------
    WriterLockError
        Naming the output and the host and pid that hold it.
    """
    import errno
    import fcntl
    import socket
    import sys

    lock = Path(path).with_name(f".{Path(path).name}.lock")
    lock.parent.mkdir(parents=True, exist_ok=True)
    while True:
        fd = os.open(lock, os.O_RDWR | os.O_CREAT, 0o666)
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError as error:
            holder = os.read(fd, 256).decode(errors="replace").strip() or "unknown"
            os.close(fd)
            if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
                raise WriterLockError(f"{path}: another process ({holder}) is writing it; wait for that job to "
                                      "end or stop it, then rerun") from None
            print(f"Warning: {lock}: no flock on this file system ({error.strerror}); nothing stops a second "
                  "writer of this output", file=sys.stderr)
            fd = None
            break
        try:  # the lock file may have been removed and remade by its last holder: lock the current one
            if os.stat(lock).st_ino == os.fstat(fd).st_ino:
                break
        except FileNotFoundError:
            pass
        os.close(fd)
    if fd is None:
        lock.unlink(missing_ok=True)
        yield
        return
    try:
        os.ftruncate(fd, 0)
        os.write(fd, f"pid {os.getpid()} on {socket.gethostname()}".encode())
        yield
    finally:
        lock.unlink(missing_ok=True)  # before the release, so that no one locks a file that is gone
        os.close(fd)


@contextlib.contextmanager
def atomic_directory(path: str | os.PathLike, complete: Callable[[Path], None] | None = None) -> Iterator[Path]:
    """Yield an empty sibling directory of ``path`` that replaces ``path`` on success.

    Whatever was being written is removed on an exception, so an interrupted
    job never leaves a directory that looks complete. One writer at a time
    (:func:`writer_lock`); ``complete(directory)``, when given, checks the written
    directory against its own manifest and raises before anything is renamed into place.
    """
    import shutil

    path = Path(path)
    tmp = path.with_name(f".{path.name}.partial")
    with writer_lock(path):
        shutil.rmtree(tmp, ignore_errors=True)
        tmp.mkdir(parents=True)
        try:
            yield tmp
            if complete is not None:
                complete(tmp)
            shutil.rmtree(path, ignore_errors=True)
            tmp.rename(path)
        finally:
            shutil.rmtree(tmp, ignore_errors=True)


def write_exr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write a float32 OpenEXR image (ZIP compression).

    Parameters
    ----------
    path : path-like
        Destination file.
    image : ndarray, shape (H, W), (H, W, 1), (H, W, 3) or (H, W, 4)
        Linear values; stored as channel ``Y``, ``RGB`` or ``RGBA``.

    Raises
    ------
    ValueError
        If the shape is not an image or values are not finite.
    """
    import OpenEXR

    image = np.asarray(image, dtype=np.float32)
    if image.ndim == 3 and image.shape[2] == 1:
        image = image[..., 0]
    depth = 1 if image.ndim == 2 else image.shape[2] if image.ndim == 3 else None
    if depth not in _CHANNELS_BY_DEPTH:
        raise ValueError(f"{path}: cannot write an image of shape {image.shape} as EXR (need (H, W) or (H, W, 1|3|4))")
    bad = int(np.count_nonzero(~np.isfinite(image)))
    if bad:
        raise ValueError(f"{path}: refusing to write {bad} NaN/Inf values")
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    with atomic_path(path) as tmp, OpenEXR.File(header, {_CHANNELS_BY_DEPTH[depth]: np.ascontiguousarray(image)}) as f:
        f.write(str(tmp))


def read_exr(path: str | os.PathLike, *, allow_nonfinite: bool = False) -> np.ndarray:
    """Read an OpenEXR image as float32.

    Parameters
    ----------
    path : path-like
        EXR file with channels ``Y``, ``RGB`` or ``RGBA`` (other single-layer
        channel sets are stacked in name order).
    allow_nonfinite : bool
        Return NaN/Inf pixels instead of raising (callers that mask and count
        them, e.g. observation extraction, set this).

    Returns
    -------
    ndarray, shape (H, W) or (H, W, C), float32

    Raises
    ------
    FileNotFoundError
        If the file does not exist.
    ValueError
        If it is not a readable EXR or holds NaN/Inf values.
    """
    import OpenEXR

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: EXR file not found")
    try:
        with OpenEXR.File(str(path)) as f:
            channels = f.channels()
            if len(channels) == 1:
                image = next(iter(channels.values())).pixels
            else:
                image = np.stack([channels[name].pixels for name in sorted(channels)], axis=-1)
            image = np.array(image, dtype=np.float32)
    except Exception as exc:  # OpenEXR raises bare RuntimeErrors without the reason
        raise ValueError(f"{path}: not a readable OpenEXR file ({exc})") from None
    if not allow_nonfinite:
        bad = int(np.count_nonzero(~np.isfinite(image)))
        if bad:
            raise ValueError(f"{path}: {bad} NaN/Inf values")
    return image


def write_png(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write an 8-bit PNG from display values in [0, 1] or from uint8.

    Parameters
    ----------
    path : path-like
        Destination file.
    image : ndarray, shape (H, W) or (H, W, 3|4)
        Float values in [0, 1] (clipped) or uint8.
    """
    import skimage.io

    image = np.asarray(image)
    if image.dtype != np.uint8:
        image = np.round(np.clip(image, 0.0, 1.0) * 255.0).astype(np.uint8)
    with atomic_path(path) as tmp:
        skimage.io.imsave(tmp, image, check_contrast=False)


def read_png(path: str | os.PathLike) -> np.ndarray:
    """Read a PNG as uint8, shape (H, W) or (H, W, C).

    Raises
    ------
    FileNotFoundError, ValueError
        Naming the file when it is missing or not a readable image.
    """
    import imageio.v3 as iio  # what skimage.io.imread runs for a PNG, without its 0.3 s import

    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: PNG file not found")
    try:
        return np.asarray(iio.imread(path))
    except Exception as exc:  # imageio's reasons run over several lines; the first one says it
        reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
        raise ValueError(f"{path}: not a readable PNG ({reason})") from None


def write_json(path: str | os.PathLike, data: Any) -> None:
    """Write ``data`` as indented JSON, atomically."""
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(data, indent=1) + "\n")


def read_json(path: str | os.PathLike) -> Any:
    """Read JSON, with a one-line error naming the file if missing or malformed."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"{path}: JSON file not found")
    try:
        return json.loads(path.read_text())
    except json.JSONDecodeError as exc:
        raise ValueError(f"{path}: malformed JSON ({exc})") from None


def read_views(capture_dir: str | os.PathLike, names: list[str] | tuple[str, ...], width: int, height: int) -> tuple[np.ndarray, np.ndarray, int]:
    """Load the HDR views and coverage masks of a capture.

    Parameters
    ----------
    capture_dir : path-like
        Directory with ``images/{name}.exr`` and ``masks/{name}.png``.
    names : sequence of str
        Views to load, in order.
    width, height : int
        Expected image size (from the cameras).

    Returns
    -------
    images : ndarray, shape (K, H, W, 3), float32
        NaN/Inf pixels are kept (callers mask them).
    coverage : ndarray, shape (K, H, W), float32 in [0, 1]
    nonfinite : int
        Number of NaN/Inf pixel values found.

    Raises
    ------
    ValueError
        Naming the file whose size or channel count is wrong.
    """
    capture_dir = Path(capture_dir)
    images = np.empty((len(names), height, width, 3), np.float32)
    coverage = np.empty((len(names), height, width), np.float32)
    for k, name in enumerate(names):
        path = capture_dir / "images" / f"{name}.exr"
        image = read_exr(path, allow_nonfinite=True)
        if image.ndim != 3 or image.shape[2] < 3 or image.shape[:2] != (height, width):
            raise ValueError(f"{path}: image is {image.shape}, cameras say ({height}, {width}, 3)")
        images[k] = image[..., :3]
        mask_path = capture_dir / "masks" / f"{name}.png"
        mask = read_png(mask_path)
        if mask.ndim == 3:
            mask = mask[..., 0]
        if mask.shape != (height, width):
            raise ValueError(f"{mask_path}: mask is {mask.shape}, cameras say ({height}, {width})")
        coverage[k] = mask / 255.0
    return images, coverage, int(np.count_nonzero(~np.isfinite(images)))
