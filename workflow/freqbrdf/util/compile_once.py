"""A compiled kernel's first call in a process, under a lock that every process on the machine shares.

numba compiles a ``cache=True`` kernel at its first call in a process unless its on-disk cache
(``__pycache__`` beside the source) already holds it. Jobs that start together with that cache
empty (a fresh clone; a many-core or GPU machine running several fits at once) would each
compile the same kernels, tens of seconds apiece. With the first call under a file lock beside
the cache, one process compiles and writes the cache; the others wait for it, then load.
"""

from __future__ import annotations

import contextlib
import fcntl
from collections.abc import Iterator
from pathlib import Path
from typing import Any

__all__ = ["first_call_locked", "lock_path"]


def lock_path(source: Path) -> Path:
    """The lock shared by the kernels of the module ``source``, in numba's cache folder beside it."""
    return source.parent / "__pycache__" / f"{source.stem}.compile.lock"


def first_call_locked(kernel: Any, *args: Any) -> Any:
    """``kernel(*args)``; under the lock of its module (`lock_path`) if it has not run in this process.

    Parameters
    ----------
    kernel : numba dispatcher
        A function compiled with ``numba.njit(cache=True)``.
    *args
        Its arguments.
    """
    if kernel.overloads:  # compiled or loaded in this process already: nothing to wait for
        return kernel(*args)
    with _locked(lock_path(Path(kernel.py_func.__code__.co_filename))):
        return kernel(*args)


@contextlib.contextmanager
def _locked(path: Path) -> Iterator[None]:
    try:
        path.parent.mkdir(exist_ok=True)
        handle = open(path, "a")
    except OSError:  # a read-only install: numba caches elsewhere, each process compiles on its own
        yield
        return
    with handle:
        fcntl.flock(handle, fcntl.LOCK_EX)
        try:
            yield
        finally:
            fcntl.flock(handle, fcntl.LOCK_UN)
