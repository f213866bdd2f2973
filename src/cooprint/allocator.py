"""The C allocator tuned for a process that makes and drops many large numpy arrays.

glibc's malloc gives every block above its mmap threshold (128 KiB at start, raised
dynamically up to 32 MiB) its own fresh pages from the kernel and returns them on free, and
trims the heap's top whenever 128 KiB of it is free. The slicer allocates and frees arrays of
a few hundred KiB to a few MiB for every layer (samples along the rings, infill segments,
search grids), so each of them paid page faults and zeroing in the kernel: on the 1.5 M-face
large part of the benchmark 4.3 s of system time against 16.2 s of user time; 1.3 s with the
settings below, the same user time, and 4% more peak memory. :func:`tune` keeps those blocks in the heap, reused from one
layer to the next.

Only the ``cooprint`` command calls it, once, before any work (the worker processes it forks
inherit the setting); a program using cooprint as a library keeps its own allocator settings.
On a C library without ``mallopt`` (musl, macOS) it does nothing.
"""

from __future__ import annotations

import ctypes
import ctypes.util

#: mallopt's parameters (glibc's malloc.h).
M_TRIM_THRESHOLD, M_TOP_PAD, M_MMAP_THRESHOLD = -1, -2, -3
#: Blocks up to this size come from the heap, bytes: glibc's largest mmap threshold on 64-bit
#: (a larger value is refused).
MMAP_THRESHOLD = 32 << 20
#: Free memory at the heap's top that is kept rather than given back to the kernel, bytes.
TRIM_THRESHOLD = 256 << 20
#: Extra bytes asked of the kernel whenever the heap grows (fewer, larger growths).
TOP_PAD = 16 << 20


def tune() -> bool:
    """Set the thresholds above; True if the C library took them."""
    try:
        libc = ctypes.CDLL(ctypes.util.find_library("c") or None)
        mallopt = libc.mallopt
    except (OSError, AttributeError):
        return False
    mallopt.argtypes, mallopt.restype = [ctypes.c_int, ctypes.c_int], ctypes.c_int
    return all(mallopt(param, value) == 1 for param, value in
               ((M_MMAP_THRESHOLD, MMAP_THRESHOLD), (M_TRIM_THRESHOLD, TRIM_THRESHOLD), (M_TOP_PAD, TOP_PAD)))
