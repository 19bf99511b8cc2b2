"""Seeds of named items, derived from the run's one seed (config ``seed``)."""

from __future__ import annotations

import zlib


def derived_seed(seed: int, *names: str) -> int:
    """A seed for one named item (object, environment, view set), stable across runs.

    Parameters
    ----------
    seed : int
        The global seed from config.
    *names : str
        Names that identify the item, e.g. ``("object", "torus")``.

    Returns
    -------
    int
        A 31-bit seed; different names give unrelated seeds.
    """
    h = zlib.crc32(str(int(seed)).encode())
    for name in names:
        h = zlib.crc32(name.encode(), h)
    return h & 0x7FFFFFFF
