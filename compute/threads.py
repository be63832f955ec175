"""One BLAS thread per process: how wearbench's own process runs its linear algebra.

wearbench's matrices are small (a few dozen features, a few hundred cycles): a team of BLAS threads
cannot speed them up, and OpenBLAS's threads spin between calls, burning the cores that the
simulations and the other processes need. Dask's workers start with one BLAS thread (its
``distributed.nanny.pre-spawn-environ``); :func:`one_blas_thread` gives the command line and the
public API's workflows the same, for their duration only, through threadpoolctl: it limits the BLAS
libraries loaded when the block starts (OpenBLAS, MKL or BLIS), so numpy's and scipy's (two separate
libraries in their wheels) are loaded first. ``benchmarks/compute/blas_threads.py`` measures what it
saves. Imports threadpoolctl, numpy and scipy.linalg.
"""

from __future__ import annotations

import functools
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

__all__ = ["on_one_blas_thread", "one_blas_thread"]

P = ParamSpec("P")
R = TypeVar("R")


@contextmanager
def one_blas_thread() -> Iterator[None]:
    """Inside the block, numpy's and scipy's BLAS (and any other already loaded) run on one thread;
    the previous limits come back after it."""
    import numpy  # noqa: F401  (loads numpy's BLAS, so that it is limited)
    import scipy.linalg  # noqa: F401  (loads scipy's)

    with threadpool_limits(limits=1, user_api="blas"):
        yield


def on_one_blas_thread(func: Callable[P, R]) -> Callable[P, R]:
    """``func`` run inside :func:`one_blas_thread` (a public workflow's decorator)."""

    @functools.wraps(func)
    def run(*args: P.args, **kwargs: P.kwargs) -> R:
        with one_blas_thread():
            return func(*args, **kwargs)

    return run
