"""Where independent tasks run: inline, in forked local processes, or on a Dask cluster (issue 15).

One interface, :class:`Executor`: ``map(fn, tasks, shared=...)`` calls ``fn(shared, task)`` for
every task and yields the results **in the order of the tasks**, with at most ``window`` tasks
submitted and not yet consumed: the memory of the results is bounded by the window, not by the
job. ``shared`` is what every task needs and no task changes (the chunk meshes of a job, a plan
to replay): it is sent to each worker once, not with every task. ``close()`` (or leaving a
``with`` block) stops the workers.

* ``inline``: in this process, one task after the other (no start-up cost, no parallelism);
* ``processes``: a pool of worker processes forked from this one, which share ``shared`` with it
  copy-on-write (nothing is pickled but the tasks and their results); one pool per ``map``;
* ``dask``: a Dask distributed cluster, an existing one (``tcp://HOST:PORT``, the address of a
  ``dask scheduler``) or a ``LocalCluster`` of ``N`` worker processes on 127.0.0.1
  (``local:N``). ``shared`` is scattered to every worker once (``broadcast``); ``fn`` and the
  tasks are pickled by reference, so each worker must have the same cooprint installed.

The results do not depend on the executor: the tasks are fixed by the caller (the slicer's
blocks of ``BLOCK`` layers, the Monte-Carlo runs and their seeds), and each task's result
depends on the task and ``shared`` alone.

Failures are one line (:class:`ExecutorError`, a :class:`~cooprint.errors.UserError`): a
scheduler that does not answer within :data:`CONNECT_TIMEOUT` seconds, a worker process that
died (Dask retries a task whose worker died, up to ``distributed.scheduler.allowed-failures``
times, before it gives up), a scheduler lost during the job. An exception raised by ``fn``
itself is re-raised as it is (a bug, with its traceback).
"""

from __future__ import annotations

import itertools
import logging
import multiprocessing
import os
import re
import signal
import sys
import threading
import uuid
from collections import deque
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from typing import Any, Callable, Iterable, Iterator

from cooprint.errors import UserError, clip
from cooprint.interrupts import blocked_sigint, deferred_sigint

#: The executors ``--executor`` names.
EXECUTORS = ("inline", "processes", "dask")
#: The executor when none is named.
DEFAULT_EXECUTOR = "processes"
#: Seconds to wait for a Dask scheduler to answer (``--scheduler tcp://...``) before giving up.
CONNECT_TIMEOUT = 5.0
#: How much longer than its own timeout cooprint waits for Dask's client to connect, s (a
#: handshake with something that is not a scheduler may never end).
CONNECT_MARGIN = 3.0
#: How long a map waits for a local cluster's workers to be up (a restarted one), s.
LOCAL_WORKERS_TIMEOUT = 30.0
#: Most workers of ``--scheduler local:N`` (and of ``processes``).
MAX_LOCAL_WORKERS = 64
#: A ``processes`` executor forks a pool only from this many tasks on: a pool costs ~0.3 s to
#: start, more than one or two blocks of layers take.
PARALLEL_TASKS = 3
#: Dask's default scheduler port (``dask scheduler`` listens there).
DASK_PORT = 8786


class ExecutorError(UserError):
    """The executor could not run the job: a scheduler that does not answer, a worker that
    died, a missing optional dependency. One line; nothing is written."""


def default_workers() -> int:
    """Local worker processes when none are asked for: one per CPU, at most 4 (the slicer's
    blocks keep 4 busy; more only add memory)."""
    return max(1, min(os.cpu_count() or 1, 4))


class Executor:
    """Runs ``fn(shared, task)`` for many tasks; see the module's doc. Subclasses set
    :attr:`name` and :attr:`slots` (tasks that run at once) and implement :meth:`_results`."""

    name = "executor"
    slots = 1

    def map(self, fn: Callable[[Any, Any], Any], tasks: Iterable[Any], shared: Any = None,
            window: int | None = None) -> Iterator[Any]:
        """``fn(shared, task)`` for each task, yielded in the order of ``tasks``. At most
        ``window`` tasks (default twice :attr:`slots`) are submitted and not yet consumed.
        Stopping the iteration early (``close()`` on the generator, an exception in the
        consumer) cancels the tasks not done."""
        window = max(1, 2 * self.slots if window is None else int(window))
        return self._results(fn, list(tasks), shared, window)

    def _results(self, fn: Callable[[Any, Any], Any], tasks: list[Any], shared: Any,
                 window: int) -> Iterator[Any]:
        raise NotImplementedError

    def close(self) -> None:
        """Stop the workers this executor started (a no-op for those it did not)."""

    def describe(self) -> str:
        """One line for messages: the kind and its workers."""
        return f"{self.name} ({self.slots} at once)"

    def __enter__(self) -> "Executor":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()


class InlineExecutor(Executor):
    """Every task in this process, one after the other."""

    name = "inline"
    slots = 1

    def _results(self, fn, tasks, shared, window):
        for task in tasks:
            yield fn(shared, task)


def _ordered(submit: Callable[[Any], Any], result: Callable[[Any], Any], tasks: list[Any],
             window: int, first: Callable[[], Any] | None = None) -> Iterator[Any]:
    """The results of ``submit(task)`` futures in the order of ``tasks``, keeping ``window``
    submitted: when the oldest is taken, the next task is submitted before waiting for it.
    ``result(future)`` waits for one; ``first()``, if given, wraps the first submissions (the
    pool forks its workers then)."""
    it = iter(tasks)
    pending: deque[Any] = deque()
    if first is not None:
        with first():
            pending.extend(submit(t) for t in itertools.islice(it, window))
    else:
        pending.extend(submit(t) for t in itertools.islice(it, window))
    while pending:
        head = pending.popleft()
        for t in itertools.islice(it, 1):
            pending.append(submit(t))
        yield result(head)


#: What the forked workers of a ``processes`` map run: ``{token: (fn, shared)}``, set in the
#: parent just before the pool forks (the children inherit it) and dropped there right after.
_FORKED: dict[int, tuple[Callable[[Any, Any], Any], Any]] = {}
_TOKENS = itertools.count()


def _run_forked(token: int, task: Any) -> Any:
    fn, shared = _FORKED[token]
    return fn(shared, task)


class ProcessExecutor(Executor):
    """A pool of worker processes forked from this one for each :meth:`map` (Linux, macOS):
    ``shared`` is inherited copy-on-write, the tasks and results are pickled. Fewer than
    ``min_tasks`` tasks, or one worker, run inline."""

    name = "processes"

    def __init__(self, workers: int | None = None, min_tasks: int = PARALLEL_TASKS):
        self.slots = default_workers() if workers is None else max(1, int(workers))
        self.min_tasks = min_tasks

    def _results(self, fn, tasks, shared, window):
        n = min(self.slots, len(tasks))
        if n <= 1 or len(tasks) < self.min_tasks:
            yield from InlineExecutor()._results(fn, tasks, shared, window)
            return
        token = next(_TOKENS)
        _FORKED[token] = (fn, shared)
        pool = None
        try:
            with blocked_sigint():  # workers are forked here: none sees a Ctrl-C before it ignores it
                pool = ProcessPoolExecutor(n, mp_context=multiprocessing.get_context("fork"),
                                           initializer=_worker_init, initargs=(os.getpid(),))

            def submit(task: Any) -> Any:
                return pool.submit(_run_forked, token, task)

            def forked() -> Any:  # the pool forks all its workers at the first submit (fork context)
                return _Forking(token)

            try:
                yield from _ordered(submit, lambda f: f.result(), tasks, max(window, n), forked)
            except BrokenProcessPool:
                raise ExecutorError(f"a worker process died during the job ({n} processes; out of memory? "
                                    "see the system log); nothing was written") from None
        except BaseException:  # Ctrl-C, an error, or the consumer stopped early (GeneratorExit)
            if pool is not None:
                stop_pool(pool)
                pool = None
            raise
        finally:
            _FORKED.pop(token, None)
            if pool is not None:
                pool.shutdown(wait=True)


class _Forking:
    """Context of the first submissions of a pool: SIGINT blocked while the workers are
    forked (:func:`~cooprint.interrupts.blocked_sigint`); after it the parent lets go of what
    it handed them (:data:`_FORKED`)."""

    def __init__(self, token: int):
        self.token = token
        self.block = blocked_sigint()

    def __enter__(self) -> None:
        self.block.__enter__()

    def __exit__(self, *exc: Any) -> None:
        self.block.__exit__(*exc)
        _FORKED.pop(self.token, None)


#: ``prctl`` option: the signal a process gets when its parent dies (Linux).
_PR_SET_PDEATHSIG = 1


def _worker_init(parent: int) -> None:
    """Set up a worker process: Ctrl-C is the parent's to handle (it stops the pool), and the
    worker dies with its parent (Linux ``PR_SET_PDEATHSIG``, best effort), so that no worker
    outlives a parent that was killed."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    if hasattr(signal, "pthread_sigmask"):
        signal.pthread_sigmask(signal.SIG_UNBLOCK, {signal.SIGINT})
    if sys.platform.startswith("linux"):
        try:
            import ctypes

            ctypes.CDLL(None, use_errno=True).prctl(_PR_SET_PDEATHSIG, int(signal.SIGTERM), 0, 0, 0)
        except (OSError, AttributeError):
            pass
    if os.getppid() != parent:  # the parent died before the death signal was armed
        os._exit(1)


def stop_pool(pool: ProcessPoolExecutor) -> None:
    """Stop a pool now: cancel what has not started, terminate the workers (a task under way
    is of no use any more), wait for them and for the pool's thread. Ctrl-C is held meanwhile."""
    with deferred_sigint():
        # the pool's own list of its processes (Python < 3.14 has no public way to terminate
        # them), taken before shutdown() forgets it
        procs = list((getattr(pool, "_processes", None) or {}).values())
        # ... and its thread: it reaps the workers too once they are gone, and shutdown(wait=True)
        # after shutdown(wait=False) no longer waits for it; unjoined, a worker it had reaped but
        # not yet marked dead still looked alive here after this returned (1 run in ~10)
        manager = getattr(pool, "_executor_manager_thread", None)
        results = getattr(pool, "_result_queue", None)
        pool.shutdown(wait=False, cancel_futures=True)
        for proc in procs:
            if proc.is_alive():
                proc.terminate()
        for proc in procs:
            proc.join(5)
            if proc.is_alive():
                proc.kill()
                proc.join(1)
        # a worker stopped while it sent a result leaves the thread waiting for the rest of it
        # (forever: the parent holds the pipe's sending end too, and at exit Python waits for
        # that thread); with every worker gone, closing that end ends the wait (end of file)
        writer = getattr(results, "_writer", None)
        if writer is not None and not any(proc.is_alive() for proc in procs):
            writer.close()
        pool.shutdown(wait=True)
        if manager is not None:
            manager.join(5)


def _run_dask(fn: Callable[[Any, Any], Any], shared: Any, task: Any) -> Any:
    """A Dask task: ``shared`` is the worker's copy of the scattered data."""
    return fn(shared, task)


class DaskExecutor(Executor):
    """A Dask distributed cluster: ``address`` ``tcp://HOST:PORT`` (a running ``dask
    scheduler``) or ``local:N`` (a ``LocalCluster`` of N single-threaded worker processes on
    127.0.0.1, started here and stopped by :meth:`close`).

    The connection to a running scheduler is made here, so that an unreachable one is one line
    (:class:`ExecutorError`) after :data:`CONNECT_TIMEOUT` seconds, before any work; a local
    cluster is started here and connected to when the first tasks come (it starts while
    cooprint reads and cuts the part). Dask's own
    log messages are silenced while the executor is open (its failures reach the user as
    :class:`ExecutorError`).

    A local cluster runs in a helper process of its own session (:func:`_serve_local`): a
    Ctrl-C at the terminal goes to this process alone, which closes the cluster (Dask's worker
    processes, reached by it, would each print a traceback), and the helper and its workers
    end when this process ends, however it ends."""

    name = "dask"

    def __init__(self, address: str, connect_timeout: float | None = None):
        self.address = address
        connect_timeout = CONNECT_TIMEOUT if connect_timeout is None else connect_timeout
        kind, where = parse_scheduler(address)
        try:
            with blocked_sigint():
                import distributed
        except ImportError:
            raise ExecutorError("--executor dask needs Dask: pip install 'cooprint[dask]' (dask and distributed)") \
                from None
        self._distributed = distributed
        self._logs = _quiet_dask_logs()
        self.helper: LocalHelper | None = None
        self.client = None
        self._timeout = connect_timeout
        if kind == "local":  # started now, connected to when the first tasks come: it starts while the part is cut
            try:
                self.helper = LocalHelper(int(where))
            except BaseException:
                self.close()
                raise
            self.slots = int(where)
            return
        self._connect(where)
        self.slots = max(1, sum(self.client.nthreads().values()))

    def _connect(self, where: str) -> None:
        """Connect the client to the scheduler at ``where``; one line if none answers.

        The client is made on a thread of its own (started with SIGINT blocked, so that the
        client's threads leave Ctrl-C to the main thread), which the main thread waits for at
        most the timeout and a margin: something at that address that is not a Dask scheduler
        (a web server, a port that accepts and stays silent) can keep Dask's handshake waiting
        for ever, or fail it in any way; either is one line, and Ctrl-C works meanwhile."""
        made: dict[str, Any] = {}

        def connect() -> None:
            try:
                made["client"] = self._distributed.Client(where, set_as_default=False, timeout=self._timeout)
            except BaseException as exc:  # reported by the main thread
                made["error"] = exc

        with blocked_sigint():
            thread = threading.Thread(target=connect, name="cooprint-dask-connect", daemon=True)
            thread.start()
        thread.join(self._timeout + CONNECT_MARGIN)
        if "client" in made:
            self.client = made["client"]
            return
        self.close()
        exc = made.get("error")
        what = (f"no Dask scheduler answered within {self._timeout:g} s (nothing listening there, or the host "
                f"cannot be resolved or reached; start one with `dask scheduler`)")
        if exc is None:
            raise ExecutorError(f"--scheduler {clip(self.address)}: something there took the connection but did "
                                f"not answer as a Dask scheduler within {self._timeout + CONNECT_MARGIN:g} s (the "
                                "scheduler's port, 8786 by default, not its dashboard's?)") from None
        if isinstance(exc, OSError):
            raise ExecutorError(f"--scheduler {clip(self.address)}: {what}: {_first_line(exc)}") from None
        if isinstance(exc, Exception):
            raise ExecutorError(f"--scheduler {clip(self.address)}: not a Dask scheduler there (its answer could "
                                f"not be read: {type(exc).__name__}: {_first_line(exc)})") from None
        raise exc

    @property
    def scheduler_address(self) -> str:
        """The scheduler's address (a local cluster's, once it is up)."""
        return self._ready().scheduler.address

    def _ready(self) -> Any:
        """The connected client (a local cluster's, once its helper has given its address)."""
        if self.client is None:
            if self.helper is None:
                raise ExecutorError(f"dask at {clip(self.address)}: the executor is closed")
            try:
                address = self.helper.wait()
            except BaseException:
                self.close()
                raise
            self._connect(address)
        return self.client

    def describe(self) -> str:
        return f"dask at {self.address} ({self.slots} worker threads)"

    def _results(self, fn, tasks, shared, window):
        distributed = self._distributed
        client = self._ready()
        pending: set[Any] = set()  # submitted, result not taken: cancelled if the map stops early
        try:
            if self.helper is not None:  # a local cluster: all its workers up (one its nanny restarts after
                # a crash included) before the broadcast, or the copy lives on fewer workers than it may need
                try:
                    client.wait_for_workers(self.helper.n, timeout=LOCAL_WORKERS_TIMEOUT)
                except TimeoutError:
                    pass  # fewer workers: the tasks run on those there are
            # once per map: every worker gets its copy now, not one per task
            [shared_f] = client.scatter([shared], broadcast=True, hash=False)
            pending.add(shared_f)
            # keys are the cluster's, shared by its clients: this job's own
            prefix = f"cooprint-{getattr(fn, '__name__', 'task')}-{uuid.uuid4().hex[:16]}"

            def submit(task: Any) -> Any:
                f = client.submit(_run_dask, fn, shared_f, task, pure=False, key=f"{prefix}-{next(_TOKENS)}")
                pending.add(f)
                return f

            def result(f: Any) -> Any:
                out = f.result()
                pending.discard(f)  # and the future goes: the cluster forgets the result
                return out

            yield from _ordered(submit, result, tasks, window)
        except distributed.KilledWorker as exc:
            raise ExecutorError(f"dask at {clip(self.address)}: a task killed every worker that ran it (out of "
                                f"memory? see the workers' logs): {_first_line(exc)}") from None
        except distributed.CancelledError as exc:
            raise ExecutorError(f"dask at {clip(self.address)}: the job's tasks were cancelled (the scheduler was "
                                f"lost or restarted): {_first_line(exc)}") from None
        except (distributed.comm.CommClosedError, OSError, TimeoutError) as exc:
            raise ExecutorError(f"dask at {clip(self.address)}: lost the connection to the scheduler during the "
                                f"job: {_first_line(exc)}") from None
        finally:
            with deferred_sigint():
                if pending:
                    try:
                        client.cancel(list(pending))
                    except Exception:  # the connection is gone: nothing left to cancel
                        pass
                pending.clear()

    def close(self) -> None:
        with deferred_sigint():
            client, helper = self.client, self.helper
            self.client = self.helper = None
            try:
                if client is not None:
                    client.close(timeout=CONNECT_TIMEOUT)
            except Exception:  # a scheduler gone: nothing to close
                pass
            finally:
                if helper is not None:
                    helper.close()
                logs, self._logs = getattr(self, "_logs", None), None
                if logs is not None:
                    logs()


#: Seconds a local cluster may take to start (its workers are new interpreters importing cooprint).
LOCAL_START_TIMEOUT = 120.0


class LocalHelper:
    """A helper process serving a ``LocalCluster`` of ``n`` worker processes on 127.0.0.1
    (:func:`_serve_local`), in a session of its own, started at once; :meth:`wait` gives its
    scheduler's address when it is up."""

    def __init__(self, n: int):
        import subprocess
        import tempfile

        self.n = n
        self.address: str | None = None
        self.log = tempfile.TemporaryFile()
        code = f"from cooprint.executors import _serve_local; _serve_local({int(n)}, {os.getpid()})"
        self.proc: Any = subprocess.Popen([sys.executable, "-c", code], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                                          stderr=self.log, start_new_session=True)

    def wait(self, timeout: float = LOCAL_START_TIMEOUT) -> str:
        """The scheduler's address, once the cluster is up (at most ``timeout`` s from now)."""
        import select

        if self.address is None:
            assert self.proc is not None and self.proc.stdout is not None
            ready, _, _ = select.select([self.proc.stdout], [], [], timeout)
            line = self.proc.stdout.readline().decode("ascii", "replace").strip() if ready else ""
            if not line.startswith("tcp://"):
                why = self._last_log_line() or (f"no answer within {timeout:g} s" if not ready else "it stopped")
                self.close()
                raise ExecutorError(f"--scheduler local:{self.n}: the local Dask cluster did not start: {why}")
            self.address = line
        return self.address

    def _last_log_line(self) -> str:
        self.log.seek(0)
        lines = [ln for ln in self.log.read().decode("utf-8", "replace").splitlines() if ln.strip()]
        return clip(lines[-1], 200) if lines else ""

    def close(self) -> None:
        """Ask the helper to stop its cluster (its standard input closes) and wait for it; kill
        it if it does not stop within :data:`CONNECT_TIMEOUT` s (its workers follow it)."""
        import subprocess

        proc, self.proc = getattr(self, "proc", None), None
        if proc is None:
            return
        with deferred_sigint():
            try:
                if proc.stdin is not None:
                    proc.stdin.close()
                proc.wait(CONNECT_TIMEOUT)
            except (OSError, subprocess.TimeoutExpired):
                proc.kill()
                proc.wait()
            finally:
                if proc.stdout is not None:
                    proc.stdout.close()
                self.log.close()


def _serve_local(n: int, parent: int) -> None:
    """The helper process of :class:`LocalHelper`: start a ``LocalCluster`` of ``n``
    single-threaded worker processes on 127.0.0.1, print its scheduler's address, and close it
    when the standard input closes (the parent closed it, or died). It dies with its parent
    (``PR_SET_PDEATHSIG``) if it cannot close in time; Dask's workers end with their nanny."""
    _worker_init(parent)  # SIGINT ignored (inherited by the workers), death signal armed
    import dask
    import distributed

    logging.getLogger("distributed").setLevel(logging.CRITICAL + 1)
    # on this machine the workers share its cores with cooprint: none of Dask's sampling of
    # their threads' stacks (every 10 ms) and of their memory (every 100 ms; no memory limit, as
    # the `processes` executor has none), less often its system monitor
    dask.config.set({"distributed.worker.profile.enabled": False, "distributed.admin.system-monitor.interval": "2s"})
    with distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  scheduler_port=0, dashboard_address=":0", silence_logs=logging.CRITICAL,
                                  memory_limit=0) as cluster:
        print(cluster.scheduler_address, flush=True)
        sys.stdin.buffer.read()


def _first_line(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()
    return clip(text[0] if text else type(exc).__name__, 160)


def _quiet_dask_logs() -> Callable[[], None]:
    """Silence the ``distributed`` loggers (a worker's death, a retried task are logged by the
    scheduler and the nanny in this process); return what restores them."""
    names = ("distributed", "distributed.nanny", "distributed.scheduler", "distributed.core", "distributed.worker",
             "distributed.client", "distributed.deploy", "distributed.comm", "tornado")
    before = {n: logging.getLogger(n).level for n in names}
    for n in names:
        logging.getLogger(n).setLevel(logging.CRITICAL + 1)

    def restore() -> None:
        for n, level in before.items():
            logging.getLogger(n).setLevel(level)

    return restore


_TCP = re.compile(r"^tcp://(?P<host>\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):(?P<port>[0-9]{1,5})$")
_LOCAL = re.compile(r"^local:(?P<n>[0-9]{1,6})$")


def parse_scheduler(text: str) -> tuple[str, str]:
    """``--scheduler`` checked: ``("tcp", "tcp://HOST:PORT")`` or ``("local", "N")`` (N from 1 to
    :data:`MAX_LOCAL_WORKERS`); anything else is a one-line :class:`ExecutorError`."""
    m = _LOCAL.match(text)
    if m:
        n = int(m["n"])
        if not 1 <= n <= MAX_LOCAL_WORKERS:
            raise ExecutorError(f"--scheduler {clip(text)}: expected local:N with N from 1 to {MAX_LOCAL_WORKERS} "
                                "worker processes")
        return "local", str(n)
    m = _TCP.match(text)
    if m:
        port = int(m["port"])
        if not 1 <= port <= 65535:
            raise ExecutorError(f"--scheduler {clip(text)}: port {port} out of range (1 to 65535)")
        return "tcp", text
    raise ExecutorError(f"--scheduler {clip(text)}: expected tcp://HOST:PORT (a `dask scheduler`, port {DASK_PORT} "
                        "by default) or local:N (N worker processes on this machine)")


def check_executor_options(executor: str | None, scheduler: str | None) -> tuple[str, str | None]:
    """``--executor NAME --scheduler ADDRESS`` checked without starting anything:
    ``(name, address)``; ``--scheduler`` only with ``--executor dask``; ``dask`` without
    ``--scheduler`` is a local cluster of :func:`default_workers` processes."""
    name = DEFAULT_EXECUTOR if executor is None else executor
    if name not in EXECUTORS:
        raise ExecutorError(f"--executor {clip(name)}: expected one of {', '.join(EXECUTORS)}")
    if scheduler is not None:
        if name != "dask":
            raise ExecutorError(f"--scheduler {clip(scheduler)} is the address of a Dask cluster: it needs "
                                f"--executor dask (not {name})")
        parse_scheduler(scheduler)
    elif name == "dask":
        scheduler = f"local:{default_workers()}"
    return name, scheduler


def make_executor(executor: str | None = None, scheduler: str | None = None) -> Executor:
    """The executor of ``--executor`` / ``--scheduler`` (:func:`check_executor_options`),
    started: a Dask cluster is connected to (or started) here, before any work."""
    name, address = check_executor_options(executor, scheduler)
    if name == "inline":
        return InlineExecutor()
    if name == "processes":
        return ProcessExecutor()
    assert address is not None
    return DaskExecutor(address)


__all__ = ["CONNECT_TIMEOUT", "DEFAULT_EXECUTOR", "EXECUTORS", "DaskExecutor", "Executor", "ExecutorError",
           "InlineExecutor", "LocalHelper", "ProcessExecutor", "check_executor_options", "default_workers", "make_executor",
           "parse_scheduler", "stop_pool"]
