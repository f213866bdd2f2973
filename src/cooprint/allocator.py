"""The C allocator set for what a command does: glibc's malloc, two policies.

* :func:`lean` (``slice``, ``run``, ``chunk``: cutting and slicing meshes): every block above
  1 MiB comes from the OS and goes back when freed. glibc would otherwise raise its mmap
  threshold after the first large free and keep later freed arrays in its heap (30 MB more
  resident memory after loading a 200k-triangle STL). Below that size, the heap's free top is
  kept up to 256 MiB instead of being given back whenever 128 KiB of it is free, and the heap
  grows 16 MiB at a time: the slicer makes and drops many blocks of tens of KiB for every
  layer, and each time the top was trimmed their pages were faulted in and zeroed again. On the
  1.5 M-face large part of the benchmark that was 4.3 s of system time against 16.2 s of user
  time; 1.3 s with the trim and pad below, the same user time, peak memory +4%. The threshold
  was glibc's initial 128 KiB until the large part's layers (points, segment groups of a few
  hundred KiB) showed what it cost: 245k page faults and 0.7-1.0 s of system time; with 1 MiB,
  91k and 0.4-0.7 s, and the same peak memory there and on benchy (4 MiB: benchy +7 MB).
* :func:`heap` (``simulate``, ``view``, ``validate``): every array from the heap, kept there when
  freed, for the next one (the simulator makes and drops arrays of millions of samples stage
  after stage; each fresh page from the OS costs a fault and zeroing: nefertiti 200k -> 145k
  page faults, 0.3-0.9 s less), and no transparent huge pages for numpy: on a kernel that
  defragments memory for them when asked (``defrag`` ``madvise``, the common default) each first
  touch of 2 MB of a large array waits for compaction and zeroes the whole page. The
  simulator's heap of ~1 GB grows page by page, so the 4 KB pages cost less in all: nefertiti's
  2-robot plan 4.3-4.7 s CPU (user + sys) instead of 5.8-6.3 s, same findings. One heap for all
  threads: 10% fewer page faults, 950 MB at peak instead of 1.07 GB.

Only the ``cooprint`` command sets them, once, before the work (the worker processes it forks
inherit the setting); a program using cooprint as a library keeps its own allocator. On a C
library without ``mallopt`` (musl, macOS) they do nothing and return False.
"""

from __future__ import annotations

import ctypes
import ctypes.util

#: mallopt's parameters (glibc's malloc.h).
M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD, M_MMAP_MAX, M_ARENA_MAX = -1, -2, -3, -4, -8
#: :func:`lean`: blocks above this size come from the OS and go back to it, bytes (held fixed).
LEAN_MMAP_THRESHOLD = 1 << 20
#: :func:`lean`: free memory at the heap's top kept rather than given back, bytes.
LEAN_TRIM_THRESHOLD = 256 << 20
#: :func:`lean`: extra bytes asked of the OS whenever the heap grows.
LEAN_TOP_PAD = 16 << 20


def _mallopt(settings: tuple[tuple[int, int], ...]) -> bool:
    """Apply ``(parameter, value)`` pairs; True if the C library took them all."""
    try:
        mallopt = ctypes.CDLL(ctypes.util.find_library("c") or None).mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all([mallopt(param, value) == 1 for param, value in settings])


def lean() -> bool:
    """Large blocks from the OS and back, the heap's top kept (module docstring)."""
    return _mallopt(((M_MMAP_THRESHOLD, LEAN_MMAP_THRESHOLD), (M_TRIM_THRESHOLD, LEAN_TRIM_THRESHOLD),
                     (M_TOP_PAD, LEAN_TOP_PAD)))


def heap() -> bool:
    """Every block from one heap, never given back; no huge pages for numpy (module docstring)."""
    import numpy as np

    core = getattr(np, "_core", None) or getattr(np, "core", None)  # numpy 2, numpy 1
    no_huge_pages = getattr(getattr(core, "multiarray", None), "_set_madvise_hugepage", None)
    if no_huge_pages is not None:
        no_huge_pages(False)
    # M_ARENA_MAX = 1: the checks' second thread allocates from the same heap (an arena of its
    # own is made of 64 MB maps given back when freed: faulted in again; 115 MB more at peak)
    return _mallopt(((M_MMAP_MAX, 0), (M_TRIM_THRESHOLD, (1 << 31) - 1), (M_ARENA_MAX, 1)))
