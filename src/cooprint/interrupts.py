"""Ctrl-C (SIGINT) where it can do no harm.

The command line turns Ctrl-C into exit code 130 and one line (:mod:`cooprint.cli`); the atomic
writers remove their temporary files on the way out (:mod:`cooprint.io.bundle`); the slicer
stops its worker processes (:mod:`cooprint.executors`). Three kinds of code must not be cut
in half, and hold a Ctrl-C until they are done, then raise it:

* :func:`deferred_sigint`: a sequence of renames (swapping a bundle in), a clean-up;
* :func:`held_imports`: importing the compiled libraries. A ``KeyboardInterrupt`` raised while
  an extension module initialises aborts the process (manifold3d's nanobind bindings: "Fatal
  Python error: Aborted"); one raised just after, when importlib drops the half-imported
  module, crashes it (nanobind's module cannot be freed: a segmentation fault in
  ``module_dealloc``, found under gdb); and trimesh's optional imports catch
  ``BaseException``, so a Ctrl-C during them is swallowed and the command runs on. Measured:
  7 of 160 interrupts of `slice` and `run` in their first second ended so before the imports
  were held. These imports run with SIGINT *blocked* (:func:`blocked_sigint`): no handler
  runs, no system call is interrupted, the signal waits in the kernel and is delivered when
  the import is done; the modules they made are kept alive;
* :func:`hold_compiles`: numba compiling a kernel (or loading it from its cache), SIGINT
  blocked the same way while numba holds its compiler lock.

Blocking works for the thread that blocks; a signal sent to the process goes to any thread that
does not block it. Threads inherit the mask of the thread that starts them, so the threads
cooprint starts (the progress bars, the process pool's) and those the libraries start while
they are imported are started with SIGINT blocked: Ctrl-C always reaches the main thread.
"""

from __future__ import annotations

import importlib.abc
import signal
import sys
import threading
from contextlib import contextmanager
from typing import Any, Iterator, Sequence

#: Top-level packages whose import holds Ctrl-C: compiled extensions, and trimesh (which
#: swallows it). Pure-Python packages are interrupted like any other code.
HELD_PACKAGES = ("numpy", "scipy", "trimesh", "manifold3d", "numba", "llvmlite", "PIL", "networkx",
                 "imageio_ffmpeg", "matplotlib", "shapely", "rtree")


@contextmanager
def blocked_sigint() -> Iterator[None]:
    """SIGINT blocked in this thread for the block (threads and processes started in it keep
    it blocked); one that arrives meanwhile is delivered when the block ends."""
    if not hasattr(signal, "pthread_sigmask"):
        yield
        return
    old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


@contextmanager
def deferred_sigint() -> Iterator[None]:
    """Hold Ctrl-C until the block is done, then raise it (through the handler there was, so
    that nested blocks raise once, at the outermost). Only the main thread receives signals;
    elsewhere this does nothing."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    caught: list[int] = []
    try:
        previous = signal.signal(signal.SIGINT, lambda signum, frame: caught.append(signum))
    except ValueError:  # not the main interpreter
        yield
        return
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        if caught:
            if callable(previous):
                previous(signal.SIGINT, None)
            elif previous == signal.SIG_DFL:
                raise KeyboardInterrupt


class _CompileHold:
    """SIGINT blocked in the main thread while numba holds its compiler lock (compiling a kernel
    or loading it from its cache), delivered when it lets go (:func:`hold_compiles`). A
    ``KeyboardInterrupt`` raised inside numba's compiler leaves the half-made function in its
    tables; a Ctrl-C during a kernel's first call, under load, ended ``run`` and ``slice`` with a
    segmentation fault instead of exit 130 (twice in about six runs of the test suite)."""

    def __init__(self) -> None:
        self.depth = 0
        self.old: Any = None

    def on_start(self, event: Any) -> None:
        if threading.current_thread() is threading.main_thread():
            if self.depth == 0:
                self.old = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
            self.depth += 1

    def on_end(self, event: Any) -> None:
        if threading.current_thread() is threading.main_thread() and self.depth:
            self.depth -= 1
            if self.depth == 0:
                signal.pthread_sigmask(signal.SIG_SETMASK, self.old)


_COMPILES: list[Any] = []


def hold_compiles() -> None:
    """Hold Ctrl-C while numba compiles (:class:`_CompileHold`, as a numba event listener); once
    per process. The modules that define kernels call it when they are imported (numba is
    loaded by then)."""
    if _COMPILES or not hasattr(signal, "pthread_sigmask"):
        return
    from numba.core import event

    class Hold(_CompileHold, event.Listener):
        pass

    hold = Hold()
    event.register("numba:compiler_lock", hold)
    _COMPILES.append(hold)


#: Modules made by a held loader, kept alive: the Ctrl-C held during an import is raised when
#: it ends, and importlib then drops the new module; an extension module must not be freed
#: (nanobind's crash in ``module_dealloc``, found under gdb). The process is ending anyway.
_KEPT: list[Any] = []


class _HeldLoader(importlib.abc.Loader):
    """A module loader whose module creation and execution run with SIGINT blocked;
    everything else is the wrapped loader's."""

    def __init__(self, loader: Any):
        self._loader = loader

    def create_module(self, spec: Any) -> Any:
        with blocked_sigint():
            module = self._loader.create_module(spec)
            if module is not None:
                _KEPT.append(module)
        return module

    def exec_module(self, module: Any) -> None:
        with blocked_sigint():
            self._loader.exec_module(module)

    def __getattr__(self, name: str) -> Any:
        return getattr(self._loader, name)


class _HoldImports(importlib.abc.MetaPathFinder):
    """Finds nothing itself: asks the other finders and wraps the loader of the packages held."""

    def __init__(self, roots: Sequence[str]):
        self.roots = frozenset(roots)

    def find_spec(self, name: str, path: Any, target: Any = None) -> Any:
        if name.partition(".")[0] not in self.roots:
            return None
        for finder in sys.meta_path:
            find = getattr(finder, "find_spec", None)
            if finder is self or find is None:
                continue
            spec = find(name, path, target)
            if spec is not None:
                if spec.loader is not None and hasattr(spec.loader, "exec_module"):
                    spec.loader = _HeldLoader(spec.loader)
                return spec
        return None


class _Sticky:
    """Whether a Ctrl-C came while :func:`sticky_sigint` was in force."""

    caught = False


def _sticky_handler(signum: int, frame: Any) -> None:
    _Sticky.caught = True
    raise KeyboardInterrupt


@contextmanager
def sticky_sigint() -> Iterator[None]:
    """Ctrl-C raises ``KeyboardInterrupt`` as usual and is also remembered, so that
    :func:`check_interrupt` raises it again if some code swallowed it. Python itself does:
    an exception in a weakref callback (importlib's module locks) is printed as "Exception
    ignored" and dropped (here: dropped without the print, ``sys.unraisablehook``); so do
    libraries with ``except BaseException`` or a bare ``except``.
    Measured before: 2 of 200 interrupts of `slice` at 0.3-0.6 s ran on to exit code 0."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    try:
        previous = signal.signal(signal.SIGINT, _sticky_handler)
    except ValueError:
        yield
        return
    _Sticky.caught = False
    hook = sys.unraisablehook

    def quiet_about_interrupts(unraisable: Any) -> None:
        if isinstance(unraisable.exc_value, KeyboardInterrupt):  # remembered above; no "Exception ignored"
            _Sticky.caught = True
            return
        hook(unraisable)

    sys.unraisablehook = quiet_about_interrupts
    try:
        yield
    finally:
        signal.signal(signal.SIGINT, previous)
        sys.unraisablehook = hook
        _Sticky.caught = False


def check_interrupt() -> None:
    """Raise ``KeyboardInterrupt`` if a Ctrl-C came (and was swallowed): the stages call it as
    they advance (the CLI's progress callback)."""
    if _Sticky.caught:
        raise KeyboardInterrupt


def interrupted(exc: BaseException) -> bool:
    """Whether ``exc`` is a Ctrl-C, or was caused by one: Python 3.11 wraps an exception raised
    in ``__set_name__`` (a Ctrl-C while a dataclass is made) in a ``RuntimeError``."""
    seen = set()
    while exc is not None and id(exc) not in seen:
        if isinstance(exc, KeyboardInterrupt):
            return True
        seen.add(id(exc))
        exc = exc.__cause__ or exc.__context__  # type: ignore[assignment]
    return False


@contextmanager
def held_imports(roots: Sequence[str] = HELD_PACKAGES) -> Iterator[None]:
    """While the block runs, importing any module of ``roots`` holds Ctrl-C until it is done."""
    finder = _HoldImports(roots)
    sys.meta_path.insert(0, finder)
    try:
        yield
    finally:
        try:
            sys.meta_path.remove(finder)
        except ValueError:
            pass
