"""The sweep runner and its back ends: local worker processes, or a Ray cluster.

:func:`run_sweep` skips the runs its store already holds, hands the others to the back end, stores each
row as its run ends and tells ``progress`` the rate and the time left. Every back end runs the same
:func:`~.tasks.execute` on the same tasks, so the rows do not depend on where or on how many workers they
ran: a task's seed is in the task.

* :class:`LocalBackend` (``--jobs N``, the default): N worker processes on this machine (forked where the
  system allows, as the planner benchmark always did); one worker runs the tasks in this process.
* :class:`RayBackend` (``--ray local|auto|ADDRESS``): ``local`` starts a one-machine cluster on 127.0.0.1
  for the sweep and stops it afterwards; ``auto`` joins the cluster this machine belongs to; anything else is
  a cluster's address (``ray://host:10001`` or ``host:6379``), whose nodes get this package's code shipped
  with the tasks (Ray's ``py_modules``) and must have its dependencies installed. Ray is an optional extra:
  ``pip install agnav[ray]``.
"""

from __future__ import annotations

import logging
import os
import signal
import sys
import time
from dataclasses import dataclass
from typing import Any, Callable, Iterator, Sequence

from .storage import RunStore
from .tasks import Outcome, Task, code_digest, execute, row_of, task_key

__all__ = ["Backend", "LocalBackend", "RayBackend", "RayMissing", "RayUnreachable", "SweepFailed", "Progress",
           "make_backend", "run_sweep", "RAY_HINT"]

log = logging.getLogger(__name__)

RAY_HINT = "pip install agnav[ray]"
#: Tasks handed out ahead of the free workers (per worker), so that none waits for the driver
AHEAD_PER_WORKER = 2


class RayMissing(RuntimeError):
    """``--ray`` was asked for and Ray is not installed."""


class RayUnreachable(RuntimeError):
    """No Ray cluster at the address given, or it could not be started."""


class SweepFailed(RuntimeError):
    """A task raised: the message names the task (its function, spec and seed) and the error; ``error`` is
    the task's own exception."""

    def __init__(self, message: str, error: BaseException | None = None) -> None:
        super().__init__(message)
        self.error = error


@dataclass(frozen=True)
class Progress:
    """Where a sweep is: ``done`` of ``total`` runs (``resumed`` of them stored by an earlier sweep), the rate
    of the runs of this sweep (runs/s) and the time left at that rate (s; None before the first run ends), the
    row that just ended."""

    done: int
    total: int
    resumed: int
    rate_per_s: float
    left_s: float | None
    row: dict[str, Any]


class Backend:
    """Runs tasks somewhere: :meth:`map` yields (index, outcome) as each task ends, in any order."""

    name = "backend"

    def __enter__(self) -> "Backend":
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def close(self) -> None:
        pass

    def workers(self, n_tasks: int) -> int:
        raise NotImplementedError

    def describe(self, n_tasks: int) -> str:
        return f"{self.workers(n_tasks)} worker(s)"

    def map(self, tasks: Sequence[Task]) -> Iterator[tuple[int, Outcome]]:
        raise NotImplementedError


def _ignore_sigint() -> None:  # workers: Ctrl-C is the driver's to handle (it stops handing out tasks)
    signal.signal(signal.SIGINT, signal.SIG_IGN)


class LocalBackend(Backend):
    """``jobs`` worker processes (default: every core), never more than the tasks; one runs them here."""

    name = "local"

    def __init__(self, jobs: int | None = None) -> None:
        self.jobs = jobs

    def workers(self, n_tasks: int) -> int:
        return max(1, min(self.jobs or os.cpu_count() or 1, n_tasks))

    def describe(self, n_tasks: int) -> str:
        n = self.workers(n_tasks)
        return "1 worker (this process)" if n == 1 else f"{n} local worker processes"

    def map(self, tasks: Sequence[Task]) -> Iterator[tuple[int, Outcome]]:
        n = self.workers(len(tasks))
        if n == 1:
            for i, t in enumerate(tasks):
                try:
                    out = execute(t)
                except Exception as e:  # noqa: BLE001  (named with its task)
                    raise SweepFailed(_failure(t, e), e) from e
                yield i, out
            return
        import multiprocessing as mp
        from concurrent.futures import FIRST_COMPLETED, ProcessPoolExecutor, wait

        ctx = mp.get_context("fork") if sys.platform.startswith("linux") else mp.get_context()
        ex = ProcessPoolExecutor(n, mp_context=ctx, initializer=_ignore_sigint)
        pending: dict[Any, int] = {}
        todo = iter(range(len(tasks)))
        try:
            while True:
                for i in todo:
                    pending[ex.submit(execute, tasks[i])] = i
                    if len(pending) >= n * (1 + AHEAD_PER_WORKER):
                        break
                if not pending:
                    return
                done, _ = wait(list(pending), return_when=FIRST_COMPLETED)
                for f in done:
                    i = pending.pop(f)
                    try:
                        out = f.result()
                    except Exception as e:  # noqa: BLE001  (named with its task below)
                        raise SweepFailed(_failure(tasks[i], e), e) from e
                    yield i, out
        finally:
            ex.shutdown(wait=True, cancel_futures=True)


def _failure(task: Task, e: BaseException) -> str:
    spec = ", ".join(f"{k}={v!r}" for k, v in task.spec.items())
    return f"{task.name} ({spec}, seed {task.seed}) failed: {type(e).__name__}: {e}"


class RayBackend(Backend):
    """The tasks on a Ray cluster at ``address`` ("local", "auto" or an address); ``jobs`` caps the CPUs of
    a ``local`` cluster (default: every core)."""

    name = "ray"

    def __init__(self, address: str, jobs: int | None = None) -> None:
        try:
            import ray  # noqa: F401
        except ImportError as e:
            raise RayMissing(f"--ray needs Ray, an optional extra of agnav: {RAY_HINT}") from e
        self.address = address
        self.jobs = jobs
        self._cpus = 0
        self._open = False

    def __enter__(self) -> "RayBackend":
        self.open()
        return self

    def open(self) -> None:
        if self._open:
            return
        import ray

        kw: dict[str, Any] = {"include_dashboard": False, "log_to_driver": False, "logging_level": logging.WARNING}
        if self.address not in ("local", "auto"):
            _reachable(self.address)
        try:
            if ray.is_initialized():
                pass
            elif self.address == "local":
                ray.init(address="local", num_cpus=self.jobs or os.cpu_count() or 1, _node_ip_address="127.0.0.1",
                         object_store_memory=256 * 1024 * 1024, **kw)
            else:
                from .._paths import PACKAGE_DIR

                ray.init(address=self.address, runtime_env={"py_modules": [str(PACKAGE_DIR)],
                                                             "excludes": ["__pycache__", "*.pyc"]}, **kw)
        except Exception as e:  # noqa: BLE001  (Ray raises ConnectionError, RuntimeError, ValueError...)
            raise RayUnreachable(f"--ray {self.address}: no Ray cluster there ({type(e).__name__}: {e})") from e
        self._open = True
        self._cpus = int(ray.cluster_resources().get("CPU", 1))  # type: ignore[no-untyped-call]

    def close(self) -> None:
        if self._open:
            import ray

            ray.shutdown()
            self._open = False

    def workers(self, n_tasks: int) -> int:
        self.open()
        return max(1, min(self._cpus, n_tasks))

    def describe(self, n_tasks: int) -> str:
        where = "a local Ray cluster (127.0.0.1)" if self.address == "local" else f"the Ray cluster at {self.address}"
        return f"{self.workers(n_tasks)} Ray worker(s) on {where}"

    def map(self, tasks: Sequence[Task]) -> Iterator[tuple[int, Outcome]]:
        import ray

        self.open()
        remote = ray.remote(num_cpus=1, max_retries=0)(execute)
        window = self.workers(len(tasks)) * (1 + AHEAD_PER_WORKER)
        pending: dict[Any, int] = {}
        todo = iter(range(len(tasks)))
        try:
            while True:
                for i in todo:
                    pending[remote.remote(tasks[i])] = i
                    if len(pending) >= window:
                        break
                if not pending:
                    return
                ready, _ = ray.wait(list(pending), num_returns=1)
                for ref in ready:
                    i = pending.pop(ref)
                    try:
                        out = ray.get(ref)
                    except Exception as e:  # noqa: BLE001  (RayTaskError carries the task's own error)
                        cause = getattr(e, "cause", None) or e
                        raise SweepFailed(_failure(tasks[i], cause), cause) from e
                    yield i, out
        finally:
            for ref in pending:
                ray.cancel(ref, force=True)


def _reachable(address: str, timeout_s: float = 5.0) -> None:
    """Raise :class:`RayUnreachable` at once when nothing listens at ``address`` (``HOST:PORT`` or
    ``ray://HOST:PORT``): Ray itself keeps retrying such an address for many minutes."""
    import socket

    hostport = address.split("://", 1)[-1].rstrip("/")
    host, sep, port = hostport.rpartition(":")
    if not sep or not port.isdigit():
        raise RayUnreachable(f"--ray {address}: expected local, auto, HOST:PORT or ray://HOST:PORT")
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=timeout_s).close()
    except OSError as e:
        raise RayUnreachable(f"--ray {address}: no Ray cluster there ({e.strerror or e})") from e


def make_backend(jobs: int | None = None, ray: str | None = None) -> Backend:
    """The back end of ``--jobs`` / ``--ray``: Ray when ``ray`` names a cluster, else local processes."""
    return RayBackend(ray, jobs) if ray else LocalBackend(jobs)


def run_sweep(tasks: Sequence[Task], backend: Backend | None = None, store: RunStore | None = None,
              progress: Callable[[Progress], None] | None = None, order: Sequence[int] | None = None) -> list[dict[str, Any]]:
    """Run every task of ``tasks`` that ``store`` does not hold yet on ``backend`` (default: local processes),
    storing each row as its run ends; returns the rows in the order of ``tasks``. ``order``: the order in which
    to hand them out (indices into ``tasks``; the longest first lets the workers end together). A task that
    raises stops the sweep with :class:`SweepFailed` (the runs that ended are stored)."""
    backend = backend or LocalBackend()
    store = store if store is not None else RunStore(None)
    code = code_digest()
    keys = [task_key(t, code) for t in tasks]
    todo: list[int] = []
    seen: set[str] = set()
    for i in (range(len(tasks)) if order is None else order):
        if keys[i] not in store and keys[i] not in seen:
            todo.append(i)
            seen.add(keys[i])
    total = len(set(keys))
    resumed = total - len(todo)
    t0 = time.monotonic()
    for n, (j, outcome) in enumerate(backend.map([tasks[i] for i in todo]), 1):
        i = todo[j]
        row = row_of(tasks[i], keys[i], outcome)
        store.add(row, outcome.timing, outcome.arrays)
        if progress is not None:
            rate = n / max(time.monotonic() - t0, 1e-9)
            progress(Progress(resumed + n, total, resumed, rate, (len(todo) - n) / rate, row))
    return [store.row(k) for k in keys]
