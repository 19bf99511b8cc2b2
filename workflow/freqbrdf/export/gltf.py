"""SVBRDF textures on a mesh as binary glTF 2.0 (``.glb``): writing, and reading back.

glTF's metallic-roughness material is the principled BSDF's parametrisation
(docs/export.md says what differs and how it is handled):

* ``baseColorTexture`` holds the base colour **sRGB-encoded** in 8 bits (glTF
  decodes it to linear before shading); our EXR textures are linear.
* ``metallicRoughnessTexture`` holds roughness in G and metallic in B, linear,
  8 bits; R is unused (written as 255, "no occlusion", so that an engine
  that reads it as ambient occlusion leaves the surface unchanged).
* Both use GGX with ``alpha = roughness^2`` and a dielectric F0 of 0.04
  (IOR 1.5), Mitsuba's ``specular = 0.5`` default, so no factor is needed.

Texture rows need no flip: glTF puts ``uv = (0, 0)`` at the first stored
texel, our atlases put texel row 0 at ``v`` near 0 (:mod:`freqbrdf.scene.meshes`).

A file may hold several materials on one shared geometry (one node per
material, all drawing the same accessors): :func:`glb_bytes` with one
material is a capture's export, with several the viewer's scene
(:mod:`freqbrdf.export.viewer`), which so stores the mesh only once.
"""

from __future__ import annotations

import io
import os
import struct
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from freqbrdf.util.colour import to_srgb
from freqbrdf.util.io import atomic_path
from freqbrdf.scene.meshes import Mesh

__all__ = ["write_textures_glb", "GltfMaterial", "GltfScene", "srgb_to_linear", "quantise", "material_images", "textures_from_images",
           "encode_png", "decode_png", "glb_bytes", "write_glb", "read_glb"]

_FLOAT, _UINT32 = 5126, 5125  # glTF accessor componentTypes
_ARRAY_BUFFER, _ELEMENT_ARRAY_BUFFER = 34962, 34963  # bufferView targets
_LINEAR, _LINEAR_MIPMAP_LINEAR, _REPEAT = 9729, 9987, 10497  # sampler enums
_TRIANGLES = 4
NO_OCCLUSION = 255
"""The unused R channel of the metallic-roughness texture: glTF's occlusion 1 (none)."""


def srgb_to_linear(encoded: np.ndarray) -> np.ndarray:
    """Linear values of sRGB-encoded ones, the inverse of :func:`freqbrdf.util.colour.to_srgb`.

    Parameters
    ----------
    encoded : numpy.ndarray
        Any shape, display values in [0, 1] (clipped).

    Returns
    -------
    numpy.ndarray
        Same shape, float64, linear in [0, 1].
    """
    s = np.clip(np.asarray(encoded, dtype=np.float64), 0.0, 1.0)
    return np.where(s <= 0.04045, s / 12.92, ((s + 0.055) / 1.055) ** 2.4)


def quantise(values: np.ndarray) -> np.ndarray:
    """8-bit codes of values in [0, 1] (clipped), rounded to the nearest of 256 levels.

    Parameters
    ----------
    values : numpy.ndarray
        Any shape.

    Returns
    -------
    numpy.ndarray
        Same shape, uint8.
    """
    return np.round(np.clip(np.asarray(values, dtype=np.float64), 0.0, 1.0) * 255.0).astype(np.uint8)


def material_images(textures: Mapping[str, np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """The two 8-bit images of a glTF metallic-roughness material from linear SVBRDF textures.

    Parameters
    ----------
    textures : Mapping
        ``base_color`` (R, R, 3), ``roughness`` and ``metallic`` (R, R), linear in [0, 1]
        (e.g. a :class:`freqbrdf.artefacts.Svbrdf`).

    Returns
    -------
    base_color : numpy.ndarray
        Shape ``(R, R, 3)``, uint8, sRGB-encoded.
    metallic_roughness : numpy.ndarray
        Shape ``(R, R, 3)``, uint8: R :data:`NO_OCCLUSION`, G roughness, B metallic (linear).
    """
    base = np.asarray(textures["base_color"])
    rough, metal = np.asarray(textures["roughness"]), np.asarray(textures["metallic"])
    if base.ndim != 3 or base.shape[2] != 3:
        raise ValueError(f"base_color must have shape (R, R, 3), got {base.shape}")
    for name, texture in (("roughness", rough), ("metallic", metal)):
        if texture.shape != base.shape[:2]:
            raise ValueError(f"{name} texture is {texture.shape}, but base_color is {base.shape[:2]}")
    packed = np.stack([np.full(rough.shape, NO_OCCLUSION, np.uint8), quantise(rough), quantise(metal)], axis=-1)
    return quantise(to_srgb(base)), packed


def textures_from_images(base_color: np.ndarray, metallic_roughness: np.ndarray) -> dict[str, np.ndarray]:
    """Linear SVBRDF textures from a glTF material's 8-bit images (the inverse of :func:`material_images`
    up to quantisation).

    Parameters
    ----------
    base_color : numpy.ndarray
        Shape ``(H, W, 3|4)``, uint8, sRGB-encoded (alpha ignored).
    metallic_roughness : numpy.ndarray
        Shape ``(H, W, 3|4)``, uint8: G roughness, B metallic.

    Returns
    -------
    dict
        ``base_color`` (H, W, 3), ``roughness`` and ``metallic`` (H, W), float32 in [0, 1].
    """
    for name, image in (("base_color", base_color), ("metallic_roughness", metallic_roughness)):
        if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] not in (3, 4):
            raise ValueError(f"{name} image must be uint8 of shape (H, W, 3|4), got {image.dtype} {image.shape}")
    mr = metallic_roughness.astype(np.float32) / 255.0
    return {"base_color": srgb_to_linear(base_color[..., :3] / 255.0).astype(np.float32),
            "roughness": mr[..., 1], "metallic": mr[..., 2]}


def encode_png(image: np.ndarray) -> bytes:
    """PNG bytes of an 8-bit RGB image (H, W, 3), losslessly."""
    from PIL import Image

    image = np.asarray(image)
    if image.dtype != np.uint8 or image.ndim != 3 or image.shape[2] != 3:
        raise ValueError(f"encode_png needs a uint8 (H, W, 3) image, got {image.dtype} {image.shape}")
    out = io.BytesIO()
    Image.fromarray(image, "RGB").save(out, format="PNG")
    return out.getvalue()


def decode_png(data: bytes, where: str) -> np.ndarray:
    """The uint8 RGB(A) array of PNG bytes; ``where`` names them in the error if they are not a PNG."""
    from PIL import Image

    try:
        with Image.open(io.BytesIO(data)) as image:
            if image.format != "PNG":
                raise ValueError(f"format {image.format}")
            return np.asarray(image.convert("RGBA" if "A" in image.mode else "RGB"))
    except Exception as exc:
        raise ValueError(f"{where}: not a readable PNG image ({exc})") from None


@dataclass(frozen=True)
class GltfMaterial:
    """One named metallic-roughness material as stored in a ``.glb``.

    Attributes
    ----------
    name : str
        Material and node name (the method, or ``truth``).
    base_color_png, metallic_roughness_png : bytes
        PNG files of :func:`material_images`' two images.
    """

    name: str
    base_color_png: bytes
    metallic_roughness_png: bytes

    @classmethod
    def from_textures(cls, name: str, textures: Mapping[str, np.ndarray]) -> GltfMaterial:
        """The material of linear SVBRDF textures (8-bit, base colour sRGB-encoded)."""
        base, packed = material_images(textures)
        return cls(name, encode_png(base), encode_png(packed))

    def textures(self) -> dict[str, np.ndarray]:
        """Linear textures decoded from the PNGs (:func:`textures_from_images`)."""
        return textures_from_images(decode_png(self.base_color_png, f"material {self.name!r} baseColorTexture"),
                                    decode_png(self.metallic_roughness_png,
                                               f"material {self.name!r} metallicRoughnessTexture"))


@dataclass(frozen=True, eq=False)
class GltfScene:
    """What :func:`read_glb` finds in a file: the shared mesh and its materials, in node order."""

    mesh: Mesh
    materials: tuple[GltfMaterial, ...]

    def material(self, name: str) -> GltfMaterial:
        """The material called ``name``."""
        for m in self.materials:
            if m.name == name:
                return m
        raise ValueError(f"no material {name!r}; the file has {[m.name for m in self.materials]}")


def _pad4(data: bytes) -> bytes:
    return data + b"\0" * (-len(data) % 4)


def glb_bytes(mesh: Mesh, materials: Sequence[GltfMaterial]) -> bytes:
    """A binary glTF 2.0 file: ``mesh`` once, drawn by one node per material.

    Parameters
    ----------
    mesh : Mesh
        V vertices (positions in object units, unit normals, uvs) and F triangles,
        counter-clockwise seen from outside (glTF's front faces).
    materials : sequence of GltfMaterial
        At least one; names unique.

    Returns
    -------
    bytes
        The ``.glb`` file: float32 POSITION, NORMAL, TEXCOORD_0 and uint32 indices,
        PNG textures embedded in the binary chunk, bilinear with mipmaps, repeating
        (Mitsuba's bitmap texture repeats too).
    """
    import pygltflib as g

    names = [m.name for m in materials]
    if not names or len(set(names)) != len(names):
        raise ValueError(f"glb_bytes needs at least one material and unique names, got {names}")
    arrays = [np.asarray(mesh.vertices, "<f4"), np.asarray(mesh.normals, "<f4"), np.asarray(mesh.uvs, "<f4"),
              np.asarray(mesh.faces, "<u4").reshape(-1)]
    chunks: list[bytes] = []
    views: list[g.BufferView] = []

    def add_view(data: bytes, target: int | None) -> int:
        offset = sum(len(c) for c in chunks)
        views.append(g.BufferView(buffer=0, byteOffset=offset, byteLength=len(data), target=target))
        chunks.append(_pad4(data))
        return len(views) - 1

    accessors = []
    for k, array in enumerate(arrays):
        view = add_view(array.tobytes(), _ELEMENT_ARRAY_BUFFER if k == 3 else _ARRAY_BUFFER)
        if k == 3:
            accessors.append(g.Accessor(bufferView=view, componentType=_UINT32, count=len(array), type="SCALAR"))
        else:
            accessors.append(g.Accessor(bufferView=view, componentType=_FLOAT, count=len(array),
                                        type=f"VEC{array.shape[1]}",
                                        # glTF requires the bounds of POSITION (viewers frame the object with them)
                                        min=array.min(axis=0).tolist() if k == 0 else None,
                                        max=array.max(axis=0).tolist() if k == 0 else None))
    images, textures, gltf_materials, meshes, nodes = [], [], [], [], []
    for m in materials:
        for png in (m.base_color_png, m.metallic_roughness_png):
            images.append(g.Image(bufferView=add_view(png, None), mimeType="image/png"))
            textures.append(g.Texture(sampler=0, source=len(images) - 1))
        gltf_materials.append(g.Material(name=m.name, pbrMetallicRoughness=g.PbrMetallicRoughness(
            baseColorTexture=g.TextureInfo(index=len(textures) - 2), baseColorFactor=[1.0, 1.0, 1.0, 1.0],
            metallicRoughnessTexture=g.TextureInfo(index=len(textures) - 1), metallicFactor=1.0, roughnessFactor=1.0)))
        meshes.append(g.Mesh(name=m.name, primitives=[g.Primitive(
            attributes=g.Attributes(POSITION=0, NORMAL=1, TEXCOORD_0=2), indices=3,
            material=len(gltf_materials) - 1, mode=_TRIANGLES)]))
        nodes.append(g.Node(name=m.name, mesh=len(meshes) - 1))
    blob = b"".join(chunks)
    gltf = g.GLTF2(
        asset=g.Asset(generator="freqbrdf.export.gltf (pygltflib)", version="2.0"),
        scene=0, scenes=[g.Scene(nodes=list(range(len(nodes))))], nodes=nodes, meshes=meshes,
        materials=gltf_materials, textures=textures, images=images,
        samplers=[g.Sampler(magFilter=_LINEAR, minFilter=_LINEAR_MIPMAP_LINEAR, wrapS=_REPEAT, wrapT=_REPEAT)],
        accessors=accessors, bufferViews=views, buffers=[g.Buffer(byteLength=len(blob))],
    )
    gltf.set_binary_blob(blob)
    return b"".join(gltf.save_to_bytes())


def write_glb(path: str | os.PathLike, mesh: Mesh, materials: Sequence[GltfMaterial]) -> None:
    """Write :func:`glb_bytes` to ``path``, atomically."""
    data = glb_bytes(mesh, materials)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def write_textures_glb(path: str | os.PathLike, mesh: Mesh, textures: Mapping[str, np.ndarray], name: str) -> str:
    """Linear SVBRDF textures (``base_color`` (R, R, 3), ``roughness``, ``metallic`` (R, R)) on
    ``mesh`` as a .glb with one material called ``name`` (`write_glb`); returns a one-line
    summary for the job's log."""
    write_glb(path, mesh, [GltfMaterial.from_textures(name, textures)])
    size = textures["base_color"].shape
    return f"{path}: {len(mesh.faces)} triangles, {size[0]}x{size[1]} textures"


def _accessor_array(gltf, blob: bytes, index: int, path: Path) -> np.ndarray:
    accessor = gltf.accessors[index]
    width = {"SCALAR": 1, "VEC2": 2, "VEC3": 3}.get(accessor.type)
    dtype = {_FLOAT: "<f4", _UINT32: "<u4"}.get(accessor.componentType)
    if width is None or dtype is None or accessor.bufferView is None:
        raise ValueError(f"{path}: accessor {index} is {accessor.type} of componentType {accessor.componentType}, "
                         "expected float32 VEC2/VEC3 or uint32 SCALAR in a bufferView")
    view = gltf.bufferViews[accessor.bufferView]
    start = (view.byteOffset or 0) + (accessor.byteOffset or 0)
    if view.byteStride not in (None, 4 * width):
        raise ValueError(f"{path}: accessor {index} is interleaved (byteStride {view.byteStride}), not supported")
    if start + accessor.count * 4 * width > len(blob):
        raise ValueError(f"{path}: accessor {index} runs past the end of the binary chunk")
    array = np.frombuffer(blob, dtype=dtype, count=accessor.count * width, offset=start)
    return array.reshape(accessor.count, width) if width > 1 else array


def _image_bytes(gltf, blob: bytes, texture_info, path: Path, what: str) -> bytes:
    if texture_info is None:
        raise ValueError(f"{path}: material has no {what}")
    image = gltf.images[gltf.textures[texture_info.index].source]
    if image.bufferView is None or image.mimeType != "image/png":
        raise ValueError(f"{path}: {what} is not a PNG embedded in the binary chunk")
    view = gltf.bufferViews[image.bufferView]
    return blob[(view.byteOffset or 0):(view.byteOffset or 0) + view.byteLength]


def _nodes(gltf, blob: bytes, path: Path) -> tuple[tuple[int, int, int, int], list[GltfMaterial]]:
    """The accessors (positions, normals, uvs, indices) all nodes share, and each node's material."""
    geometry, materials = None, []
    for node in gltf.nodes:
        if node.mesh is None or len(gltf.meshes[node.mesh].primitives) != 1:
            raise ValueError(f"{path}: node {node.name!r} does not draw exactly one primitive")
        primitive = gltf.meshes[node.mesh].primitives[0]
        a = primitive.attributes
        layout = (a.POSITION, a.NORMAL, a.TEXCOORD_0, primitive.indices)
        if None in layout or primitive.mode not in (None, _TRIANGLES) or primitive.material is None:
            raise ValueError(f"{path}: node {node.name!r} lacks positions, normals, uvs, indices or a material, "
                             "or does not draw triangles")
        if geometry is None:
            geometry = layout
        elif layout != geometry:
            raise ValueError(f"{path}: node {node.name!r} draws other geometry than node {gltf.nodes[0].name!r}")
        pbr = gltf.materials[primitive.material].pbrMetallicRoughness
        if pbr is None:
            raise ValueError(f"{path}: material of node {node.name!r} is not metallic-roughness")
        materials.append(GltfMaterial(
            node.name or "", _image_bytes(gltf, blob, pbr.baseColorTexture, path, "baseColorTexture"),
            _image_bytes(gltf, blob, pbr.metallicRoughnessTexture, path, "metallicRoughnessTexture")))
    return geometry, materials


def read_glb(path: str | os.PathLike) -> GltfScene:
    """Read a ``.glb`` in the layout :func:`glb_bytes` writes: every node draws the same geometry.

    Returns
    -------
    GltfScene
        The mesh (float32 values widened to float64) and one `GltfMaterial` per node.

    Raises
    ------
    ValueError
        One line naming ``path`` if the file is missing, not a binary glTF, or
        not in that layout (other attributes, non-triangles, external or
        non-PNG images, nodes drawing different geometry).
    """
    import pygltflib as g

    path = Path(path)
    try:
        data = path.read_bytes()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read glTF file ({exc.strerror or exc})") from None
    if len(data) < 12 or data[:4] != b"glTF" or struct.unpack("<I", data[4:8])[0] != 2:
        raise ValueError(f"{path}: not a binary glTF 2.0 file")
    try:
        gltf = g.GLTF2.load_from_bytes(data)
    except Exception as exc:
        raise ValueError(f"{path}: unreadable binary glTF ({exc})") from None
    blob = gltf.binary_blob()
    if blob is None or not gltf.nodes:
        raise ValueError(f"{path}: no binary chunk or no nodes")
    try:
        geometry, materials = _nodes(gltf, blob, path)
        positions, normals, uvs, indices = (_accessor_array(gltf, blob, i, path) for i in geometry)
    except (IndexError, TypeError, AttributeError) as exc:  # an index or field the document lacks
        raise ValueError(f"{path}: malformed glTF document ({type(exc).__name__}: {exc})") from None
    if indices.size % 3:
        raise ValueError(f"{path}: {indices.size} indices is not a whole number of triangles")
    try:
        mesh = Mesh(vertices=positions, normals=normals, uvs=uvs, faces=indices.reshape(-1, 3).astype(np.int64))
    except ValueError as exc:
        raise ValueError(f"{path}: {exc}") from None
    return GltfScene(mesh, tuple(materials))
