"""Robot programs as streams of pieces, chunk commands kept out of memory (issue 15).

A plan of a big part holds tens of millions of commands: made whole, a robot's program does not
fit in memory. Here a robot's program is a :class:`RobotStream`, a list of parts in order: small
:class:`~cooprint.program.commands.Program` pieces (travel, turns, NOTIFY / WAIT) and
:class:`ChunkPiece` references to a stretch of a chunk's commands. A chunk's commands are made
once, when its layers are sliced, as its *canonical program* (:func:`canonical_program`: every
layer through :func:`~cooprint.program.build.layer_program`, the nozzle coming from nowhere),
and kept in a :class:`ChunkStore`: in memory for a small job, or spooled to disk, one chunk per
file, for a big one. The store keeps of each chunk only a small :class:`ChunkSummary` in memory.

A robot that comes to a chunk from a known place ``entry`` prints the canonical program with its
way in replaced (:func:`entered`): the commands are those ``layer_program`` makes from there, so
a stream resolved piece by piece gives exactly the program that ``Program.concat`` of the
pieces made before (the writers then give the same bytes, written as the pieces come).
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path
from typing import Iterator, Mapping, Sequence

import numba
import numpy as np

from cooprint import jit
from cooprint.program.commands import COLUMNS, MOVE, Program, program_rows, quantize
from cooprint.slicing.paths import LayerPaths

jit.setup()  # Ctrl-C held while numba compiles; LLVM calls untimed (cooprint.jit)


#: The most commands a consumer of a stream takes at once (:meth:`RobotStream.programs`): a
#: beam's chunk holds two million; a writer's text or a timing's arrays for 262,144 commands
#: are tens of megabytes.
PIECE_COMMANDS = 1 << 18


@dataclass(frozen=True)
class ChunkSummary:
    """What the later stages need of a sliced chunk without its paths.

    Attributes
    ----------
    first, last : (3,) float64 or None
        Where the nozzle starts printing it (its first non-empty layer's first point) and where
        it ends (its last layer's last point), on the 1 µm grid; None: nothing to print.
    hull : (k, 2) float64
        XY points whose convex hull holds every point its paths go through (the hull's corners:
        any extreme of a linear function over the printed points is one of them).
    layers : int
        Its non-empty layers.
    commands : int
        Commands of its canonical program.
    """

    first: np.ndarray | None
    last: np.ndarray | None
    hull: np.ndarray
    layers: int
    commands: int


def canonical_program(cid: str, layers: Sequence[tuple[int, LayerPaths]]) -> Program:
    """A chunk's commands (every layer, in the object's layer grid), the nozzle coming from
    nowhere: what :func:`entered` starts from."""
    from cooprint.program.build import layer_program

    pos = np.full(3, np.nan)
    parts = []
    for li, layer in layers:
        piece, pos = layer_program(layer, pos, index=li, chunk=cid)
        parts.append(piece)
    return Program.concat("", parts)


def entered(canon: Program, entry: np.ndarray | None) -> Program:
    """The chunk's commands for a nozzle that comes from ``entry`` (3,): as
    :func:`~cooprint.program.build.layer_program` makes them from there. Only the way in
    differs from the canonical program's: up to the first layer's height where the nozzle is,
    then over to the first point (each left out where the nozzle is already); from the first
    point on, the commands are the same."""
    if entry is None or len(canon) == 0 or not np.isfinite(entry).all():
        return canon
    assert canon.kind[0] == MOVE, "a chunk's commands start with the move to its first point"
    here = quantize(np.asarray(entry, dtype=np.float64))
    first = canon.xyz[0]
    lead = quantize(np.array([[here[0], here[1], first[2]], first]))
    keep = (lead != np.vstack([here[None], lead[:1]])).any(axis=1)
    k = int(keep.sum())
    rows = np.r_[np.zeros(k, np.int64), np.arange(1, len(canon))]
    cols = {f: getattr(canon, f)[rows] for f in COLUMNS}
    cols["xyz"] = np.vstack([lead[keep], canon.xyz[1:]])
    return Program(canon.robot, **cols, chunks=canon.chunks, events=canon.events, turns=())


def chunk_ends(layers: Sequence[tuple[int, LayerPaths]]) -> tuple[np.ndarray, np.ndarray] | None:
    """Where the nozzle starts printing a chunk (its first non-empty layer's first point) and
    where it ends (its last layer's last point), on the 1 µm grid; None: nothing to print."""
    full = [layer for _, layer in layers if len(layer)]
    if not full:
        return None
    return quantize(np.r_[full[0].points[0], full[0].z]), quantize(np.r_[full[-1].points[-1], full[-1].z])


def summarize(layers: Sequence[tuple[int, LayerPaths]], canon: Program) -> ChunkSummary:
    """The :class:`ChunkSummary` of a chunk's layers and canonical program."""
    ends = chunk_ends(layers)
    if ends is None:
        return ChunkSummary(None, None, np.zeros((0, 2)), 0, len(canon))
    full = [layer for _, layer in layers if len(layer)]
    pts = np.concatenate([layer.points[:, :2] for layer in full])
    return ChunkSummary(ends[0], ends[1], hull_points(pts), len(full), len(canon))


def hull_points(pts: np.ndarray) -> np.ndarray:
    """(k, 2) the corners of the convex hull of XY points (n, 2), collinear points on its edges
    kept; the points themselves, not rounded: the least or greatest of any linear function over
    ``pts`` is reached at one of them (Andrew's monotone chain)."""
    pts = np.asarray(pts, dtype=np.float64)
    if len(pts) <= 3:
        return pts.copy()
    order = np.lexsort((pts[:, 1], pts[:, 0]))
    sorted_pts = np.ascontiguousarray(pts[order])
    keep = np.r_[True, (np.diff(sorted_pts, axis=0) != 0).any(axis=1)]
    distinct = np.ascontiguousarray(sorted_pts[keep])
    return distinct if len(distinct) < 3 else _chain(distinct)


@numba.njit(cache=True)
def _chain(p: np.ndarray) -> np.ndarray:  # pragma: no cover - compiled
    n = len(p)
    out = np.empty((2 * n, 2))
    k = 0
    for i in range(n):  # lower chain
        while k >= 2 and ((out[k - 1, 0] - out[k - 2, 0]) * (p[i, 1] - out[k - 2, 1])
                          - (out[k - 1, 1] - out[k - 2, 1]) * (p[i, 0] - out[k - 2, 0])) < 0:
            k -= 1
        out[k] = p[i]
        k += 1
    low = k + 1
    for i in range(n - 2, -1, -1):  # upper chain
        while k >= low and ((out[k - 1, 0] - out[k - 2, 0]) * (p[i, 1] - out[k - 2, 1])
                            - (out[k - 1, 1] - out[k - 2, 1]) * (p[i, 0] - out[k - 2, 0])) < 0:
            k -= 1
        out[k] = p[i]
        k += 1
    return out[:k - 1].copy()


def _save(fh, array: np.ndarray) -> None:
    """``np.save`` through the file's own ``write`` (numpy's fast path writes with ``tofile``,
    whose error on a full disk has no errno: here it is the OS's ENOSPC, which the bundle
    reports as a full disk)."""
    a = np.ascontiguousarray(array)
    np.lib.format.write_array_header_1_0(fh, np.lib.format.header_data_from_array_1_0(a))
    if a.size:
        fh.write(memoryview(a.reshape(-1)).cast("B"))


class ChunkStore:
    """The chunks' canonical programs and summaries: in memory (``folder`` None) or one file per
    chunk in ``folder`` (the last one read is kept, for the pieces of a chunk that follow one
    another). ``put`` is called as each chunk is sliced; the summaries stay in memory."""

    def __init__(self, folder: str | Path | None = None):
        self.folder = None if folder is None else Path(folder)
        if self.folder is not None:
            self.folder.mkdir(parents=True, exist_ok=True)
        self.summaries: dict[str, ChunkSummary] = {}
        self._mem: dict[str, Program] = {}
        self._files: dict[str, Path] = {}
        self._last: tuple[str, Program] | None = None
        #: what other stages computed of a chunk's program and keep (e.g. the fleet's pieces)
        self.memo: dict[tuple, object] = {}

    def put(self, cid: str, layers: Sequence[tuple[int, LayerPaths]]) -> Program:
        """Make and keep chunk ``cid``'s canonical program from its layers; returns it."""
        canon = canonical_program(cid, layers)
        self.summaries[cid] = summarize(layers, canon)
        if self.folder is None:
            self._mem[cid] = canon
        else:
            path = self.folder / f"{len(self._files):06d}.npy"
            try:
                with open(path, "wb") as fh:
                    for f in COLUMNS:
                        _save(fh, getattr(canon, f))
            except OSError as exc:  # a full disk: named with the file (the bundle's error says which)
                raise OSError(exc.errno, exc.strerror, str(path)) from None
            self._files[cid] = path
            self._last = (cid, canon)
        return canon

    def __contains__(self, cid: object) -> bool:
        return cid in self.summaries

    def __iter__(self) -> Iterator[str]:
        return iter(self.summaries)

    def summary(self, cid: str) -> ChunkSummary:
        return self.summaries[cid]

    def program(self, cid: str) -> Program:
        """Chunk ``cid``'s canonical program."""
        if self.folder is None:
            return self._mem[cid]
        if self._last is not None and self._last[0] == cid:
            return self._last[1]
        with open(self._files[cid], "rb") as fh:
            cols = {f: np.load(fh, allow_pickle=False) for f in COLUMNS}
        canon = Program("", **cols, chunks=(cid,))
        self._last = (cid, canon)
        return canon

    def piece(self, piece: "ChunkPiece") -> Program:
        """The commands of ``piece``."""
        prog = entered(self.program(piece.chunk), None if piece.entry is None else np.asarray(piece.entry))
        if piece.start == 0 and piece.stop is None:
            return prog
        return program_rows(prog, piece.start, len(prog) if piece.stop is None else piece.stop)

    def nbytes(self) -> int:
        """Bytes of the programs on disk (0 in memory)."""
        return sum(os.path.getsize(p) for p in self._files.values())


@dataclass(frozen=True)
class ChunkPiece:
    """Commands ``start .. stop`` (None: to the end) of a chunk's program as a nozzle coming from
    ``entry`` prints it (None: the canonical program, from nowhere)."""

    chunk: str
    start: int = 0
    stop: int | None = None
    entry: tuple[float, float, float] | None = None


@dataclass
class RobotStream:
    """A robot's program as parts in order (see the module doc)."""

    robot: str
    parts: list

    def programs(self, store: ChunkStore, most: int | None = None) -> Iterator[Program]:
        """Each part's commands, in order (a chunk piece read from the store); with ``most``, a
        chunk piece longer than that in parts of at most ``most`` commands (what a consumer
        makes of each piece, e.g. a writer's text, stays that small)."""
        for part in self.parts:
            if not isinstance(part, ChunkPiece):
                yield part
                continue
            prog = store.piece(part)
            if most is None or len(prog) <= most:
                yield prog
                continue
            for a in range(0, len(prog), most):
                yield program_rows(prog, a, min(a + most, len(prog)))

    def program(self, store: ChunkStore) -> Program:
        """The whole program in memory (for small jobs and tests)."""
        return Program.concat(self.robot, self.programs(store))


class Programs(Mapping[str, Program]):
    """``{robot: Program}`` made whole on first use from streams (a small job's programs as a
    dict; a big job's programs are only ever streamed)."""

    def __init__(self, streams: Mapping[str, RobotStream], store: ChunkStore):
        self.streams, self.store = streams, store
        self._made: dict[str, Program] = {}

    def __getitem__(self, robot: str) -> Program:
        if robot not in self._made:
            self._made[robot] = self.streams[robot].program(self.store)
        return self._made[robot]

    def __iter__(self) -> Iterator[str]:
        return iter(self.streams)

    def __len__(self) -> int:
        return len(self.streams)


class ProgramStats:
    """Counts and lengths of a command stream and the material it deposits, added up piece by
    piece (:meth:`add`, in order; :meth:`to_dict`). The sums are those of the whole program up
    to the rounding of their order."""

    def __init__(self) -> None:
        self.commands = self.moves = self.notify = self.wait = 0
        self.print_mm = self.travel_mm = self.volume = 0.0
        self._prev: np.ndarray | None = None  # where the last move ended
        self._tool = False

    def add(self, p: Program) -> "ProgramStats":
        from cooprint.program.commands import NOTIFY, WAIT
        from cooprint.slicing.paths import flow_area

        mv = np.flatnonzero(p.kind == MOVE)
        xyz = p.xyz[mv]
        on = p.tool_on(self._tool)[mv]
        width, height, role = p.width[mv], p.height[mv], p.role[mv]
        if self._prev is None:  # the first move comes from nowhere: no length
            xyz_from, on, width, height, role = xyz, on[1:], width[1:], height[1:], role[1:]
        else:
            xyz_from = np.vstack([self._prev[None], xyz])
        seg = np.linalg.norm(np.diff(xyz_from, axis=0), axis=1)
        area = flow_area(width, height, role)
        self.volume += float((np.where(on, area, 0.0) * seg).sum())
        self.print_mm += float(seg[on].sum())
        self.travel_mm += float(seg[~on].sum())
        self.commands += len(p)
        self.moves += len(mv)
        self.notify += int((p.kind == NOTIFY).sum())
        self.wait += int((p.kind == WAIT).sum())
        if len(mv):
            self._prev = xyz[-1]
        if len(p):
            self._tool = bool(p.tool_on(self._tool)[-1])
        return self

    def to_dict(self, filament_diameter: float) -> dict[str, float | int]:
        return {"commands": self.commands, "moves": self.moves, "print_mm": self.print_mm,
                "travel_mm": self.travel_mm, "volume_mm3": self.volume,
                "filament_mm": self.volume / (np.pi * (filament_diameter / 2) ** 2),
                "notify": self.notify, "wait": self.wait}


__all__ = ["PIECE_COMMANDS", "ChunkPiece", "ChunkStore", "chunk_ends", "ChunkSummary", "ProgramStats", "Programs", "RobotStream", "canonical_program", "entered",
           "hull_points", "summarize"]
