"""What every module holding numba kernels sets up when it is imported (:func:`setup`, once per
process; worker processes forked later inherit it).

* A Ctrl-C waits for numba to finish compiling or loading a kernel
  (:func:`cooprint.interrupts.hold_compiles`).
* numba's timing of the LLVM lock is switched off (:func:`_untimed_llvm_lock`). numba registers
  two Python callbacks that llvmlite runs around *every* call into LLVM, to time the lock for
  its compile events; loading one kernel from numba's on-disk cache makes a few hundred such
  calls (the symbols of the kernel's module, one by one). Measured on benchy's last block of
  layers (a worker's first block loads 27 kernels): 0.23 s of CPU to load them with the
  callbacks, 0.17 s without. Every ``cooprint slice`` worker and every command's first kernel
  pays that load, so on a small part it is a good part of the command's time. The callbacks
  only feed the ``llvm_lock`` timer of numba's compile metadata, which cooprint never reads.
"""

from __future__ import annotations

from cooprint.interrupts import hold_compiles

_DONE: list[bool] = []


def setup() -> None:
    """Prepare numba for cooprint's kernels (see the module's text); once per process."""
    if _DONE:
        return
    _DONE.append(True)
    hold_compiles()
    _untimed_llvm_lock()


def _untimed_llvm_lock() -> None:
    """Unregister numba's callbacks on llvmlite's lock (llvmlite's public
    ``unregister_lock_callback``; the registered pairs are read from the lock, which llvmlite
    does not document: with another layout nothing is removed, and the kernels only load as
    slowly as before)."""
    import importlib

    from llvmlite.binding import ffi

    importlib.import_module("numba.core.base")  # registers the callbacks on import

    pairs = getattr(getattr(getattr(ffi, "lib", None), "_lock", None), "_cblist", None)
    if not isinstance(pairs, list):
        return
    for acquire, release in list(pairs):
        if getattr(acquire, "__module__", "") == "numba.core.base":
            ffi.unregister_lock_callback(acquire, release)
