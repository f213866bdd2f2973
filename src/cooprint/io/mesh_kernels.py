"""Compiled kernels of the mesh loader (numba; imported on first use, so that commands that
never read a mesh do not load numba)."""

from __future__ import annotations

import numba
import numpy as np

from cooprint import jit

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)

#: Multipliers of the vertex hash (odd 64-bit constants; the products wrap modulo 2**64). The
#: loader's merge groups use the same mix.
MIX = (0x9E3779B97F4A7C15, 0xC2B2AE3D27D4EB4F, 0x165667B19E3779F9)


@numba.njit(cache=True, nogil=True)
def first_copies(bits, size_log2, out_local, out_first):
    """Bit-identical rows of ``bits`` (n, 3) found with an open-addressing hash table of
    ``2**size_log2`` slots: ``out_local[i]`` is the number of row i's value in order of first
    appearance, ``out_first[k]`` the row where value k first appears. Returns the number of
    distinct values, or -1 when they would fill more than half of the table (the caller
    retries with a larger one)."""
    size = 1 << size_log2
    mask = size - 1
    shift = np.uint64(64 - size_log2)
    table = np.full(size, -1, out_local.dtype)
    m0, m1, m2 = np.uint64(MIX[0]), np.uint64(MIX[1]), np.uint64(MIX[2])
    u = 0
    for i in range(bits.shape[0]):
        a, b, c = bits[i, 0], bits[i, 1], bits[i, 2]
        h = (np.uint64(a) * m0) ^ (np.uint64(b) * m1) ^ (np.uint64(c) * m2)
        h ^= h >> np.uint64(31)
        h *= m1
        s = np.int64(h >> shift)
        while True:
            k = table[s]
            if k < 0:
                if 2 * (u + 1) > size:
                    return -1
                table[s] = u
                out_first[u] = i
                out_local[i] = u
                u += 1
                break
            j = out_first[k]
            if bits[j, 0] == a and bits[j, 1] == b and bits[j, 2] == c:
                out_local[i] = k
                break
            s = (s + 1) & mask
    return u


@numba.njit(cache=True, nogil=True)
def _hash2(a, b, shift):
    """Slot of the pair (a, b) in a table of ``2**(64 - shift)`` slots."""
    h = (np.uint64(a) * np.uint64(MIX[0])) ^ (np.uint64(b) * np.uint64(MIX[1]))
    h ^= h >> np.uint64(31)
    h *= np.uint64(MIX[2])
    return np.int64(h >> shift)


@numba.njit(cache=True, nogil=True)
def proper_faces(verts, faces, size_log2, out_keep):
    """``out_keep[i]``: triangle i has three distinct corners, a cross product of its edges
    from corner 0 of non-zero length (as ``np.linalg.norm(np.cross(...)) > 0``), and no earlier
    triangle has the same three vertices (an open-addressing table of ``2**size_log2`` slots,
    at least twice the triangles, keyed by the sorted corners)."""
    size = 1 << size_log2
    mask = size - 1
    shift = np.uint64(64 - size_log2)
    table = np.full(size, -1, np.int64)
    for i in range(faces.shape[0]):
        a, b, c = np.int64(faces[i, 0]), np.int64(faces[i, 1]), np.int64(faces[i, 2])
        keep = a != b and b != c and c != a
        ax, ay, az = verts[b, 0] - verts[a, 0], verts[b, 1] - verts[a, 1], verts[b, 2] - verts[a, 2]
        bx, by, bz = verts[c, 0] - verts[a, 0], verts[c, 1] - verts[a, 1], verts[c, 2] - verts[a, 2]
        cx, cy, cz = ay * bz - az * by, az * bx - ax * bz, ax * by - ay * bx
        keep = keep and cx * cx + cy * cy + cz * cz > 0
        x, y, z = min(a, b, c), max(min(a, b), min(max(a, b), c)), max(a, b, c)
        s = _hash2(x * np.int64(0x9E3779B1) + y, z, shift)
        while True:
            k = table[s]
            if k < 0:
                table[s] = i
                break
            p, q, r = np.int64(faces[k, 0]), np.int64(faces[k, 1]), np.int64(faces[k, 2])
            if min(p, q, r) == x and max(p, q, r) == z and max(min(p, q), min(max(p, q), r)) == y:
                keep = False  # a repeat of triangle k
                break
            s = (s + 1) & mask
        out_keep[i] = keep
