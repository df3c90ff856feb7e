"""One BLAS thread for a solve: asked for before numpy loads, known to hold afterwards.

The matrices of a solve are small (tens of rows): BLAS threads only contend, tens of times
slower when the machine is busy, so an epoch loop runs on one BLAS thread. The console
entry asks for it through the environment before numpy is imported
(:func:`single_threaded_blas`: OpenBLAS's thread pool would also cost 0.05–0.1 s of every
start). Where that held, an epoch loop has nothing to limit; anywhere else (a program that
imported numpy first, or asked for more threads) :func:`one_blas_thread` limits the pool
with ``threadpoolctl`` for the duration of the loop. Skipping ``threadpoolctl`` where it
has nothing to do saves its import and its scan of the loaded libraries (2.6 % of the
instructions of the geonet RTK solve, 120 epochs).
"""

from __future__ import annotations

import contextlib
import os
import sys

#: BLAS thread-pool variables set to one thread (unless already set) before numpy loads:
#: OpenBLAS, MKL, OpenMP and BLIS (which also reads OpenMP's).
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS", "OMP_NUM_THREADS", "BLIS_NUM_THREADS")

#: Set by :func:`single_threaded_blas`: every variable said one thread before numpy loaded.
_ONE_THREAD_FROM_START: list[bool] = [False]


def single_threaded_blas() -> None:
    """One BLAS thread for this process unless the environment says otherwise.

    Sets each of :data:`BLAS_THREAD_VARS` to ``1`` where unset. Must run before numpy is
    imported to act; when it does and every variable then says one thread, the process is
    known to run one BLAS thread (:func:`blas_known_single_threaded`).
    """
    for var in BLAS_THREAD_VARS:
        os.environ.setdefault(var, "1")
    _ONE_THREAD_FROM_START[0] = "numpy" not in sys.modules and all(
        os.environ.get(var) == "1" for var in BLAS_THREAD_VARS
    )


def blas_known_single_threaded() -> bool:
    """True when :func:`single_threaded_blas` ran before numpy loaded and every BLAS
    thread variable said one thread: the BLAS libraries numpy loaded run one thread."""
    return _ONE_THREAD_FROM_START[0]


def one_blas_thread() -> contextlib.AbstractContextManager[object]:
    """A context in which the BLAS runs one thread: nothing to do when
    :func:`blas_known_single_threaded`, else ``threadpoolctl``'s limit (imported here, not
    at start-up: its import is slow)."""
    if blas_known_single_threaded():
        return contextlib.nullcontext()
    from threadpoolctl import threadpool_limits

    return threadpool_limits(limits=1, user_api="blas")


__all__ = ["BLAS_THREAD_VARS", "blas_known_single_threaded", "one_blas_thread", "single_threaded_blas"]
