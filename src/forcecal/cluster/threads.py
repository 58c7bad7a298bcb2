"""The threads forcecal's linear algebra runs on, set by forcecal itself for each command and API
call (INTERFACES.md section 5: ``--threads``).

forcecal's work is many small dense matrix problems: one BLAS thread per process is the fastest,
and BLAS threads beside a busy process, or in every worker of a cluster, oversubscribe the cores.
So a command or an API call runs under :func:`limited`: the BLAS and OpenMP pools
(``threadpoolctl``), Numba's threads when its threading layer is running, and the
``*_NUM_THREADS`` variables (read by a BLAS library loaded during the call, and by the worker
processes it starts) are held at the limit and restored after. The limit is, first found:

- the number given (``--threads N``, :func:`forcecal.threads`, ``limited(N)``);
- the limit of an enclosing :func:`limited` (an API call inside a command or inside
  ``with forcecal.threads(N):`` keeps it);
- the environment variable ``FORCECAL_THREADS``;
- :data:`DEFAULT_THREADS` (one).

Jobs spread over workers run under the limit of the call that spreads them
(:class:`LimitedJob`), on this machine or on a remote cluster.
"""

from __future__ import annotations

import contextlib
import functools
import operator
import os
import sys
from collections.abc import Callable, Iterator
from contextvars import ContextVar
from typing import Any, ParamSpec, TypeVar

from threadpoolctl import threadpool_limits

from ..errors import InputError

__all__ = ["LimitedJob", "current_threads", "limited", "thread_count", "with_threads"]

P = ParamSpec("P")
R = TypeVar("R")

DEFAULT_THREADS = 1
"""Threads per process when neither the call nor ``FORCECAL_THREADS`` says otherwise."""
ENVIRONMENT = "FORCECAL_THREADS"
"""The environment variable that sets the limit of every command and API call."""
THREAD_VARIABLES = ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS")
"""The variables that set the BLAS and OpenMP libraries' thread counts when they load."""

_ACTIVE: ContextVar[int | None] = ContextVar("forcecal_threads", default=None)
"""The limit of the innermost :func:`limited` (None outside any)."""


def thread_count(value: int | str, name: str | None = None) -> int:
    """A number of threads, checked: a whole number >= 1 (an int or its decimal text).

    Parameters
    ----------
    value : int or str
        The number asked for.
    name : str, optional
        Where it was given (``"FORCECAL_THREADS"``, ``"forcecal.threads"``), to begin the
        message of a refusal.

    Raises
    ------
    InputError
        In one line, for 0, a negative number, a fraction, a bool or text that is no integer.
    """
    try:
        if isinstance(value, bool):
            raise TypeError
        n = int(value) if isinstance(value, str) else operator.index(value)
    except (TypeError, ValueError):
        n = 0
    if n < 1:
        where = f"{name}: " if name else ""
        raise InputError(f"{where}{value!r} is not a number of threads; give a whole number "
                         ">= 1")
    return n


def current_threads() -> int:
    """The limit a call made now runs under: the enclosing :func:`limited`'s, else
    ``FORCECAL_THREADS``, else :data:`DEFAULT_THREADS`.

    Raises
    ------
    InputError
        ``FORCECAL_THREADS`` is set to something that is not a number of threads.
    """
    active = _ACTIVE.get()
    if active is not None:
        return active
    text = os.environ.get(ENVIRONMENT, "").strip()
    return thread_count(text, ENVIRONMENT) if text else DEFAULT_THREADS


@contextlib.contextmanager
def limited(n: int | str | None = None) -> Iterator[int]:
    """Run the block on ``n`` threads (None: :func:`current_threads`), restoring them after.

    Inside an enclosing :func:`limited`, ``limited()`` changes nothing. Usable as a decorator.

    Yields
    ------
    int
        The limit.

    Raises
    ------
    InputError
        ``n`` (or ``FORCECAL_THREADS``) is not a number of threads.
    """
    active = _ACTIVE.get()
    if n is None and active is not None:
        yield active
        return
    count = current_threads() if n is None else thread_count(n, "threads")
    token = _ACTIVE.set(count)
    try:
        with _environment(count), threadpool_limits(limits=count), _numba_threads(count):
            yield count
    finally:
        _ACTIVE.reset(token)


def with_threads(function: Callable[P, R]) -> Callable[P, R]:
    """Decorate ``function`` to run under :func:`limited` (an enclosing limit kept)."""

    @functools.wraps(function)
    def wrapper(*args: P.args, **kwargs: P.kwargs) -> R:
        with limited():
            return function(*args, **kwargs)

    return wrapper


class LimitedJob:
    """``work`` made to run under ``limited(threads)`` wherever it is called: a worker of a
    process pool or of a Dask cluster (picklable when ``work`` is a module-level function).

    Parameters
    ----------
    work : callable
        The job's function, of one argument.
    threads : int
        The limit, that of the call that spreads the jobs.
    """

    def __init__(self, work: Callable[[Any], Any], threads: int) -> None:
        self.work = work
        self.threads = threads
        self.__name__ = getattr(work, "__name__", "job")     # what Dask names its tasks after

    def __call__(self, job: Any) -> Any:
        with limited(self.threads):
            return self.work(job)


@contextlib.contextmanager
def _environment(count: int) -> Iterator[None]:
    """The ``*_NUM_THREADS`` variables at ``count`` (for a BLAS library that loads inside, and
    for the worker processes started inside), restored after."""
    saved = {name: os.environ.get(name) for name in THREAD_VARIABLES}
    os.environ.update({name: str(count) for name in THREAD_VARIABLES})
    try:
        yield
    finally:
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value


@contextlib.contextmanager
def _numba_threads(count: int) -> Iterator[None]:
    """Numba's parallel threads at ``count`` (at most those it launched), restored after; only
    when its threading layer is running (forcecal's kernels are serial: launching the layer
    just to limit it would start threads that nothing uses)."""
    parallel = sys.modules.get("numba.np.ufunc.parallel")
    if parallel is None or not getattr(parallel, "_is_initialized", False):
        yield
        return
    before = parallel.get_num_threads()
    parallel.set_num_threads(max(1, min(count, sys.modules["numba"].config.NUMBA_NUM_THREADS)))
    try:
        yield
    finally:
        parallel.set_num_threads(before)
