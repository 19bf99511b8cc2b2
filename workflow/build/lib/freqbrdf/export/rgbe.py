"""Radiance RGBE (``.hdr``) images: the HDR format that web viewers and engines read.

The environment maps are EXR (float32); the viewer (:mod:`freqbrdf.export.viewer`)
and most engines take equirectangular ``.hdr`` files. A pixel is three 8-bit
mantissas sharing one exponent (Ward 1991), so each channel keeps a relative
precision of 2^-8 of the pixel's largest channel; smaller channels lose more
in relative terms, and values below 2^-128 of it become 0.

Scanlines are written run-length encoded in the "new" format (every reader
of ``.hdr`` decodes it; flat scanlines whose first pixel happens to read as
the marker 2, 2 are misread by some, three.js's among them), using literal
runs only: the maps are smooth floats, whose bytes rarely repeat.
"""

from __future__ import annotations

import os
import re

import numpy as np

from freqbrdf.util.io import atomic_path

__all__ = ["encode_rgbe", "decode_rgbe", "hdr_bytes", "read_hdr", "write_hdr"]

_MIN_WIDTH, _MAX_WIDTH = 8, 0x7FFF  # widths the run-length format can encode
_LITERAL = 128  # longest literal run


def encode_rgbe(image: np.ndarray) -> np.ndarray:
    """RGBE pixels of linear RGB values.

    Parameters
    ----------
    image : numpy.ndarray
        Shape ``(H, W, 3)``: linear radiance, finite and >= 0.

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W, 4)``, uint8: mantissas rounded to nearest, exponent + 128;
        all 0 where the largest channel is below 1e-32.
    """
    x = np.asarray(image, dtype=np.float64)
    if x.ndim != 3 or x.shape[2] != 3:
        raise ValueError(f"encode_rgbe needs an (H, W, 3) image, got shape {x.shape}")
    if not np.all(np.isfinite(x)) or x.min() < 0.0:
        raise ValueError("encode_rgbe needs finite, non-negative values")
    peak = x.max(axis=2)
    mantissa, exponent = np.frexp(peak)  # peak = mantissa 2^exponent, mantissa in [0.5, 1)
    # Rounding can carry the largest mantissa to 256: then the next exponent up.
    carry = np.round(mantissa * 256.0) >= 256.0
    exponent = exponent + carry
    scale = np.ldexp(256.0, -exponent)[..., None]
    out = np.zeros(x.shape[:2] + (4,), np.uint8)
    lit = peak >= 1e-32
    out[..., :3] = np.where(lit[..., None], np.clip(np.round(x * scale), 0, 255), 0)
    out[..., 3] = np.where(lit, np.clip(exponent + 128, 0, 255), 0)
    return out


def decode_rgbe(rgbe: np.ndarray) -> np.ndarray:
    """Linear RGB of RGBE pixels (H, W, 4) uint8: ``mantissa 2^(e - 136)``; float32 (H, W, 3)."""
    rgbe = np.asarray(rgbe)
    if rgbe.dtype != np.uint8 or rgbe.ndim != 3 or rgbe.shape[2] != 4:
        raise ValueError(f"decode_rgbe needs uint8 (H, W, 4) pixels, got {rgbe.dtype} {rgbe.shape}")
    e = rgbe[..., 3].astype(np.int64)
    scale = np.where(e > 0, np.ldexp(1.0, e - 136), 0.0)
    return (rgbe[..., :3] * scale[..., None]).astype(np.float32)


def hdr_bytes(image: np.ndarray) -> bytes:
    """A Radiance ``.hdr`` file of a linear RGB image (H, W, 3), rows top to bottom.

    Raises
    ------
    ValueError
        If the width is outside 8 ... 32767 (the run-length format's range).
    """
    rgbe = encode_rgbe(image)
    height, width = rgbe.shape[:2]
    if not _MIN_WIDTH <= width <= _MAX_WIDTH:
        raise ValueError(f"hdr_bytes: width {width} outside {_MIN_WIDTH}..{_MAX_WIDTH}, which .hdr run-length encoding needs")
    starts = np.arange(0, width, _LITERAL)
    counts = np.minimum(_LITERAL, width - starts).astype(np.uint8)
    # One scanline: marker, then each channel as literal runs "count, bytes...".
    pieces = [b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n", f"-Y {height} +X {width}\n".encode("ascii")]
    marker = bytes([2, 2, width >> 8, width & 0xFF])
    for row in rgbe:
        pieces.append(marker)
        for channel in range(4):
            values = row[:, channel]
            pieces += [bytes([c]) + values[s : s + c].tobytes() for s, c in zip(starts, counts)]
    return b"".join(pieces)


def write_hdr(path: str | os.PathLike, image: np.ndarray) -> None:
    """Write :func:`hdr_bytes` of ``image`` to ``path``, atomically."""
    data = hdr_bytes(image)
    with atomic_path(path) as tmp:
        tmp.write_bytes(data)


def read_hdr(path: str | os.PathLike) -> np.ndarray:
    """Read a Radiance ``.hdr`` image with ``-Y H +X W`` orientation, flat or run-length encoded.

    Returns
    -------
    numpy.ndarray
        Shape ``(H, W, 3)``, float32, linear.

    Raises
    ------
    ValueError
        One line naming ``path`` if it is missing, not RGBE, or truncated.
    """
    try:
        data = open(path, "rb").read()
    except OSError as exc:
        raise ValueError(f"{path}: cannot read .hdr file ({exc.strerror or exc})") from None
    match = re.match(rb"#\?(?:RADIANCE|RGBE)\n(?:[^\n]*\n)*?\n-Y (\d+) \+X (\d+)\n", data)
    if match is None or b"FORMAT=32-bit_rle_rgbe" not in data[: match.end()]:
        raise ValueError(f"{path}: not a Radiance RGBE file with -Y H +X W orientation")
    height, width = int(match.group(1)), int(match.group(2))
    pos, rows = match.end(), []
    try:
        for _ in range(height):
            if data[pos : pos + 2] == b"\x02\x02" and (data[pos + 2] << 8 | data[pos + 3]) == width:
                pos += 4
                channels = []
                for _ in range(4):
                    values = bytearray()
                    while len(values) < width:
                        count = data[pos]
                        if count > 128:  # a run: one byte repeated count - 128 times
                            values += bytes([data[pos + 1]]) * (count - 128)
                            pos += 2
                        else:
                            values += data[pos + 1 : pos + 1 + count]
                            pos += 1 + count
                    if len(values) != width:
                        raise IndexError
                    channels.append(np.frombuffer(bytes(values), np.uint8))
                rows.append(np.stack(channels, axis=-1))
            else:
                if pos + 4 * width > len(data):
                    raise IndexError
                rows.append(np.frombuffer(data, np.uint8, 4 * width, pos).reshape(width, 4))
                pos += 4 * width
    except IndexError:
        raise ValueError(f"{path}: truncated or malformed RGBE scanlines") from None
    return decode_rgbe(np.stack(rows))
