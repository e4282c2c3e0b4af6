"""Numba decorators of the NSCD kernels.

``kernel`` compiles a loop kernel without numba's reference-counting runtime (NRT): such a
kernel must not allocate arrays (work arrays are passed in). Reason, measured (numba 0.68,
79 000 bonds, tests/unit/test_nscd_core.py keeps the results identical): a loop that calls
a helper taking arrays (e.g. local_laws.bond_velocity) pays an atomic increment and
decrement of every array's reference count per call, even when the helper is inlined,
which made such loops 5-15 times slower than the same loop written out by hand. Without
NRT arrays are borrowed from the caller and no counting is emitted.
``_nrt`` is a numba compiler flag without a public name; if a numba version rejects it,
``kernel`` falls back to a plain ``njit(cache=True)`` (same results, slower).

``helper`` compiles a small function inlined into its callers (numba IR inlining), also
without NRT.

Threads: the threaded kernels (``parallel=True``, NSCDParameters.threads > 1) run on numba's
OpenMP layer, whose threads by default spin while waiting at the end of each parallel
region. On a machine shared with other jobs a spinning thread delays the pre-empted one:
the conjugate gradient (3 parallel regions per iteration) ran 4-7 times slower on 2 threads
than on 1 (N = 12 000, load 5-12 on 2 cores), and 1.5 times faster with passive waiting.
``OMP_WAIT_POLICY=PASSIVE`` is therefore set here unless the environment already sets it
(it must be set before numba starts its thread pool).
"""

from __future__ import annotations

import os

from numba import njit

os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")


def _accepts_nrt_flag() -> bool:
    """Whether this numba's CPU target declares the ``_nrt`` option (read from its option
    table, without compiling: a compile at import cost every process about 0.75 s of CPU, the
    first compilation initialising numba's compiler; tests/unit/test_nscd_threads.py compiles
    a kernel with the flag)."""
    try:
        from numba.core.cpu import CPUTargetOptions
    except ImportError:  # a numba without that module: use the public decorator
        return False
    return hasattr(CPUTargetOptions, "_nrt")


NO_NRT = _accepts_nrt_flag()
_OPTS = {"_nrt": False} if NO_NRT else {}


def kernel(fn=None, **kw):
    """``numba.njit(cache=True)`` without NRT (module docstring); extra njit options in kw
    (e.g. parallel=True)."""

    def deco(f):
        return njit(cache=True, **_OPTS, **kw)(f)

    return deco(fn) if fn is not None else deco


def helper(fn):
    """``numba.njit(cache=True, inline='always')`` without NRT."""
    return njit(cache=True, inline="always", **_OPTS)(fn)
