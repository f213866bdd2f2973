"""The allocator tuning the ``cooprint`` command applies (cooprint.allocator)."""

import platform
import subprocess
import sys

import pytest

from cooprint import allocator


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")
def test_glibc_takes_the_thresholds():
    """glibc accepts every value (it refuses an mmap threshold above 32 MiB on 64-bit)."""
    assert allocator.tune() is True


@pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc", reason="glibc's mallopt")
def test_large_arrays_reuse_the_heap():
    """After tune(), the pages of freed arrays are reused: making and dropping three 16 MiB
    arrays 50 times faults their pages in once, where plain glibc gives the heap's free top back
    to the kernel each time (more than its dynamic trim threshold) and faults them in again."""
    code = (
        "import resource, sys, numpy as np\n"
        "from cooprint import allocator\n"
        "if sys.argv[1] == 'tuned': allocator.tune()\n"
        "np.ones(1 << 21)\n"
        "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
        "for _ in range(50): a, b, c = np.ones(1 << 21), np.ones(1 << 21), np.ones(1 << 21); del a, b, c\n"
        "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n")
    faults = {}
    for mode in ("plain", "tuned"):
        out = subprocess.run([sys.executable, "-c", code, mode], capture_output=True, text=True, check=True)
        faults[mode] = int(out.stdout.strip())
    assert 10 * faults["tuned"] < faults["plain"], faults
