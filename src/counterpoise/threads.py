"""Keep numerical linear algebra on one thread.

The matrices here are small (a few hundred rows); on a shared machine a threaded BLAS
spends far longer synchronising than computing (a 0.4 ms SVD was measured at 146 ms under
load). The designer calls :func:`limit_blas_threads` before it builds anything. Set
``COUNTERPOISE_BLAS_THREADS`` to allow more threads.
"""

from __future__ import annotations

import os

_limited = False


def limit_blas_threads() -> None:
    """Limit BLAS/OpenMP thread pools already loaded in this process (once)."""
    global _limited
    if _limited:
        return
    _limited = True
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return
    threadpool_limits(limits=int(os.environ.get("COUNTERPOISE_BLAS_THREADS", "1")))
