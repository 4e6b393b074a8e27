"""Where independent tasks run: in this process (:class:`_Inline`), in worker processes (:class:`_Processes`)
or on a Dask cluster (:class:`_Dask`), each behind the same three calls (``submit``, ``as_completed``,
``close``); :func:`executor` chooses.  A batch's pictures and a big stack's slabs run on them.
"""

from __future__ import annotations

import os
import shutil
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError


class _Inline:
    """Runs tasks in this process, in order (jobs = 1)."""

    died = ()       # what a future's result raises when the process of its task died: nothing here

    def submit(self, fn, *args):
        from concurrent.futures import Future

        future = Future()
        future.set_result(fn(*args))
        return future

    def as_completed(self, futures):
        return iter(futures)

    def close(self):
        pass


class _WorkerDied(Exception):
    """The process running a task died (killed, or out of memory); the message says how."""


@dataclass
class _Task:
    """A task of :class:`_Processes`: what to run, its mark, and its future in the pool now."""

    fn: object
    args: tuple
    mark: Path                          # exists while a worker runs the task
    running: object = None              # its future in the pool


class _Processes:
    """Runs tasks in worker processes (jobs > 1), and survives a worker that dies.

    A worker killed (by a signal, or for want of memory) breaks its whole pool: every task not yet finished then
    fails.  The tasks that were running when it broke (each marks itself while it runs) are run again one at a
    time, each in a process of its own, so the one that kills its process is found and gets a :class:`_WorkerDied`
    with how its process ended; the tasks still waiting go to a new pool.  :meth:`submit` gives a future of its
    own, which stays the task's whichever process runs it.
    """

    died = (_WorkerDied,)

    def __init__(self, jobs):
        self.jobs = jobs
        self.marks = Path(tempfile.mkdtemp(prefix="voxrender-running-"))
        self.tasks = {}
        self.pool = self._new_pool()

    def _new_pool(self):
        from concurrent.futures import ProcessPoolExecutor

        return ProcessPoolExecutor(max_workers=self.jobs, initializer=_start_worker, initargs=(os.getpid(), self.jobs))

    def submit(self, fn, *args):
        from concurrent.futures import Future

        future = Future()
        self._start(self.tasks.setdefault(future, _Task(fn, args, self.marks / str(len(self.tasks)))))
        return future

    def _start(self, task):
        from concurrent.futures import Future
        from concurrent.futures.process import BrokenProcessPool

        try:
            task.running = self.pool.submit(_marked, task.mark, task.fn, *task.args)
        except BrokenProcessPool as exc:    # broken since the last look: it goes again with the others
            task.running = Future()
            task.running.set_exception(exc)

    def as_completed(self, futures):
        from concurrent.futures import FIRST_COMPLETED, wait
        from concurrent.futures.process import BrokenProcessPool

        waiting = set(futures)
        while waiting:
            running = {self.tasks[future].running: future for future in waiting}
            done, _ = wait(running, return_when=FIRST_COMPLETED)
            if any(isinstance(finished.exception(), BrokenProcessPool) for finished in done):
                self._recover()
            for future in list(waiting):
                task = self.tasks[future]
                if not future.done() and task.running.done() and \
                        not isinstance(task.running.exception(), BrokenProcessPool):
                    _settle(future, task.running.exception() or task.running.result())
                if future.done():
                    waiting.discard(future)
                    yield future

    def _recover(self):
        """After a worker died: a new pool for the tasks that were waiting, each running one again alone."""
        from concurrent.futures.process import BrokenProcessPool

        self.pool.shutdown(wait=True)       # once it is down, every task it broke says so
        self.pool = self._new_pool()
        broken = [(future, task) for future, task in self.tasks.items()
                  if not future.done() and isinstance(task.running.exception(), BrokenProcessPool)]
        for _, task in broken:
            if not task.mark.exists():
                self._start(task)
        for future, task in broken:
            if task.mark.exists():
                task.mark.unlink()
                _settle(future, _alone(task.fn, task.args))

    def close(self):
        self.pool.shutdown(cancel_futures=True)
        shutil.rmtree(self.marks, ignore_errors=True)


def why_died(exc):
    """The error of a task whose process died: how, as :class:`_Processes` or Dask tells."""
    if isinstance(exc, _WorkerDied):
        return str(exc)
    return "its worker process died, on as many Dask workers as Dask allows (their logs say why)"


def _start_worker(parent, jobs):
    """In a worker, as it starts: end it with its batch (:func:`_end_with`), and give its BLAS one ``jobs``-th of
    the cores.  The workers are forked with the batch's BLAS, whose threads (one per core, spinning while they
    wait for work) would make the workers wait on each other's: 24 studies on two workers took 13.4 s with them,
    9.7 s without (``benchmarks.studies``' batch, medians of 3).  voxrender's matrix products are small (points
    by a 3 x 3 matrix) and gain nothing from them.
    """
    from threadpoolctl import threadpool_limits

    threadpool_limits(max(1, (os.cpu_count() or 1) // jobs), user_api="blas")
    _end_with(parent)


def _end_with(parent):
    """In a worker: end it once ``parent``, its batch, has ended.  A batch killed outright cannot end its workers,
    which would otherwise wait for work for ever, or go on writing beside the batch that is run next.
    """
    import threading

    def watch():
        while os.getppid() == parent:
            time.sleep(0.5)
        os._exit(1)

    threading.Thread(target=watch, name="voxrender-end-with-batch", daemon=True).start()


def _marked(mark, fn, *args):
    """``fn(*args)`` in a worker, with ``mark`` there while it runs (see :class:`_Processes`)."""
    Path(mark).touch()
    try:
        return fn(*args)
    finally:
        Path(mark).unlink()


def _alone(fn, args):
    """``fn(*args)`` in a process of its own: its result, or a :class:`_WorkerDied` saying how the process ended."""
    import multiprocessing
    import signal

    receiving, sending = multiprocessing.Pipe(duplex=False)
    process = multiprocessing.Process(target=_send_result, args=(sending, fn, args), daemon=True)
    process.start()
    sending.close()
    try:
        return receiving.recv()
    except EOFError:                    # it died before it could send
        process.join()
        code = process.exitcode
        how = f"killed by {signal.Signals(-code).name}" if code < 0 else f"exit status {code}"
        return _WorkerDied(f"its worker process died ({how})")
    finally:
        receiving.close()
        process.join()


def _send_result(connection, fn, args):
    try:
        result = fn(*args)
    except Exception as exc:            # the tasks report their own errors; this is for the unforeseen
        result = exc
    connection.send(result)


def _settle(future, result):
    """Give ``future`` the task's result, or its exception when the task raised one."""
    if isinstance(result, BaseException):
        future.set_exception(result)
    else:
        future.set_result(result)


class _Dask:
    def __init__(self, scheduler, jobs):
        try:
            from distributed import Client, LocalCluster
        except ImportError:
            raise InputError("a Dask scheduler needs Dask: pip install 'voxrender[distributed]'",
                             parameter="scheduler") from None
        if scheduler == "local":
            self.cluster = LocalCluster(n_workers=jobs, threads_per_worker=1, processes=True,
                                        dashboard_address=None)
            self.client = Client(self.cluster)
        else:
            self.cluster = None
            try:
                self.client = Client(scheduler, timeout="10s")
            except OSError as exc:
                raise InputError(f"cannot reach the Dask scheduler at {scheduler}: {exc}",
                                 parameter="scheduler") from None

    @property
    def died(self):
        from distributed import KilledWorker  # once the workers running the task died as often as Dask allows

        return (KilledWorker,)

    def submit(self, fn, *args):
        return self.client.submit(fn, *args, pure=False)

    def as_completed(self, futures):
        from distributed import as_completed

        return as_completed(futures)

    def close(self):
        self.client.close()
        if self.cluster is not None:
            self.cluster.close()


def executor(jobs, scheduler=None):
    """What runs tasks: this process (``jobs`` 1), worker processes, or a Dask cluster (``scheduler``); each with
    ``submit(fn, *args)``, ``as_completed(futures)`` and ``close()``.
    """
    if scheduler:
        return _Dask(scheduler, jobs)
    return _Inline() if jobs <= 1 else _Processes(jobs)

