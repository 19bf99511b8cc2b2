"""Synthetic samples shared by the SH tests: hemisphere directions and lobe filters."""

from __future__ import annotations

import numpy as np

from freqbrdf.sphere import sampling, sh


def upper_hemisphere(n: int) -> np.ndarray:
    """Fibonacci points on the local upper hemisphere (z = normal), (n, 3)."""
    p = sampling.fibonacci_hemisphere(n)  # about +Y
    return np.stack([p[:, 0], -p[:, 2], p[:, 1]], axis=-1)


def random_unit(shape: tuple[int, ...], rng: np.random.Generator) -> np.ndarray:
    d = rng.normal(size=shape + (3,))
    return d / np.linalg.norm(d, axis=-1, keepdims=True)


def filter_coeffs(coeffs: np.ndarray, alpha: float) -> np.ndarray:
    """Specular-lobe filter exp(-(alpha l)^2) on a (n_coeffs, ...) coefficient array."""
    lmax = round(np.sqrt(coeffs.shape[0])) - 1
    f = np.exp(-((alpha * sh.sh_degrees(lmax)) ** 2))
    return coeffs * f.reshape((-1,) + (1,) * (coeffs.ndim - 1))


def rewrite_z_up(root, mesh, camera_axes: np.ndarray | None = None) -> None:
    """Rewrite an exchange-layout capture in ``root`` as a Z-up tool would hand it over.

    The mesh (a `freqbrdf.scene.meshes.Mesh`, Y-up) becomes ``mesh.obj`` in a Z-up
    world, without normals; the cameras of ``transforms_*.json`` are turned into
    that world and, with ``camera_axes`` (4, 4), re-expressed in other camera axes
    (``diag(1, -1, -1, 1)``: OpenCV's).
    """
    from freqbrdf.capture.exchange import Y_UP_FROM_Z_UP
    from freqbrdf.util.io import read_json, write_json

    z_up = mesh.vertices @ Y_UP_FROM_Z_UP  # the inverse of the import's rotation
    lines = ["# Z-up, no normals: the import recomputes them"]
    lines += [f"v {x:.9g} {y:.9g} {z:.9g}" for x, y, z in z_up] + [f"vt {u:.9g} {v:.9g}" for u, v in mesh.uvs]
    lines += [f"f {a + 1}/{a + 1} {b + 1}/{b + 1} {c + 1}/{c + 1}" for a, b, c in mesh.faces]
    (root / "mesh.obj").write_text("\n".join(lines) + "\n")
    world = np.eye(4)
    world[:3, :3] = Y_UP_FROM_Z_UP.T
    axes = np.eye(4) if camera_axes is None else camera_axes
    for split in ("train", "test"):
        transforms = read_json(root / f"transforms_{split}.json")
        for frame in transforms["frames"]:
            frame["transform_matrix"] = (world @ np.array(frame["transform_matrix"]) @ axes).tolist()
        write_json(root / f"transforms_{split}.json", transforms)


def fake_package(path, members: dict) -> None:
    """A tarball laid out like the package: each member a JS module of one base64 data URI."""
    import base64
    import io
    import tarfile

    with tarfile.open(path, "w:gz") as tar:
        for name, data in members.items():
            text = f"export default 'data:application/octet-stream;base64,{base64.b64encode(data).decode()}'\n".encode()
            info = tarfile.TarInfo(name)
            info.size = len(text)
            tar.addfile(info, io.BytesIO(text))
