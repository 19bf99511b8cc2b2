"""The first call of a compiled kernel in a process waits for the machine's lock; later calls do not."""

import fcntl
import os
import select
import subprocess
import sys
import textwrap
import time

from freqbrdf.util.compile_once import lock_path

CHILD = textwrap.dedent("""
    import sys
    sys.path.insert(0, sys.argv[1])
    import toy_kernels
    from freqbrdf.util.compile_once import first_call_locked
    print("ready", flush=True)
    print(first_call_locked(toy_kernels.add_kernel, 1.0, 2.0), flush=True)
    sys.stdin.readline()
    print(first_call_locked(toy_kernels.add_kernel, 3.0, 4.0), flush=True)
""")


def read_within(fd: int, seconds: float) -> bytes:
    """The next line the child writes to ``fd`` within ``seconds``; what came of it if none ended (b"")."""
    deadline, line = time.monotonic() + seconds, b""
    while not line.endswith(b"\n"):
        ready, _, _ = select.select([fd], [], [], max(0.0, deadline - time.monotonic()))
        if not ready:
            break
        line += os.read(fd, 1)
    return line


def test_the_first_call_waits_for_the_lock_and_a_later_one_does_not(tmp_path):
    source = tmp_path / "toy_kernels.py"
    source.write_text("import numba\n\n\n@numba.njit(cache=True)\ndef add_kernel(a, b):\n    return a + b\n")
    lock = lock_path(source)
    lock.parent.mkdir()
    with open(lock, "a") as held:
        fcntl.flock(held, fcntl.LOCK_EX)  # another process compiling
        child = subprocess.Popen([sys.executable, "-c", CHILD, str(tmp_path)], stdin=subprocess.PIPE,
                                 stdout=subprocess.PIPE)
        out = child.stdout.fileno()
        try:
            assert read_within(out, 60) == b"ready\n"
            assert read_within(out, 5) == b""  # waiting at its first call, not compiling alongside
            fcntl.flock(held, fcntl.LOCK_UN)
            assert read_within(out, 60) == b"3.0\n"
            fcntl.flock(held, fcntl.LOCK_EX)  # held again: the kernel has run in that process, no wait
            child.stdin.write(b"go\n")
            child.stdin.flush()
            assert read_within(out, 60) == b"7.0\n"
            assert child.wait(timeout=60) == 0
        finally:
            child.kill()
