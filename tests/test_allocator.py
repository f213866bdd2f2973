"""The allocator policies the ``cooprint`` command applies (cooprint.allocator)."""

import platform
import subprocess
import sys

import pytest

from cooprint import allocator

glibc = pytest.mark.skipif(platform.system() != "Linux" or platform.libc_ver()[0] != "glibc",
                           reason="glibc's mallopt")

#: Makes and drops 20 arrays of 64 KiB (under lean's mmap threshold: from the heap) 100 times
#: under the policy named by argv[1], and prints the page faults that cost.
CHURN = (
    "import resource, sys, numpy as np\n"
    "from cooprint import allocator\n"
    "assert sys.argv[1] == 'plain' or getattr(allocator, sys.argv[1])()\n"
    "np.ones(1 << 13)\n"
    "before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt\n"
    "for _ in range(100): a = [np.ones(1 << 13) for _ in range(20)]; del a\n"
    "print(resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before)\n")


def faults(policy):
    out = subprocess.run([sys.executable, "-c", CHURN, policy], capture_output=True, text=True, check=True)
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
