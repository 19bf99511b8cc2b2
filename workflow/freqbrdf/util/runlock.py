"""One executing run at a time in a working directory.

Snakemake 9.27.1 guards a working directory with lock files under
``.snakemake/locks``, but every run removes that whole folder when it exits, so a
second run that finishes while a first one is still executing strips the first of
its protection, and a third run then rebuilds what the first is writing. The
workflow therefore holds a lock of its own for an executing run's whole life: an
exclusive ``flock`` on :data:`LOCK_NAME` under ``.snakemake/``, taken in the
Snakefile's ``onstart:`` handler (so only when jobs are about to execute: not in
dry runs, ``--report``, ``--unlock`` or ``--list-*``, and not in the job processes
Snakemake spawns, which run with ``--no-hooks``). The kernel drops the lock when
the process exits, however it exits (SIGKILL included), so it never needs removing.
"""

from __future__ import annotations

import errno
import fcntl
import json
import os
import socket
import sys
from datetime import datetime
from pathlib import Path
from typing import Any

__all__ = ["LOCK_NAME", "RunLockError", "hold_run_lock", "read_holder", "refusal"]

LOCK_NAME = "freqbrdf-run.lock"

# The open lock file of this process's run: kept open (and so locked) until the process exits.
_HELD: dict[str, int] = {}


class RunLockError(RuntimeError):
    """Another run is executing in the same working directory; the message is one line."""


def read_holder(path: str | Path) -> dict[str, Any]:
    """The record the run holding the lock wrote into ``path`` (empty if none is readable).

    Parameters
    ----------
    path : str or Path
        The lock file.

    Returns
    -------
    dict
        ``pid``, ``started`` (ISO time), ``host`` and ``command`` of the holder, or ``{}``
        while the holder has not written them yet.
    """
    try:
        record = json.loads(Path(path).read_text())
    except (OSError, ValueError):
        return {}
    return record if isinstance(record, dict) else {}


def refusal(workdir: str | Path, holder: dict[str, Any]) -> str:
    """The one line that stops a run while ``holder`` (`read_holder`) executes in ``workdir``.

    Parameters
    ----------
    workdir : str or Path
        The working directory both runs share.
    holder : dict
        The record of the run holding the lock.

    Returns
    -------
    str
        The message: who holds the directory and what to do.
    """
    who = f"pid {holder.get('pid', '?')}, started {holder.get('started', 'at an unknown time')}"
    if holder.get("host") and holder["host"] != socket.gethostname():
        who += f" on {holder['host']}"
    return (f"another FreqBRDF run is executing in {workdir} ({who}): wait for it to end, or stop it; "
            f"its lock (.snakemake/{LOCK_NAME}) frees itself when that process exits, no --unlock needed")


def hold_run_lock(directory: str | Path, workdir: str | Path | None = None) -> bool:
    """Lock ``directory/LOCK_NAME`` for this process's lifetime, or stop if another run holds it.

    Called again in a process that holds the lock, it does nothing. The lock file's
    descriptor is not inherited by the job processes, so the lock ends with this one.

    Parameters
    ----------
    directory : str or Path
        Snakemake's ``.snakemake`` folder of the working directory.
    workdir : str or Path, optional
        The working directory, for the message (default: ``directory``'s parent).

    Returns
    -------
    bool
        True if this process holds the lock; False if the file system offers no ``flock``
        (the run goes on unguarded, with a warning on stderr).

    Raises
    ------
    RunLockError
        Another live process holds the lock; the message (`refusal`) names it.
    """
    path = Path(directory) / LOCK_NAME
    if str(path) in _HELD:
        return True
    path.parent.mkdir(parents=True, exist_ok=True)
    fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as error:
        os.close(fd)
        if error.errno in (errno.EWOULDBLOCK, errno.EAGAIN, errno.EACCES):
            raise RunLockError(refusal(workdir or Path(directory).absolute().parent, read_holder(path))) from None
        print(f"Warning: {path}: no flock on this file system ({error.strerror}); "
              "nothing stops a second run in this directory", file=sys.stderr)
        return False
    record = {"pid": os.getpid(), "started": datetime.now().isoformat(sep=" ", timespec="seconds"),
              "host": socket.gethostname(), "command": " ".join(sys.argv)}
    os.ftruncate(fd, 0)
    os.pwrite(fd, (json.dumps(record) + "\n").encode(), 0)
    _HELD[str(path)] = fd
    return True
