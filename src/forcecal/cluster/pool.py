"""Many jobs at once: a process pool on this machine, or a Dask cluster.

forcecal's jobs (one run's reconstruction, one campaign's calibration) are pure functions of
their inputs, so where they run changes nothing in their results: :func:`run_jobs` gives the
serial path's results, in the order of the jobs, whichever way it spreads them.

- :func:`pool_map`: a ``spawn`` process pool, the campaign's runs on the cores of this machine.
- :func:`run_jobs`: serially when there is one job or one worker; otherwise over Dask
  (``distributed``): a local cluster of ``workers`` processes started for the command and
  closed with it, or an existing cluster given by its scheduler's address (``tcp://host:8786``),
  whose workers must have forcecal installed. Inputs travel to the workers as pickled objects
  (rig, model, records), an input that several jobs share (the rig, the model) once
  (:func:`_share`); outputs come back the same way and are written by the caller, so the
  workers need no shared file system.

Workers run their linear algebra on the threads of the call that spreads the jobs, one each
unless told (:mod:`.threads`): the workers are the parallelism. No worker outlives the command:
the pool's workers watch their parent (:func:`_watch_parent`) and are terminated on an error or
Ctrl-C; a local Dask cluster is closed when :func:`run_jobs` returns or fails, and its worker
processes leave when their parent does.
"""

from __future__ import annotations

import ast
import contextlib
import importlib
import inspect
import logging
import multiprocessing
import os
import sys
import threading
import time
import tokenize
from collections.abc import Callable, Iterator, Sequence
from concurrent.futures import ProcessPoolExecutor, ThreadPoolExecutor, as_completed
from pathlib import Path
from typing import Any, TypeVar

from ..errors import ForcecalError, InputError
from .threads import THREAD_VARIABLES as THREAD_VARIABLES  # re-exported: the variables set
from .threads import LimitedJob, current_threads, limited

__all__ = ["pool_map", "run_jobs", "unguarded_script"]

T = TypeVar("T")
R = TypeVar("R")

CONNECT_TIMEOUT_S = 20.0
"""How long to wait for an existing Dask scheduler [s]."""

_QUIET_WORKERS = {"distributed.worker.profile.enabled": False}
"""Dask settings of a local cluster's workers: no statistical profiler sampling every task's
stack (forcecal's jobs are many small NumPy calls, which it slows)."""

_HEAP = {"MALLOC_MMAP_THRESHOLD_": 32 << 20, "MALLOC_TRIM_THRESHOLD_": 256 << 20}
"""glibc's allocator in a local cluster's workers: arrays up to 32 MiB from the heap, and up to
256 MiB of freed heap kept for the next job. Dask's nanny sets ``MALLOC_TRIM_THRESHOLD_`` to
64 kB in its workers (``distributed.nanny.pre-spawn-environ``), which turns off glibc's adaptive
thresholds: every array over 128 kB is then a fresh mapping whose pages fault in when first
written. A calibration job in a fresh worker took 451,000 page faults and 0.9 s of system time
so (240,000 and 0.5 s with glibc's defaults, whose thresholds adapt during the first job);
with these, 3,600 faults and no system time, as in a process that has run one job already."""

_PARENT_POLL_S = 0.5
"""How often a pool worker checks that its parent is alive [s]."""

_INLINE = (type(None), bool, int, float, complex, str, bytes)
"""Job inputs sent within each job, even when shared: a scalar or a name."""


def _is_main_test(test: ast.expr) -> bool:
    """Whether an ``if`` tests ``__name__ == "__main__"`` (either way round)."""
    if not (isinstance(test, ast.Compare) and len(test.ops) == 1
            and isinstance(test.ops[0], ast.Eq)):
        return False
    sides = {ast.unparse(test.left), ast.unparse(test.comparators[0])}
    return sides == {"__name__", "'__main__'"}           # unparse writes one kind of quote


def unguarded_script() -> str | None:
    """Where the running script calls forcecal outside ``if __name__ == "__main__":``, when a
    ``spawn`` worker process would run that script again; None when no worker would.

    A ``spawn`` worker imports the main module again under another name: a script (or a
    module run with ``python -m``) runs its unguarded top level once more in every worker, and
    a call that starts workers there fails (``BrokenProcessPool``). A package's
    ``__main__``, an interactive session, ``python -c`` and a notebook are not run again.

    Returns
    -------
    str or None
        ``"script 'PATH' line N"``: the line of the script's top level that leads to this call.
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    name = getattr(getattr(main, "__spec__", None), "name", None) or ""
    if main is None or path is None or name == "__main__" or name.endswith(".__main__") \
            or Path(path).stem == "ipython":
        return None
    frame = inspect.currentframe()
    while frame is not None and not (frame.f_globals is vars(main)
                                     and frame.f_code.co_name == "<module>"):
        frame = frame.f_back
    if frame is None:                           # not from the script's top level: a thread
        return None
    line = frame.f_lineno
    try:
        with tokenize.open(path) as source:
            tree = ast.parse(source.read())
    except (OSError, SyntaxError, ValueError):
        return None
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and _is_main_test(node.test) \
                and node.body[0].lineno <= line <= (node.body[-1].end_lineno or line):
            return None
    return f"script '{path}' line {line}"


def check_main_guard(workers: int) -> None:
    """Refuse to start ``workers`` processes that would run the calling script again.

    Raises
    ------
    InputError
        Naming the script and its line (:func:`unguarded_script`), when it calls forcecal
        outside ``if __name__ == "__main__":``.
    """
    where = unguarded_script()
    if where is not None:
        raise InputError(f"workers = {workers}: the {where} calls forcecal outside "
                         "'if __name__ == \"__main__\":'; every worker process would run the "
                         "script again. Put the script's top level under that guard, or use "
                         "workers=1")


def pool_map(work: Callable[[Any], Any], items: list[Any], workers: int) -> Iterator[Any]:
    """``work(item)`` for every item in a ``spawn`` pool of at most ``workers`` processes,
    yielded as they complete.

    The pool starts its processes as the tasks are submitted, so the tasks are submitted under
    :func:`~.threads.limited` (the workers start with its ``*_NUM_THREADS``) and each task runs
    under the caller's limit (:class:`~.threads.LimitedJob`); the workers leave when the parent
    dies (:func:`_watch_parent`) and are terminated when the caller stops early or fails. A script
    that would run again in every worker is refused first (:func:`check_main_guard`).
    """
    check_main_guard(workers)
    pool = ProcessPoolExecutor(max_workers=max(1, min(workers, len(items))),
                               mp_context=multiprocessing.get_context("spawn"),
                               initializer=_watch_parent, initargs=(os.getpid(),))
    try:
        with limited() as threads:
            job = LimitedJob(work, threads)
            futures = [pool.submit(job, item) for item in items]
        for future in as_completed(futures):
            yield future.result()
    except BaseException:  # an error, Ctrl-C or the caller closing the generator early
        _stop_pool(pool)
        raise
    pool.shutdown(wait=True)


def _stop_pool(pool: ProcessPoolExecutor) -> None:
    """End a pool now: pending tasks cancelled, running workers terminated (an error or
    Ctrl-C in the parent must not leave them computing)."""
    processes = list(getattr(pool, "_processes", {}).values())  # before shutdown clears it
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        with contextlib.suppress(Exception):
            process.terminate()
    for process in processes:
        with contextlib.suppress(Exception):
            process.join(timeout=5)


def _watch_parent(parent: int) -> None:
    """Pool worker initializer: exit when the parent process is gone (killed with SIGKILL,
    say, when nothing could terminate the workers); a daemon thread polls the parent's pid."""

    def watch() -> None:
        while True:
            time.sleep(_PARENT_POLL_S)
            if os.getppid() != parent:
                os._exit(1)

    threading.Thread(target=watch, name="forcecal-parent-watch", daemon=True).start()


def run_jobs(
    work: Callable[[T], R],
    jobs: Sequence[T],
    names: Sequence[str] | None = None,
    workers: int = 1,
    scheduler: str | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> list[R]:
    """``[work(job) for job in jobs]``, spread over Dask when asked to.

    Parameters
    ----------
    work : callable
        A module-level function (the workers import it by name), pure in its argument.
    jobs : sequence
        Its arguments, one per job; picklable.
    names : sequence of str, optional
        A name per job for the progress (default its index).
    workers : int
        Processes of the local cluster; 1 runs the jobs serially in this process (unless
        ``scheduler`` is given).
    scheduler : str, optional
        The address of an existing Dask scheduler (``tcp://host:8786``); its workers run the
        jobs and ``workers`` is not used.
    progress : callable, optional
        ``progress(done, total, name)`` after each job, in the order they complete.

    Returns
    -------
    list
        The results, in the order of ``jobs``.

    Raises
    ------
    InputError
        The scheduler cannot be reached, or Dask is not installed.
    Exception
        The first job's failure, as the job raised it; the other jobs are cancelled.
    """
    total = len(jobs)
    labels = list(names) if names is not None else [str(k) for k in range(total)]
    if scheduler is None and (workers <= 1 or total <= 1):
        results = []
        for k, job in enumerate(jobs):
            results.append(work(job))
            if progress is not None:
                progress(k + 1, total, labels[k])
        return results
    with _Ahead(jobs, 2 * workers if scheduler is None else 2) as ahead, \
            _client(workers, scheduler) as client:
        return _spread(client, LimitedJob(work, current_threads()), ahead, labels, progress)


def _spread(client: Any, job: LimitedJob, jobs: _Ahead, labels: list[str],
            progress: Callable[[int, int, str], None] | None) -> list[Any]:
    """``job`` of every job over a Dask client, the results in the order of ``jobs``.

    The jobs are taken as they are submitted, at most :func:`_window` of them running or
    queued at once, from a reader that takes them ahead (:class:`_Ahead`): a sequence that reads
    a job's inputs when the job is taken (:func:`forcecal.cluster.jobs.calibrate_jobs`) is read
    while the cluster starts and while the workers compute, and the client holds the inputs of
    a few jobs only. The inputs the first two jobs share go to the cluster once
    (:func:`_share`). On a failure the jobs not done are cancelled; a job whose worker died, or
    a cluster left without workers, is one clear error (:func:`_result`, :func:`_finished`),
    never a wait without end.
    """
    total = len(jobs)
    jobs.ahead = max(jobs.ahead, _window(client))
    first = [jobs.take() for _ in range(min(2, total))]
    shared = _share(client, first)
    taken = enumerate(_taken(first, jobs))
    out: list[Any] = [None] * total
    running: dict[str, tuple[int, Any]] = {}

    def top_up() -> None:
        """Submit the next jobs until the window is full or no job is left."""
        limit = _window(client)
        while len(running) < limit and (item := next(taken, None)) is not None:
            k, args = item
            future = client.submit(job, _with_shared(args, shared),
                                   key=f"forcecal-{k}-{labels[k]}", pure=False)
            running[future.key] = (k, future)

    count = 0
    try:
        top_up()
        while running:
            for future in _finished(client, [f for _, f in running.values()], total - count):
                k, _ = running.pop(future.key)
                out[k] = _result(future, labels[k])
                count += 1
                if progress is not None:
                    progress(count, total, labels[k])
            top_up()
    except BaseException:
        client.cancel([future for _, future in running.values()])
        raise
    return out


WORKERLESS_S = 60.0
"""How long a cluster may have no worker while jobs wait before the jobs are given up [s]."""
_POLL_S = 1.0
"""How often the jobs' client looks at the cluster's workers while it waits [s]."""


def _finished(client: Any, futures: list[Any], left: int) -> list[Any]:
    """The futures done, once at least one is; a :class:`~forcecal.errors.ForcecalError`
    when the cluster has had no worker for :data:`WORKERLESS_S` (its workers died, or never
    came) while ``left`` jobs wait."""
    from distributed import wait

    alone_since: float | None = None
    while True:
        try:
            return list(wait(futures, timeout=_POLL_S, return_when="FIRST_COMPLETED").done)
        except TimeoutError:
            pass
        if client.nthreads():
            alone_since = None
            continue
        now = time.monotonic()
        alone_since = now if alone_since is None else alone_since
        if now - alone_since >= WORKERLESS_S:
            raise ForcecalError(
                f"the Dask cluster at {client.scheduler.address} has had no worker for "
                f"{WORKERLESS_S:g} s with {left} job{'s' if left != 1 else ''} not done (its "
                "workers died or never started: out of memory, killed, or not installed); "
                "the jobs were given up")


def _result(future: Any, label: str) -> Any:
    """A job's result; its failure as the job raised it, or one clear error when the worker
    running it died each time it was tried (Dask's ``KilledWorker``)."""
    from distributed import KilledWorker

    try:
        return future.result()
    except KilledWorker:
        raise ForcecalError(
            f"job '{label}': the worker process running it died (out of memory, or killed) "
            "each time it was tried; the other jobs were cancelled") from None


def _taken(first: list[Any], jobs: _Ahead) -> Iterator[Any]:
    """The jobs, the first ones as taken already, the others taken from ``jobs`` one by one."""
    yield from first
    for _ in range(len(first), len(jobs)):
        yield jobs.take()


_READERS = 1
"""Threads of the client reading jobs ahead. Two, on 16 workers of a 16-core machine, competed
with the workers for the cores: the jobs computed slower (0.78 s a job against 0.25) and the
workers waited as long (0.97 s a job against 0.93)."""


class _Ahead:
    """The jobs of a sequence taken in order (:meth:`take`), up to ``ahead`` of them taken
    beforehand by a reader thread (:data:`_READERS`) from the moment the block opens: the client
    reads the first jobs' inputs while the cluster starts (1.6 s on 2 cores, 4.4 s on 16), and
    the next while the workers compute (``ahead``: the cluster's window, :func:`_window`, once
    it is known). A job that fails to be taken raises when it is its turn; leaving the block
    cancels what is not yet read."""

    def __init__(self, jobs: Sequence[Any], ahead: int) -> None:
        self.jobs, self.ahead, self.next = jobs, max(1, ahead), 0
        self.pool = ThreadPoolExecutor(_READERS, thread_name_prefix="forcecal-reader")
        self.pending: dict[int, Any] = {}

    def __len__(self) -> int:
        return len(self.jobs)

    def __enter__(self) -> _Ahead:
        self._fill()
        return self

    def __exit__(self, *exc: object) -> None:
        self.pool.shutdown(wait=True, cancel_futures=True)

    def _fill(self) -> None:
        """Start reading the jobs up to ``ahead`` beyond the next one taken."""
        end = min(len(self.jobs), self.next + self.ahead)
        for k in range(self.next, end):
            if k not in self.pending:
                self.pending[k] = self.pool.submit(self.jobs.__getitem__, k)

    def take(self) -> Any:
        """The next job, read (its reading's error raised here)."""
        k = self.next
        self._fill()
        self.next += 1
        return self.pending.pop(k).result()


def _window(client: Any) -> int:
    """Jobs submitted and not done at most: two for each thread of the cluster's workers
    (one running, one queued behind it), at least two."""
    return max(2, 2 * sum(client.nthreads().values()))


def _share(client: Any, first: list[Any]) -> dict[int, tuple[Any, Any]]:
    """The inputs that the first tuple jobs hold in common (the same object: the rig, the
    model), each sent to the cluster once (``client.scatter``): ``id(input) -> (input, its
    future)``; every other input travels within its job."""
    tuples = [job for job in first if isinstance(job, tuple)]
    if len(tuples) < 2:
        return {}
    common = {id(x): x for x in tuples[0] if not isinstance(x, _INLINE)}
    common = {key: x for key, x in common.items() if any(y is x for y in tuples[1])}
    futures = client.scatter(list(common.values()), hash=False) if common else []
    return {key: (x, f) for (key, x), f in zip(common.items(), futures, strict=True)}


def _with_shared(job: Any, shared: dict[int, tuple[Any, Any]]) -> Any:
    """The job with each input of ``shared`` replaced by its future, which the worker resolves
    to the input before the job runs."""
    if not isinstance(job, tuple) or not shared:
        return job
    return tuple(shared[id(x)][1] if not isinstance(x, _INLINE) and id(x) in shared
                 and shared[id(x)][0] is x else x for x in job)


@contextlib.contextmanager
def _client(workers: int, scheduler: str | None) -> Iterator[Any]:
    """A Dask client: to the scheduler at ``scheduler``, or to a local cluster of ``workers``
    processes of one task each, started under the caller's thread limit (:mod:`.threads`),
    that lives as long as the client (its HTTP server on a free port, quiet logs)."""
    try:
        from distributed import Client, LocalCluster
    except ImportError:  # pragma: no cover - a dependency; kept for a trimmed install
        raise InputError("--scheduler/--workers: the Dask 'distributed' package is not "
                         "installed (pip install distributed)") from None
    if scheduler is not None:
        try:
            client = Client(scheduler, timeout=CONNECT_TIMEOUT_S)
        except (OSError, TimeoutError, ValueError) as exc:
            raise InputError(f"--scheduler {scheduler}: no Dask scheduler answers there "
                             f"({exc})") from None
        with client:
            yield client
        return
    import dask

    check_main_guard(workers)
    environ = dask.config.get("distributed.nanny.pre-spawn-environ")
    with limited() as threads, dask.config.set(
            {**_QUIET_WORKERS, "distributed.nanny.pre-spawn-environ":
             {**environ, **_HEAP, **dict.fromkeys(THREAD_VARIABLES, threads)}}):
        # its HTTP server on a free port: two clusters on one machine (two commands at once)
        # do not both ask for Dask's default 8787
        cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True,
                               dashboard_address=":0", silence_logs=logging.ERROR)
    with cluster, Client(cluster) as client:
        client.run(importlib.import_module, "forcecal.cluster.jobs")  # imports paid at the start
        yield client
