"""The npm package ``@pmndrs/assets``: captured HDR maps and scanned meshes that install offline.

The package (1.7.0, CC0-1.0 as a whole; the Stanford bunny keeps Stanford's terms,
:mod:`freqbrdf.scene.scans`) stores each file as a base64 ``data:`` URI in a JS module
(``package/hdri/<name>.exr.js``, ``package/models/<name>.glb.js``). :func:`fetch_package`
brings its tarball from the npm registry and checks it against npm's integrity hash;
:func:`read_member` decodes one file of it.
"""

from __future__ import annotations

import base64
import binascii
import hashlib
import re
import shutil
import subprocess
import tarfile
import tempfile
from pathlib import Path

PACKAGE = "@pmndrs/assets"
VERSION = "1.7.0"
TARBALL = f"pmndrs-assets-{VERSION}.tgz"
# npm's dist.integrity of the version: the tarball is refused unless it matches.
INTEGRITY = "sha512-zHmKNS+3Jvu9K3zJBQfYQKT9Pn9IQt8s0q/eJC3CXKpWpyg6IBa+ivN9NgDn+fDT2AVjUh2YRZ//GXUueuAdCg=="
LICENCE = "CC0-1.0"
_DATA_URI = re.compile(rb"data:[^;,]*;base64,([A-Za-z0-9+/=]+)")


def fetch_package(directory: Path, npm: str = "npm") -> Path:
    """The package's tarball in ``directory``, fetched with ``npm pack`` unless already there.

    Parameters
    ----------
    directory : Path
        Where the tarball (:data:`TARBALL`) is kept.
    npm : str
        The npm executable.

    Returns
    -------
    Path
        ``directory / TARBALL``, its integrity checked against :data:`INTEGRITY`.

    Raises
    ------
    RuntimeError
        One line: npm missing or failing, or a tarball whose integrity does not match.
    """
    target = Path(directory) / TARBALL
    if target.is_file():
        check_integrity(target)
        return target
    if shutil.which(npm) is None:
        raise RuntimeError(f"{npm}: not found; the captured light and the scans come from the npm package {PACKAGE}@{VERSION} "
                           f"(make asset-deps installs npm; or put {TARBALL} in {directory})")
    target.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory(dir=target.parent, prefix=".npm-pack-") as tmp:
        done = subprocess.run([npm, "pack", f"{PACKAGE}@{VERSION}", "--pack-destination", tmp],
                              capture_output=True, text=True, timeout=600)
        packed = Path(tmp) / TARBALL
        if done.returncode != 0 or not packed.is_file():
            lines = [line for line in (done.stderr or done.stdout).splitlines() if line.strip()]
            raise RuntimeError(f"npm pack {PACKAGE}@{VERSION} failed: {lines[-1] if lines else f'exit {done.returncode}'}")
        check_integrity(packed)
        packed.replace(target)
    return target


def check_integrity(tarball: Path) -> None:
    """Raise RuntimeError (one line naming ``tarball``) unless its SHA-512 is npm's :data:`INTEGRITY`."""
    digest = "sha512-" + base64.b64encode(hashlib.sha512(Path(tarball).read_bytes()).digest()).decode()
    if digest != INTEGRITY:
        raise RuntimeError(f"{tarball}: not {PACKAGE}@{VERSION} (its SHA-512 differs from npm's); delete it to fetch again")


def read_member(tarball: Path, member: str) -> bytes:
    """The file that JS module ``member`` of the package's tarball holds as a base64 ``data:`` URI.

    Raises
    ------
    ValueError
        One line naming the tarball and member: missing, unreadable, or without a base64 URI.
    """
    try:
        with tarfile.open(tarball, "r:gz") as tar:
            text = tar.extractfile(member).read()
    except (KeyError, AttributeError):
        raise ValueError(f"{tarball}: no member {member}") from None
    except (OSError, tarfile.TarError) as exc:
        raise ValueError(f"{tarball}: not a readable tarball ({exc})") from None
    match = _DATA_URI.search(text)
    try:
        return base64.b64decode(match.group(1), validate=True) if match else b""
    except binascii.Error as exc:
        raise ValueError(f"{tarball}:{member}: not a base64 data URI ({exc})") from None
