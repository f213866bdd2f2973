"""cooprint.jit: the numba set-up of every kernel module."""

import subprocess
import sys


def test_kernel_modules_untime_llvm_and_still_run():
    """Importing a kernel module drops numba's per-LLVM-call timing callbacks (they cost a
    quarter of loading a worker's cached kernels), and the kernels load and run as before."""
    code = (
        "import numpy as np\n"
        "from llvmlite.binding import ffi\n"
        "import numba.core.base\n"
        "assert any(a.__module__ == 'numba.core.base' for a, _ in ffi.lib._lock._cblist)\n"
        "from cooprint.io.mesh_kernels import first_copies\n"
        "assert not any(a.__module__ == 'numba.core.base' for a, _ in ffi.lib._lock._cblist)\n"
        "bits = np.array([[1, 2, 3], [4, 5, 6], [1, 2, 3]], np.uint32)\n"
        "local, first = np.empty(3, np.int32), np.empty(8, np.int32)\n"
        "assert first_copies(bits, 4, local, first) == 2\n"
        "assert local.tolist() == [0, 1, 0] and first[:2].tolist() == [0, 1]\n"
    )
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
