"""Keep numerical linear algebra on one thread.

The matrices here are small (a few hundred rows); on a shared machine a threaded BLAS
spends far longer synchronising than computing (a 0.4 ms SVD was measured at 146 ms under
load). Two mechanisms, because BLAS libraries read their thread count when they are loaded:

- :func:`limit_blas_environment` sets ``OPENBLAS_NUM_THREADS``, ``OMP_NUM_THREADS`` and
  ``MKL_NUM_THREADS`` (unless the user set them) for libraries loaded later: CasADi loads
  its own OpenBLAS and OpenMP runtime with the IPOPT plugin, when the first solver is
  built. The command line calls it before numpy is imported.
- :func:`limit_blas_threads` also limits the thread pools already loaded (numpy's
  OpenBLAS) through threadpoolctl, once per process. The designer calls it before it
  builds anything. When :func:`limit_blas_environment` ran before any BLAS was loaded
  (the command line) and set every variable to the count wanted, the libraries read it
  when they load and threadpoolctl (~5–10 ms: it inspects every loaded library) is skipped.

Set ``COUNTERPOISE_BLAS_THREADS`` to allow more threads.
"""

from __future__ import annotations

import os
import sys

_limited = False
#: set when the environment alone limits every BLAS (see :func:`limit_blas_environment`)
_environment_suffices = False

#: modules whose import loads a BLAS or OpenMP runtime (numpy's OpenBLAS, CasADi's plugins)
BLAS_MODULES = ("numpy", "scipy", "casadi", "clarabel")

#: environment variables BLAS and OpenMP runtimes read when they are loaded
ENVIRONMENT = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def blas_threads() -> int:
    return max(1, int(os.environ.get("COUNTERPOISE_BLAS_THREADS", "1")))


def limit_blas_environment() -> None:
    """Set the thread counts of BLAS/OpenMP libraries not loaded yet (user settings win)."""
    global _environment_suffices
    loaded = any(name in sys.modules for name in BLAS_MODULES)
    for name in ENVIRONMENT:
        os.environ.setdefault(name, str(blas_threads()))
    if not loaded and all(os.environ[name] == str(blas_threads()) for name in ENVIRONMENT):
        _environment_suffices = True


def limit_blas_threads() -> None:
    """Limit BLAS/OpenMP thread pools: those loaded later and those already loaded (once)."""
    global _limited
    if _limited:
        return
    _limited = True
    limit_blas_environment()
    if _environment_suffices:
        return
    try:
        from threadpoolctl import threadpool_limits
    except ImportError:  # pragma: no cover - threadpoolctl is a dependency
        return
    threadpool_limits(limits=blas_threads())
