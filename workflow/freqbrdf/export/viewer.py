"""A self-contained HTML page that shows a capture's exported materials side by side.

The page (``web/viewer.html`` and ``web/viewer.js``) draws one panel per
material with three.js (vendored in ``web/vendor``, see its README), all
panels through one camera, lit by a selectable environment map, with the
capture's entropy map as an optional overlay on the methods' panels.

Everything is inlined in the one file, the models included: a page opened
from ``file://`` may neither import modules nor fetch files. The materials
come from the exported ``.glb`` files, re-packed into one glTF scene that
stores the shared mesh once (:func:`freqbrdf.export.gltf.glb_bytes`), since eleven
copies of a mesh would make the page (and the report embedding it) tens of
megabytes.
"""

from __future__ import annotations

import base64
import json
import re
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from freqbrdf.export.gltf import GltfMaterial, encode_png, glb_bytes
from freqbrdf.scene.meshes import Mesh

__all__ = ["WEB_DIR", "WEB_ASSETS", "THREE_VERSION", "Panel", "entropy_overlay", "same_mesh", "viewer_html"]

WEB_DIR = Path(__file__).parent / "web"
WEB_ASSETS = ("viewer.html", "viewer.js", "vendor/three.bundle.min.js")
"""Files of ``WEB_DIR`` that every page is built from (a rule's inputs)."""
THREE_VERSION = "0.187.0"
"""three.js version of ``web/vendor/three.bundle.min.js`` (web/vendor/package.json)."""
BACKGROUND = "#3a3a40"
"""Clear colour of the panels: mid-dark, so that neither a black nor a white object vanishes."""


@dataclass(frozen=True)
class Panel:
    """One panel of the page.

    Attributes
    ----------
    name : str
        Its node and material in the scene (the method, or ``truth``).
    label : str
        Its caption.
    overlay : bool
        Whether the entropy overlay is drawn on it (the methods' panels).
    """

    name: str
    label: str
    overlay: bool


def entropy_overlay(atlas: np.ndarray) -> np.ndarray:
    """The entropy atlas in the Turbo colour map (blue: certain, red: uncertain), as in the maps figure.

    Parameters
    ----------
    atlas : numpy.ndarray
        Shape ``(R, R)``: normalised entropy in [0, 1] (clipped).

    Returns
    -------
    numpy.ndarray
        Shape ``(R, R, 3)``, uint8, sRGB (the colour map's display values).
    """
    from matplotlib import colormaps

    atlas = np.asarray(atlas, dtype=np.float64)
    if atlas.ndim != 2:
        raise ValueError(f"entropy atlas must have shape (R, R), got {atlas.shape}")
    rgb = colormaps["turbo"](np.clip(atlas, 0.0, 1.0))[..., :3]
    return np.round(rgb * 255.0).astype(np.uint8)


def same_mesh(a: Mesh, b: Mesh) -> bool:
    """Whether two meshes hold identical vertices, normals, uvs and faces."""
    return all(np.array_equal(getattr(a, f), getattr(b, f)) for f in ("vertices", "normals", "uvs", "faces"))


def _inline(script: str) -> str:
    # A literal "</script" would end the inline <script> element early.
    return re.sub(r"</(script)", r"<\\/\1", script, flags=re.IGNORECASE)


def asset_credits(records: Sequence[Mapping]) -> list[str]:
    """One line per distinct third-party asset among source records (rule build_env's and
    build_object's ``source`` outputs): its credit and licence, in first-seen order."""
    lines = [f"{r['credit']} ({r['licence']})" for r in records if "credit" in r]
    return list(dict.fromkeys(lines))


def _escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;")


def viewer_html(title: str, mesh: Mesh, materials: Sequence[GltfMaterial], panels: Sequence[Panel],
                envs: Mapping[str, bytes], entropy: np.ndarray, camera_position: Sequence[float],
                fov_deg: float, panel_size: int = 300, credits: Sequence[str] = ()) -> str:
    """The viewer page.

    Parameters
    ----------
    title : str
        Page title and heading.
    mesh : Mesh
        The geometry every panel shows (object units, object radius 1).
    materials : sequence of GltfMaterial
        One per panel, in panel order.
    panels : sequence of Panel
        Node names (= material names), captions, overlay flags.
    envs : Mapping
        Environment name -> Radiance ``.hdr`` bytes (Mitsuba's equirect layout);
        the first is shown first.
    entropy : numpy.ndarray
        Shape ``(R, R)``: the capture's entropy atlas (:func:`entropy_overlay`).
    camera_position : sequence of float
        Shape ``(3,)``: where the shared camera starts, looking at the origin (world units).
    fov_deg : float
        Vertical field of view of the square panels, degrees.
    panel_size : int
        Smallest panel width, CSS pixels.
    credits : sequence of str
        Where the shown mesh and maps come from and under which terms (:func:`asset_credits`).

    Returns
    -------
    str
        The HTML document.
    """
    if [m.name for m in materials] != [p.name for p in panels]:
        raise ValueError(f"materials {[m.name for m in materials]} and panels {[p.name for p in panels]} disagree")
    if not envs:
        raise ValueError("the viewer needs at least one environment map")
    position = np.asarray(camera_position, dtype=np.float64)
    if position.shape != (3,) or not np.all(np.isfinite(position)) or np.linalg.norm(position) == 0:
        raise ValueError(f"camera_position must be a finite, non-zero 3-vector, got {camera_position!r}")

    def b64(data: bytes) -> str:
        return base64.b64encode(data).decode("ascii")

    data = {
        "panels": [{"name": p.name, "label": p.label, "overlay": p.overlay} for p in panels],
        "scene": b64(glb_bytes(mesh, materials)),
        "envs": {name: b64(hdr) for name, hdr in envs.items()},
        "entropy": b64(encode_png(entropy_overlay(entropy))),
        "camera": {"position": position.tolist(), "fov_deg": float(fov_deg)},
        "panel_size": int(panel_size),
        "background": BACKGROUND,
    }
    fields = {
        "TITLE": _escape(title),
        # In a <script> element "<" can only start "</script" or "<!--": escaped, JSON reads the same.
        "DATA": json.dumps(data).replace("<", "\\u003c"),
        "THREE": _inline((WEB_DIR / "vendor" / "three.bundle.min.js").read_text(encoding="utf-8")),
        "VIEWER": _inline((WEB_DIR / "viewer.js").read_text(encoding="utf-8")),
        "THREE_VERSION": THREE_VERSION,
        "CREDITS": "".join(f"<br>{_escape(line)}" for line in credits),
    }
    template = (WEB_DIR / "viewer.html").read_text(encoding="utf-8")
    # One pass: a field's text is never searched for placeholders again.
    return re.sub(r"\{\{(\w+)\}\}", lambda m: fields[m.group(1)], template)
