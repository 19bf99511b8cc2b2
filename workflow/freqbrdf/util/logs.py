"""Logging for the pipeline's entry scripts.

Each script hands its ``main(snakemake, log)`` to :func:`run_script`, which logs
to the rule's ``log:`` file and to stderr with timestamps, reports the total
time and peak memory, and records a one-line error before re-raising, so a
failure is explained both on the console and in the log.
"""

from __future__ import annotations

import logging
import re
import resource
import sys
import time
import traceback
from collections.abc import Callable
from pathlib import Path
from typing import Any


def script_logger(name: str, log_file: str | Path | None) -> logging.Logger:
    """A logger writing timestamped lines to ``log_file`` (if given) and stderr."""
    logger = logging.getLogger(f"freqbrdf.{name}")
    logger.setLevel(logging.INFO)
    logger.handlers.clear()
    logger.propagate = False
    fmt = logging.Formatter("%(asctime)s %(levelname)s [%(name)s] %(message)s", "%H:%M:%S")
    handlers: list[logging.Handler] = [logging.StreamHandler(sys.stderr)]
    if log_file:
        Path(log_file).parent.mkdir(parents=True, exist_ok=True)
        handlers.append(logging.FileHandler(log_file, mode="w"))
    for handler in handlers:
        handler.setFormatter(fmt)
        logger.addHandler(handler)
    return logger


def progress(done: int, total: int, elapsed_s: float) -> str:
    """``"3 of 24, 2.1 s elapsed, about 14 s left"``: a long job's progress line, the time left
    extrapolated from the mean time per item so far."""
    left = elapsed_s / done * (total - done) if done else float("nan")
    return f"{done} of {total}, {elapsed_s:.1f} s elapsed, about {left:.0f} s left"


def peak_memory_mb() -> float:
    """Peak resident memory of this process so far, in MiB (Linux ``ru_maxrss`` is KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0


def die_with_parent() -> None:
    """Have the kernel end this process (SIGTERM) when its parent, the Snakemake that started the
    job, dies (Linux ``PR_SET_PDEATHSIG``; elsewhere nothing).

    A Snakemake killed alone would otherwise leave its jobs writing as orphans, and a rerun
    could mark their half-written outputs done. :func:`run_script` calls it before the job's
    ``main``; a job whose Snakemake died while the script was importing ends then.
    """
    if not sys.platform.startswith("linux"):
        return
    import ctypes
    import os
    import signal

    parent = os.getppid()
    pr_set_pdeathsig = 1
    if ctypes.CDLL(None, use_errno=True).prctl(pr_set_pdeathsig, int(signal.SIGTERM), 0, 0, 0) != 0:
        return  # not allowed here (a seccomp sandbox): the writer lock still stops a second writer
    # The parent died before the request took effect: while this script imported (adopted by
    # init, pid 1), or during the request itself.
    if parent == 1 or os.getppid() != parent:
        os.kill(os.getpid(), signal.SIGTERM)


def run_script(main: Callable[[Any, logging.Logger], None], smk: Any) -> None:
    """Run a rule's ``main(snakemake, log)`` with logging, timing and a one-line error.

    Parameters
    ----------
    main : callable
        The script body.
    smk : snakemake.script.Snakemake
        The ``snakemake`` object Snakemake injects into ``script:`` files.
    """
    die_with_parent()
    log_file = smk.log[0] if len(smk.log) else None
    wildcards = ", ".join(f"{k}={v}" for k, v in smk.wildcards.items())
    log = script_logger(smk.rule, log_file)
    log.info("start %s%s", smk.rule, f" ({wildcards})" if wildcards else "")
    start = time.perf_counter()
    try:
        main(smk, log)
    except Exception as exc:
        log.error("%s failed: %s", smk.rule, str(exc).splitlines()[0] if str(exc) else type(exc).__name__)
        log.debug("".join(traceback.format_exc()))
        if log_file:
            with open(log_file, "a") as f:
                f.write(traceback.format_exc())
        raise
    log.info("done in %.1f s, peak memory %.0f MiB", time.perf_counter() - start, peak_memory_mb())


_FAILED_JOB = re.compile(r"^Error in rule (\S+):\n((?:[ \t]+.*\n?)*)", re.M)


def first_error_line(log_text: str) -> str:
    """The line of a job's log that says what failed: the first ``ERROR`` line :func:`run_script`
    writes, else the first line of an exception, else the last non-empty line; '' for an empty log."""
    lines = [line.strip() for line in log_text.splitlines() if line.strip()]
    for pattern in (r"\bERROR\b", r"^\w+(Error|Exception)\b"):
        found = next((line for line in lines if re.search(pattern, line)), None)
        if found:
            return found
    return lines[-1] if lines else ""


def failure_summary(snakemake_log: str, workdir: str | Path = ".") -> list[str]:
    """Lines naming each failed job of a run, its log file and the first error line in that log.

    Parameters
    ----------
    snakemake_log : str
        The text of Snakemake's own log of the run (``.snakemake/log/*.snakemake.log``), with its
        ``Error in rule ...:`` blocks.
    workdir : path-like
        The run's working directory, against which the jobs' log paths are read.

    Returns
    -------
    list of str
        A heading and, per failed job, its rule and output, its log and that log's first error
        line; empty when the log names no failed job.
    """
    lines = []
    for match in _FAILED_JOB.finditer(snakemake_log):
        fields = dict(re.findall(r"^\s+(\w[\w-]*): (.*)$", match.group(2), re.M))
        output = fields.get("output", "").split(", ")[0]
        log = fields.get("log", "").split(" (check log")[0].split(", ")[0]
        text = ""
        if log and (Path(workdir) / log).is_file():
            text = first_error_line((Path(workdir) / log).read_text(errors="replace"))
        lines += [f"  rule {match.group(1)}{f' ({output})' if output else ''}: log {log or 'none'}",
                  f"    {text or 'the log says nothing; see the rule error above'}"]
    return [f"FreqBRDF: {len(lines) // 2} job(s) failed:", *lines] if lines else []
