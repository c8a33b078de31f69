"""Run idempotent tasks in this process, on a local pool of worker processes, or on a Dask cluster.

One small API for all three (:class:`Executor`): ``map_unordered(fn, tasks, *shared)``
yields ``(task, result)`` pairs as tasks finish, where ``result`` is ``fn(task, *shared)``
or a :class:`TaskFailure` when ``fn`` raised one of qdcnn's own errors or an OS error
(programming errors propagate, as in :func:`qdcnn.batch.run_batch`).

Where tasks run is one string, the CLI's ``--scheduler``:

``None`` or ``"none"``
    In this process, one task after the other (no extra needed).
``"local:N"``
    A ``dask.distributed.LocalCluster`` of ``N`` worker processes with one thread each,
    started for the executor and stopped with it.
``"tcp://HOST:PORT"``
    An existing Dask scheduler. If none answers within ``timeout`` seconds the executor
    raises :class:`~qdcnn.errors.InputError` naming the address.

Tasks must be idempotent (running one twice gives the same result and writes nothing
that a second run would change), because Dask runs a task again when its worker dies
(``distributed.scheduler.allowed-failures``, 3 by default) and ``retries`` times more when
it raises. Tasks, shared objects and results travel between processes pickled *in
memory* by Dask; no file is ever unpickled. ``shared`` objects are not sent with every
task: each is the result of one small task that returns it (:func:`_shared_value`),
which the tasks depend on, so each worker fetches it once, from another. Nothing a task needs
exists only on one worker: a lost worker's copy is recomputed elsewhere from the task's
definition, which the scheduler keeps (scattered data, by contrast, is lost with the
last worker holding it, and every task needing it is cancelled).

Without the ``dask`` extra, asking for a scheduler raises
:class:`~qdcnn.errors.MissingExtraError` naming it.
"""

from __future__ import annotations

import logging
import os
import re
import time
from collections.abc import Callable, Iterable, Iterator
from dataclasses import dataclass, replace
from typing import Any, Generic, TypeVar

from qdcnn._closing import ClosesOnExit
from qdcnn._optional import require
from qdcnn.errors import InputError, ParameterError, QdcnnError

T = TypeVar("T")
R = TypeVar("R")

_LOCAL = re.compile(r"^local(?::(\d+))?$")
_REMOTE = re.compile(r"^(tcp|tls|ucx|ws|wss)://[^\s/:]+(:\d+)?/?$")
_SCHEDULER_HELP = "none, local, local:N (N worker processes) or tcp://HOST:PORT"


@dataclass(frozen=True)
class TaskFailure:
    """A task that raised one of qdcnn's errors (or an OS error), as one line."""

    error: str
    kind: str

    def to_dict(self) -> dict[str, str]:
        return {"error": self.error, "kind": self.kind}


@dataclass
class ExecutorStats:
    """Counts and times of the tasks an executor has run (measured).

    ``compute_seconds`` is the time spent inside ``fn``; ``wall_seconds`` the time from
    the first submission to the last result; ``overhead_per_task`` is their difference
    per task, divided by the workers' count where tasks run in parallel, so it is the
    scheduling and transfer cost one task adds to a job.
    """

    tasks: int = 0
    failures: int = 0
    compute_seconds: float = 0.0
    wall_seconds: float = 0.0
    workers: int = 1

    @property
    def overhead_per_task(self) -> float | None:
        if not self.tasks:
            return None
        return max(self.wall_seconds * self.workers - self.compute_seconds, 0.0) / self.tasks

    def to_dict(self) -> dict[str, Any]:
        return {
            "kind": "measured",
            "tasks": self.tasks,
            "failures": self.failures,
            "compute_seconds": self.compute_seconds,
            "wall_seconds": self.wall_seconds,
            "workers": self.workers,
            "overhead_per_task_seconds": self.overhead_per_task,
        }


@dataclass(frozen=True)
class _Shared:
    """An object handed to tasks, wrapped so that Dask sends it as one opaque value (a
    dict or list would be searched for futures, item by item)."""

    value: Any


def _shared_value(shared: _Shared) -> Any:
    """The task whose result is a shared object (recomputed if its worker is lost)."""
    return shared.value


@dataclass(frozen=True)
class _Done(Generic[R]):
    result: R | TaskFailure
    seconds: float


def _call(fn: Callable[..., R], task: Any, *shared: Any) -> _Done[R]:
    """Run one task where it is scheduled; qdcnn and OS errors become failures."""
    t0 = time.perf_counter()
    try:
        result: R | TaskFailure = fn(task, *shared)
    except QdcnnError as exc:
        result = TaskFailure(" ".join(str(exc).split()), type(exc).__name__)
    except OSError as exc:
        result = TaskFailure(f"{exc.filename or 'task'}: {exc.strerror or exc}", type(exc).__name__)
    return _Done(result, time.perf_counter() - t0)


def parse_scheduler(spec: str | None) -> tuple[str, int | str | None]:
    """``("in-process", None)``, ``("local", N)`` or ``("remote", address)``.

    Raises
    ------
    ParameterError
        Anything else.
    """
    if spec is None or spec == "none":
        return "in-process", None
    if not isinstance(spec, str):
        raise ParameterError("scheduler", spec, _SCHEDULER_HELP)
    m = _LOCAL.match(spec)
    if m:
        n = int(m.group(1)) if m.group(1) else (os.cpu_count() or 1)
        if not 1 <= n <= 1024:
            raise ParameterError("scheduler", spec, "local:N with N in [1, 1024]")
        return "local", n
    if _REMOTE.match(spec):
        return "remote", spec
    raise ParameterError("scheduler", spec, _SCHEDULER_HELP)


def _limit_threads() -> None:
    """One thread per worker for OpenCV and BLAS (workers are the parallelism)."""
    import cv2
    from threadpoolctl import threadpool_limits  # type: ignore[import-untyped]

    cv2.setNumThreads(1)
    threadpool_limits(1)


class Executor(ClosesOnExit):
    """Where tasks run; see the module docstring.

    Parameters
    ----------
    scheduler : str or None
        ``None``/``"none"``, ``"local:N"`` or ``"tcp://HOST:PORT"``.
    retries : int
        Extra attempts of a task that raised (Dask only; a dead worker's tasks are
        rescheduled in any case).
    timeout : float
        Seconds to wait for a remote scheduler to answer, or for a local cluster to start.
    max_in_flight : int or None
        Tasks submitted ahead of the results taken (default: 2 per worker thread), so
        results of a long job never pile up in memory.

    Raises
    ------
    ParameterError
        A scheduler string of another form.
    MissingExtraError
        A scheduler was asked for without the ``dask`` extra.
    InputError
        The remote scheduler did not answer within ``timeout`` seconds.
    """

    def __init__(
        self,
        scheduler: str | None = None,
        *,
        retries: int = 2,
        timeout: float = 5.0,
        max_in_flight: int | None = None,
    ) -> None:
        self.kind, target = parse_scheduler(scheduler)
        self.spec = scheduler or "none"
        if isinstance(retries, bool) or not isinstance(retries, int) or not 0 <= retries <= 100:
            raise ParameterError("retries", retries, "an integer in [0, 100]")
        ok = isinstance(timeout, int | float) and not isinstance(timeout, bool)
        if not ok or not 0 < timeout <= 3600:
            raise ParameterError("timeout", timeout, "seconds in (0, 3600]")
        self.retries, self.timeout = retries, float(timeout)
        self._client: Any = None
        self._cluster: Any = None
        self.stats = ExecutorStats()
        if self.kind == "local":
            self._start_local(int(target))  # type: ignore[arg-type]
        elif self.kind == "remote":
            self._connect(str(target))
        self.workers = self._count_workers()
        self.stats.workers = self.workers
        self.max_in_flight = max_in_flight or 2 * self.workers

    def _start_local(self, n: int) -> None:
        distributed = require("distributed", "running tasks on a Dask LocalCluster (--scheduler)")
        env = {"OMP_NUM_THREADS": "1", "OPENBLAS_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
        self._cluster = distributed.LocalCluster(
            n_workers=n,
            threads_per_worker=1,
            processes=True,
            dashboard_address=None,
            silence_logs=logging.ERROR,
            env=env,
        )
        self._client = distributed.Client(self._cluster, timeout=self.timeout)
        self._client.wait_for_workers(n, timeout=self.timeout)  # slow to register under load
        self._client.register_worker_callbacks(_limit_threads)  # restarted workers too

    def _connect(self, address: str) -> None:
        distributed = require("distributed", "connecting to a Dask scheduler (--scheduler)")
        try:
            self._client = distributed.Client(address, timeout=self.timeout)
        except (OSError, TimeoutError) as exc:
            reason = " ".join(str(exc).split())[:160]
            raise InputError(
                address, f"no Dask scheduler answered within {self.timeout:g} s ({reason})"
            ) from None
        except Exception as exc:  # whatever answered, it is not a scheduler
            # Something that is not a Dask scheduler can answer with bytes that the
            # protocol reads as an absurd frame length (seen as MemoryError).
            raise InputError(
                address, f"did not answer as a Dask scheduler ({type(exc).__name__})"
            ) from None

    def _count_workers(self) -> int:
        if self._client is None:
            return 1
        info = self._client.scheduler_info()
        threads = sum(int(w.get("nthreads", 1)) for w in info.get("workers", {}).values())
        return max(threads, 1)

    @property
    def in_process(self) -> bool:
        return self._client is None

    # ------------------------------------------------------------------ running tasks
    def map_unordered(
        self, fn: Callable[..., R], tasks: Iterable[T], *shared: Any
    ) -> Iterator[tuple[T, R | TaskFailure]]:
        """Run ``fn(task, *shared)`` for every task; yield ``(task, result)`` as each ends.

        In this process the order is the tasks' order; on Dask it is the order of
        completion. A task whose ``fn`` raised a qdcnn error or an OS error yields a
        :class:`TaskFailure` instead of a result.
        """
        t0 = time.perf_counter()
        try:
            if self._client is None:
                for task in tasks:
                    done = _call(fn, task, *shared)
                    yield task, self._account(done)
            else:
                yield from self._map_dask(fn, tasks, shared)
        finally:
            self.stats.wall_seconds += time.perf_counter() - t0

    def _account(self, done: _Done[Any]) -> Any:
        self.stats.tasks += 1
        self.stats.compute_seconds += done.seconds
        if isinstance(done.result, TaskFailure):
            self.stats.failures += 1
        return done.result

    def _map_dask(
        self, fn: Callable[..., R], tasks: Iterable[T], shared: tuple[Any, ...]
    ) -> Iterator[tuple[T, R | TaskFailure]]:
        distributed = require("distributed", "running tasks on Dask")
        client = self._client
        handles = [client.submit(_shared_value, _Shared(obj), pure=False) for obj in shared]
        pending: dict[Any, T] = {}
        queue = distributed.as_completed()
        source = iter(tasks)

        def submit_more() -> None:
            while len(pending) < self.max_in_flight:
                try:
                    task = next(source)
                except StopIteration:
                    return
                future = client.submit(_call, fn, task, *handles, pure=False, retries=self.retries)
                pending[future] = task
                queue.add(future)

        try:
            submit_more()
            while pending:
                future = next(queue)
                task = pending.pop(future)
                done = future.result()
                future.release()
                submit_more()
                yield task, self._account(done)
        finally:
            for future in list(pending):
                future.cancel()
            for handle in handles:
                handle.release()

    def measure_overhead(self, n: int = 200) -> float:
        """Seconds a no-op task costs from submission to result, per task (measured)."""
        saved = replace(self.stats)
        t0 = time.perf_counter()
        for _ in self.map_unordered(_noop, range(n)):
            pass
        seconds = time.perf_counter() - t0
        self.stats = saved
        return seconds * self.workers / n

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
        if self._cluster is not None:
            self._cluster.close()
            self._cluster = None

    def describe(self) -> dict[str, Any]:
        return {"scheduler": self.spec, "kind": self.kind, "workers": self.workers}


def _noop(task: Any) -> Any:
    return task
