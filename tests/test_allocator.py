"""The allocator policies the ``cooprint`` command applies (cooprint.allocator)."""

import platform
import subprocess
import sys

import pytest

from cooprint import allocator

glibc = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                           reason="glibc's mallopt")

#: Makes and drops 20 arrays of argv[2] doubles (64 KiB by default: under lean's mmap threshold,
#: from the heap) 100 times under the policy named by argv[1], and prints the page faults that
#: cost.
CHURN = (
    "import resource, sys, numpy as np\n"
    "from cooprint import allocator\n"
    "assert sys.argv[1] == 'plain' or getattr(allocator, sys.argv[1])()\n"
    "n = int(sys.argv[2])\n"
    "np.ones(n)\n"
    "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
    "for _ in range(100): a = [np.ones(n) for _ in range(20)]; del a\n"
    "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n")


def faults(policy, doubles=1 << 13):
    out = subprocess.run([sys.executable, "-c", CHURN, policy, str(doubles)], capture_output=True, text=True,
                         check=True)
    return int(out.stdout.strip())


@glibc
def test_glibc_takes_both_policies():
    assert allocator.lean() is True
    assert allocator.heap() is True


@glibc
@pytest.mark.parametrize("policy", ["lean", "heap"])
def test_freed_blocks_are_reused_not_faulted_in_again(policy):
    """Plain glibc gives the heap's free top back whenever 128 KiB of it is free, so 20 arrays
    of 64 KiB made and dropped 100 times fault their pages in again every round (about 240
    faults a round); both policies keep the heap's top and fault them in once."""
    plain, kept = faults("plain"), faults(policy)
    assert plain > 100 * 100 and plain > 20 * kept, (plain, kept)


@glibc
def test_lean_reuses_arrays_under_a_mib():
    """Arrays of 512 KiB (a large part's layer of points, a group of section segments) come
    from lean's heap and are reused: made and dropped 20 at a time 100 times, they fault their
    pages in once (from the OS each time, it was 128 faults an array: 256k)."""
    assert faults("lean", 1 << 16) < 20 * 128 * 5
