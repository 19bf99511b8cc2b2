"""A self-contained HTML page that shows a capture's exported materials side by side.

The page (``web/viewer.html`` and ``web/viewer.js``) draws one panel per
material with three.js (vendored in ``web/vendor``, see its README), all
panels through one camera, lit by a selectable environment map, with an
uncertainty overlay on the methods' panels: each method's own map (the
expected error under its fit's posterior, where its estimate has one; else
the capture's entropy), or the capture's entropy on every panel.

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

__all__ = ["WEB_DIR", "WEB_ASSETS", "THREE_VERSION", "ENTROPY", "POSTERIOR_RMS_MAX", "Panel", "capture_light_first",
           "overlay_image", "posterior_overlay", "same_mesh", "viewer_html"]

WEB_DIR = Path(__file__).parent / "web"
WEB_ASSETS = ("viewer.html", "viewer.js", "vendor/three.bundle.min.js")
"""Files of ``WEB_DIR`` that every page is built from (a rule's inputs)."""
THREE_VERSION = "0.187.0"
"""three.js version of ``web/vendor/three.bundle.min.js`` (web/vendor/package.json)."""
BACKGROUND = "#3a3a40"
"""Clear colour of the panels: mid-dark, so that neither a black nor a white object vanishes."""
ENTROPY = "entropy"
"""The overlay of the capture's spectrum entropy, which every page has."""
POSTERIOR_RMS_MAX = 0.25
"""Expected RMS parameter error shown in full red: above a whole `freq` estimate's RMS error on the
tuning sets (docs/tuning_log.md), so red marks texels expected to be worse than a typical estimate."""


@dataclass(frozen=True)
class Panel:
    """One panel of the page.

    Attributes
    ----------
    name : str
        Its node and material in the scene (the method, or ``truth``).
    label : str
        Its caption.
    uncertainty : str or None
        The overlay (a key of `viewer_html`'s ``overlays``) its own uncertainty layer shows;
        None: no overlay (the ground truth's panel).
    """

    name: str
    label: str
    uncertainty: str | None


def overlay_image(atlas: np.ndarray) -> np.ndarray:
    """An uncertainty atlas in the Turbo colour map (blue: certain, red: uncertain), as in the maps figure.

    Parameters
    ----------
    atlas : numpy.ndarray
        Shape ``(R, R)``: uncertainty in [0, 1] (clipped), e.g. the normalised entropy.

    Returns
    -------
    numpy.ndarray
        Shape ``(R, R, 3)``, uint8, sRGB (the colour map's display values).
    """
    from matplotlib import colormaps

    atlas = np.asarray(atlas, dtype=np.float64)
    if atlas.ndim != 2:
        raise ValueError(f"an overlay's atlas must have shape (R, R), got {atlas.shape}")
    rgb = colormaps["turbo"](np.clip(atlas, 0.0, 1.0))[..., :3]
    return np.round(rgb * 255.0).astype(np.uint8)


def posterior_overlay(score: np.ndarray) -> np.ndarray:
    """`overlay_image` of an estimate's expected squared parameter error (R, R)
    (`freqbrdf.estimate.optimise.posterior.expected_error_atlas`), as RMS error over `POSTERIOR_RMS_MAX`."""
    return overlay_image(np.sqrt(np.maximum(np.asarray(score, dtype=np.float64), 0.0)) / POSTERIOR_RMS_MAX)


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


def capture_light_first(envs: Mapping[str, bytes], env: str) -> dict[str, bytes]:
    """``envs`` with the capture's own environment ``env`` first (the page opens under the first),
    the others in their order; unchanged if ``env`` is not among them (a real capture's own light)."""
    return {name: envs[name] for name in sorted(envs, key=lambda name: name != env)}


def viewer_html(title: str, mesh: Mesh, materials: Sequence[GltfMaterial], panels: Sequence[Panel],
                envs: Mapping[str, bytes], overlays: Mapping[str, np.ndarray], camera_position: Sequence[float],
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
        Node names (= material names), captions, each panel's own uncertainty overlay.
    envs : Mapping
        Environment name -> Radiance ``.hdr`` bytes (Mitsuba's equirect layout);
        the first is shown first.
    overlays : Mapping
        Name -> ``(R, R, 3)`` uint8 sRGB image on the atlas (:func:`overlay_image`): `ENTROPY`,
        the capture's entropy, and every panel's ``uncertainty``.
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
    missing = sorted(({ENTROPY} | {p.uncertainty for p in panels if p.uncertainty is not None}) - set(overlays))
    if missing:
        raise ValueError(f"overlays {missing} are missing: given {sorted(overlays)}")
    position = np.asarray(camera_position, dtype=np.float64)
    if position.shape != (3,) or not np.all(np.isfinite(position)) or np.linalg.norm(position) == 0:
        raise ValueError(f"camera_position must be a finite, non-zero 3-vector, got {camera_position!r}")

    def b64(data: bytes) -> str:
        return base64.b64encode(data).decode("ascii")

    data = {
        "panels": [{"name": p.name, "label": p.label, "uncertainty": p.uncertainty} for p in panels],
        "scene": b64(glb_bytes(mesh, materials)),
        "envs": {name: b64(hdr) for name, hdr in envs.items()},
        "overlays": {name: b64(encode_png(image)) for name, image in overlays.items()},
        "entropy": ENTROPY,
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
        "POSTERIOR_RMS_MAX": f"{POSTERIOR_RMS_MAX:g}",
        "CREDITS": "".join(f"<br>{_escape(line)}" for line in credits),
    }
    template = (WEB_DIR / "viewer.html").read_text(encoding="utf-8")
    # One pass: a field's text is never searched for placeholders again.
    return re.sub(r"\{\{(\w+)\}\}", lambda m: fields[m.group(1)], template)
