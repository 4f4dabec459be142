"""Workers for ipm's long jobs (``ipm generate``, ``ipm fit FOLDER``): each holds one object
made once (a renderer, nets) and is given one task at a time; this process alone, spawned
local processes, or Ray actors on a cluster (``--ray``).  A task's result is the same
whichever way it ran; the driver writes what the workers return, so workers need no disk
shared with it.  Spawned, not forked: Dr.Jit's threads do not survive a fork."""

from __future__ import annotations

import os
import signal
import sys
from collections.abc import Callable, Hashable, Iterable, Iterator
from concurrent.futures import FIRST_COMPLETED, Future, ProcessPoolExecutor, wait
from multiprocessing import get_context

from ipm.errors import UserError

RAY_HELP = ("run on Ray actors instead of local processes: 'local' starts a cluster on this "
            "machine, 'auto' joins the one `ray start --head` started, or host:port "
            "(pip install -e '.[ray]')")


def die_with_parent() -> None:
    """End this worker when the process that started it ends, even by SIGKILL: Linux's
    parent-death signal where there is one, and everywhere a thread that watches the parent
    (a worker of a killed command would otherwise work on, orphaned)."""
    import threading
    import time

    parent = os.getppid()
    if sys.platform.startswith("linux"):
        import ctypes

        try:
            ctypes.CDLL("libc.so.6", use_errno=True).prctl(1, signal.SIGKILL)  # PR_SET_PDEATHSIG
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the signal was set
        os._exit(1)

    def watch() -> None:
        while os.getppid() == parent:
            time.sleep(1.0)
        os._exit(1)

    threading.Thread(target=watch, daemon=True, name="parent-watch").start()


def connect_ray(address: str):
    """The ``ray`` module, connected: ``address`` "local" starts a cluster on this machine,
    "auto" joins a running one (``ray start --head``), else ``host:port``; a process that
    already called ``ray.init`` keeps its cluster."""
    try:
        import ray
    except ImportError:
        raise UserError("--ray needs the ray extra: pip install -e '.[ray]'") from None
    if not ray.is_initialized():
        try:
            ray.init(address=None if address == "local" else address, log_to_driver=False,
                     include_dashboard=False)
        except ConnectionError as e:
            raise UserError(f"cannot reach a Ray cluster at {address!r} ({e}): start one with "
                            "`ray start --head`, or give --ray local; a cluster with token "
                            "authentication also needs RAY_AUTH_MODE=token and its token "
                            "(~/.ray/auth_token) here") from None
    return ray


# -- what a worker holds ---------------------------------------------------------------------
_held = None


def _hold(factory: Callable, args: tuple, threads: int | None) -> None:
    """A local worker process's initializer: make its object once."""
    global _held
    die_with_parent()
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # Ctrl-C is the driver's to handle
    _held = factory(*args, threads=threads)


def _call(method: str, args: tuple):
    return getattr(_held, method)(*args)


class _Actor:
    """A Ray actor holding one object (as :func:`_hold`)."""

    def __init__(self, factory: Callable, args: tuple, threads: int) -> None:
        self.held = factory(*args, threads=threads)

    def call(self, method: str, args: tuple):
        return getattr(self.held, method)(*args)


class Workers:
    """``workers`` holders of ``factory(*args, threads=T)``: this process itself (one
    worker, no Ray: nothing spawned, every core its threads), spawned local processes
    (cores / workers threads each), or Ray actors of one CPU each (``ray``: an address for
    :func:`connect_ray`; at most the cluster's CPUs).  :meth:`run` keeps every worker busy
    with one task at a time, so at most ``workers`` tasks are in flight: a killed run
    loses only those."""

    def __init__(self, factory: Callable, args: tuple = (), workers: int = 1,
                 ray: str | None = None) -> None:
        if workers < 1:
            raise UserError(f"workers must be >= 1, got {workers}")
        self.ray = None
        self._pool = None
        self._actors: list = []
        self._local = None
        if ray is not None:
            self.ray = connect_ray(ray)
            cpus = int(self.ray.cluster_resources().get("CPU", 1))
            remote = self.ray.remote(num_cpus=1)(_Actor)
            self._actors = [remote.remote(factory, args, 1) for _ in range(min(workers, cpus))]
            self.count = len(self._actors)
        elif workers == 1:
            self._local = factory(*args, threads=None)
            self.count = 1
        else:
            cores = os.cpu_count() or 1
            self._pool = ProcessPoolExecutor(workers, mp_context=get_context("spawn"),
                                             initializer=_hold,
                                             initargs=(factory, args,
                                                       max(1, cores // workers)))
            self.count = workers

    def run(self, method: str, tasks: Iterable[tuple[Hashable, tuple]]
            ) -> Iterator[tuple[Hashable, object]]:
        """``(key, result)`` of ``held.method(*args)`` for each ``(key, args)`` of
        ``tasks``, in the order they finish.  ``tasks`` is drawn from only when a worker is
        free (a generator that reads a photo's bytes then keeps in memory only those in
        flight).  A worker's exception is raised here."""
        tasks = iter(tasks)
        if self._local is not None:
            for key, args in tasks:
                yield key, getattr(self._local, method)(*args)
            return
        pending: dict[Future, tuple[Hashable, object]] = {}
        idle = list(self._actors) if self._actors else [None] * self.count

        def submit() -> bool:
            nxt = next(tasks, None)
            if nxt is None:
                return False
            key, args = nxt
            worker = idle.pop()
            fut = (self._pool.submit(_call, method, args) if worker is None
                   else worker.call.remote(method, args).future())
            pending[fut] = (key, worker)
            return True

        while idle and submit():
            pass
        while pending:
            finished, _ = wait(pending, return_when=FIRST_COMPLETED)
            for fut in finished:
                key, worker = pending.pop(fut)
                idle.append(worker)
                yield key, fut.result()
                submit()

    def close(self) -> None:
        """Stop every worker now; tasks in flight are dropped."""
        if self._pool is not None:
            processes = list((self._pool._processes or {}).values())  # noqa: SLF001
            self._pool.shutdown(wait=False, cancel_futures=True)
            for p in processes:  # a task in flight may run for minutes: do not wait for it
                p.kill()
            self._pool = None
        for actor in self._actors:
            self.ray.kill(actor)
        self._actors = []

    def __enter__(self) -> Workers:
        return self

    def __exit__(self, *exc) -> None:
        self.close()
