"""One setting of numba's thread pool for every compiled kernel of the package.

numba's thread count is per process, so the modules of compiled kernels
(`freqbrdf.estimate.optimise.kernels`, `freqbrdf.capture.kernels`) share this setter. It
lives apart from both so that a rule's derived dependencies follow only
the kernels it runs: a change to the model's kernels does not rerun the
rules that extract observations.
"""

from __future__ import annotations

import numba

__all__ = ["set_threads"]


def set_threads(workers: int) -> None:
    """Use ``workers`` threads (at most numba's configured maximum) in the kernels."""
    numba.set_num_threads(max(1, min(int(workers), numba.config.NUMBA_NUM_THREADS)))
