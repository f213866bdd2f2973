"""Pictures of a simulated plan (thin, on the timelines): the fleet at an instant, like the seed's
Fig. 14 and 16 (material as lines coloured per robot, robots as their footprints with the
nozzle, and the outlines of their frames and printheads over the print), and a Gantt chart of who prints, travels and waits when."""

from __future__ import annotations

import errno
import math
import os
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np
from PIL import Image, ImageDraw

from cooprint.errors import UserError
from cooprint.render.chunks import BACKGROUND, _font, _view_basis
from cooprint.render.palette import FIXED, robot_colour
from cooprint.render.paths import _fit
from cooprint.simulation import SimResult
from cooprint.simulation.checks import body_corners, outline_corners

ROBOT_COLOURS = FIXED  # the first robots' colours (render/palette.py)
WAIT_COLOUR = (235, 200, 60)
TRAVEL_COLOUR = (185, 185, 185)
#: The frame of a chunk on the schedule's critical path, and the lower bound's line, in the Gantt chart.
CRITICAL_COLOUR = (204, 0, 0)
BOUND_COLOUR = (40, 40, 40)


def _colour(i: int) -> tuple[int, int, int]:
    return robot_colour(i)


#: Seconds in a day: times from one day on are written in days.
DAY = 86400.0


def _hms(t: float) -> str:
    """``H:MM:SS``, from one day on ``D d HH:MM:SS`` (a 375-day plan is ``375 d 00:00:00``, not
    ``9000:00:00``)."""
    d, s = divmod(int(round(t)), int(DAY))
    hms = f"{s // 3600:02d}:{s % 3600 // 60:02d}:{s % 60:02d}"
    return f"{d} d {hms}" if d else hms.removeprefix("0")


class _Scene:
    """The projection of a simulated plan, fitted once so that every frame lines up."""

    def __init__(self, result: SimResult, size: tuple[int, int], azimuth_deg: float, elevation_deg: float):
        self.result, self.size = result, size
        self.basis = _view_basis(azimuth_deg, elevation_deg)
        # the moves' ends projected a block at a time: the least and the most of each axis (all
        # that the fit and the shading take), not a projected copy of every move
        ends = [p for tl in result.timelines.values() for a in range(0, len(tl.p0), BLOCK_MOVES)
                for p in (tl.p0[a:a + BLOCK_MOVES], tl.p1[a:a + BLOCK_MOVES])]
        extent = [f(p @ self.basis.T, axis=0) for p in ends for f in (np.min, np.max)]
        feet = [_footprint(result, r, p, t) for r in result.robots for tl in [result.timelines[r.name]]
                for p, t in ([(tl.p0[0], tl.t0[0]), (tl.p1[-1], tl.t1[-1])] if len(tl.p0) else [])
                if result.placed]
        feet += [part for r in result.robots if result.placed for tl in [result.timelines[r.name]]
                 for p, t in ([(tl.p0[0], tl.t0[0]), (tl.p1[-1], tl.t1[-1])] if len(tl.p0) else [])
                 for part in _upper_parts(result, r, p, t)]  # the frames and printheads, in the air
        for r in result.robots if result.placed else []:  # where a robot turns, in the facings before and after
            spans = r.facing_spans(result.timelines[r.name]) if r.program.turns else []
            feet += [np.column_stack([sp.position[:2] + body_corners(r.profile or result.profile, f), np.zeros(4)])
                     for before, sp in zip(spans, spans[1:]) for f in (before.facing, sp.facing)]
        every = np.vstack(extent + [f @ self.basis.T for f in feet]) if extent else np.zeros((1, 3)) @ self.basis.T
        self.lo, self.scale, self.off = _fit(every[:, :2], size, 40, 90)
        self.palette = np.array([_colour(i) for i in range(len(result.robots))])
        depth = [f(p @ self.basis.T[:, 2]) for p in ends for f in (np.min, np.max)] or [0.0]  # for shading
        self.d_lo, self.d_span = float(min(depth)), max(float(max(depth) - min(depth)), 1e-9)
        # per robot, for its progress bar: the printing time done before each block of moves
        self.printing = {}
        for r in result.robots:
            tl = result.timelines[r.name]
            done = [_printing(tl, a, min(a + BLOCK_MOVES, len(tl.t0))) for a in range(0, len(tl.t0), BLOCK_MOVES)]
            self.printing[r.name] = np.concatenate([[0.0], np.cumsum(done)])

    def printed(self, robot: str, t: float) -> tuple[float, float]:
        """Seconds of printing robot ``robot`` has done by ``t``, and in all."""
        tl, before = self.result.timelines[robot], self.printing[robot]
        k = int(np.searchsorted(tl.t1, t, side="right"))  # moves finished by t
        b = k // BLOCK_MOVES
        done = before[b] + (_printing(tl, b * BLOCK_MOVES, k) if k > b * BLOCK_MOVES else 0.0)
        under_way = t - tl.t0[k] if k < len(tl.t0) and tl.on[k] and tl.t0[k] < t else 0.0  # a print under way
        return float(done + under_way), float(before[-1])

    def px(self, p: np.ndarray) -> np.ndarray:
        return ((p @ self.basis.T)[..., :2] - self.lo) * self.scale * np.array([1, -1]) + self.off

    def material(self, draw: ImageDraw.ImageDraw, seg: np.ndarray, col: np.ndarray, sort: bool) -> None:
        """Segments (k, 2, 3) in their robots' colours, shaded by depth (far to near if ``sort``)."""
        if not len(seg):
            return
        depth = (seg @ self.basis.T)[:, :, 2].mean(axis=1)
        order = np.argsort(depth, kind="stable") if sort else np.arange(len(seg))
        shade = 0.65 + 0.35 * np.clip((depth[order] - self.d_lo) / self.d_span, 0, 1)
        colours = (self.palette[col[order]] * shade[:, None]).astype(int).tolist()
        for ((x0, y0), (x1, y1)), c in zip(self.px(seg[order]).round(1).tolist(), colours):
            draw.line([(x0, y0), (x1, y1)], fill=tuple(c), width=1)

    def robots(self, draw: ImageDraw.ImageDraw, t: float, filled: bool) -> None:
        """Footprints on the floor (where they are known: not for G-code printers) and nozzles (a
        mast from the floor and a dot)."""
        for i, r in enumerate(self.result.robots):
            n = self.result.timelines[r.name].position(t)
            if self.result.placed:
                foot = [tuple(q) for q in self.px(_footprint(self.result, r, n, t)).round(1).tolist()]
                light = tuple(int(0.5 * x + 0.5 * 255) for x in _colour(i))
                draw.polygon(foot, fill=light if filled else None, outline=_colour(i))
                if not filled:  # the frame and the printhead, in the air over the print, on the nozzle
                    parts = _upper_parts(self.result, r, n, t)
                    for part in parts:
                        draw.polygon([tuple(q) for q in self.px(part).round(1).tolist()], outline=_colour(i))
                    up = self.px(np.array([n[0], n[1], parts[0][0, 2]]))
                    draw.line([tuple(self.px(n)), tuple(up)], fill=_colour(i), width=1)
            a, b = self.px(np.array([n[0], n[1], 0.0])), self.px(n)
            draw.line([tuple(a), tuple(b)], fill=(60, 60, 60), width=2)
            draw.ellipse([b[0] - 5, b[1] - 5, b[0] + 5, b[1] + 5], fill=_colour(i), outline=(30, 30, 30))


#: Moves looked at a block at a time (the scene's extent, the printing time, the material drawn).
BLOCK_MOVES = 1 << 20


def _printing(tl, a: int, e: int) -> float:
    """Seconds of printing in moves ``a:e`` of a timeline."""
    on = tl.on[a:e]
    return float((tl.t1[a:e][on] - tl.t0[a:e][on]).sum())


def _deposited(result: SimResult, t: float, most: int | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The segments (m, 2, 3) of material laid down by ``t`` (each robot's in order, the last
    one of each cut at ``t``) and the robot of each; with ``most``, at most that many of them,
    evenly spread over all (``linspace`` over their order), gathered a block of moves at a time
    (never all of a big plan's segments at once)."""
    counts = []  # per robot: its moves that may have started by t, and its deposits in each block of them
    for r in result.robots:
        tl = result.timelines[r.name]
        k = int(np.searchsorted(tl.t0, t, side="left"))
        counts.append((k, np.array([int(np.count_nonzero(tl.on[a:min(a + BLOCK_MOVES, k)]))
                                    for a in range(0, k, BLOCK_MOVES)], dtype=np.int64)))
    total = int(sum(int(c.sum()) for _, c in counts))
    pick = np.linspace(0, total - 1, most).astype(np.int64) if most is not None and total > most else None
    segs, cols = [], []
    first = 0  # the robot's first segment among all
    for i, (r, (k, blocks)) in enumerate(zip(result.robots, counts)):
        tl = result.timelines[r.name]
        mine = int(blocks.sum())
        want = None if pick is None else pick[np.searchsorted(pick, first):np.searchsorted(pick, first + mine)] - first
        starts = np.concatenate([[0], np.cumsum(blocks)])
        full = np.flatnonzero(blocks)  # the robot's last deposit by t: the last of the last block that has one
        last = (int(np.flatnonzero(tl.on[full[-1] * BLOCK_MOVES:min((full[-1] + 1) * BLOCK_MOVES, k)])[-1])
                + int(full[-1]) * BLOCK_MOVES) if len(full) else -1
        for j, a in enumerate(range(0, k, BLOCK_MOVES)):
            idx = np.flatnonzero(tl.on[a:min(a + BLOCK_MOVES, k)]) + a  # the block's deposits
            if want is not None:
                idx = idx[want[np.searchsorted(want, starts[j]):np.searchsorted(want, starts[j + 1])] - starts[j]]
            seg = np.stack([tl.p0[idx], tl.p1[idx]], axis=1)
            if len(idx) and idx[-1] == last and tl.t1[last] > t:  # its last deposit, under way: up to the nozzle
                seg[-1, 1] = tl.position(t)
            segs.append(seg)
            cols.append(np.full(len(seg), i))
        first += mine
    return (np.concatenate(segs) if segs else np.zeros((0, 2, 3)),
            np.concatenate(cols) if cols else np.zeros(0, np.int64))


def render_snapshot(result: SimResult, t: float, path: str | Path, size: tuple[int, int] = (1280, 720),
                    azimuth_deg: float = -35.0, elevation_deg: float = 30.0, max_segments: int = 300_000) -> Path:
    """The fleet at time ``t``: material laid down so far (per robot colour, far to near), each
    robot's footprint on the floor and its nozzle, a clock and each robot's progress."""
    scene = _Scene(result, size, azimuth_deg, elevation_deg)
    seg, col = _deposited(result, t, max_segments)  # at most max_segments, spread over all
    img = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(img)
    scene.robots(draw, t, filled=True)
    scene.material(draw, seg, col, sort=True)
    scene.robots(draw, t, filled=False)
    _overlay(draw, scene, t, size)
    path = Path(path)
    img.save(path, format="PNG")
    return path


#: The most frames an animation may have: an MP4 is streamed (20,000 frames are 14 min at 24
#: fps and take about as many seconds to draw), a GIF's frames are all held until it is written
#: (1,000 of 640 x 360 are 230 MB).
MAX_FRAMES = 20_000
MAX_GIF_FRAMES = 1_000
#: An animation's length without --duration or --speedup, s.
DEFAULT_LENGTH = 20.0
#: The longest animation --speedup may make, s: a longer one is asked for by its length
#: (--duration), never made by a speed-up that happens to be too small for a long plan
#: (``--speedup 100`` on a 24 h plan would be a 14 min, 60 MB MP4).
MAX_SPEEDUP_LENGTH = 600.0
#: A GIF's most frames per second: its delays are whole hundredths of a second and browsers
#: play a delay of 0 or 1 as 10 (50 fps is 2 each).
MAX_GIF_FPS = 50.0


def animation_length(makespan: float, duration: float | None = None, speedup: float | None = None) -> float:
    """Seconds an animation of a ``makespan`` s plan lasts: ``duration``, or the plan played
    ``speedup`` times faster than real time, or :data:`DEFAULT_LENGTH`."""
    return makespan / speedup if speedup is not None else (duration or DEFAULT_LENGTH)


def length_text(seconds: float) -> str:
    """An animation's length for people: ``20.0 s``, ``14 min 24 s``, ``10 min``, ``2 h 05 min``."""
    if seconds < 60:
        return f"{seconds:.1f} s"
    s = int(round(seconds))
    if s >= 3600:
        return f"{s // 3600} h {s % 3600 // 60:02d} min"
    return f"{s // 60} min" + (f" {s % 60:02d} s" if s % 60 else "")


def frame_count(makespan: float, fps: float, duration: float | None = None, speedup: float | None = None,
                gif: bool = False) -> int:
    """How many frames an animation ``duration`` s long (or played ``speedup`` times faster than
    real time) at ``fps`` has; a :class:`~cooprint.errors.UserError` naming the options when
    that is not a finite count of at most ``MAX_FRAMES`` (``MAX_GIF_FRAMES`` for a GIF): the
    options alone must not ask for unbounded work (``--speedup 0.001 --fps 120`` over a 50 min
    plan is 360,000 frames); when ``speedup`` makes it longer than :data:`MAX_SPEEDUP_LENGTH`
    (the length it would have, the speed-up that keeps it within, and --duration to ask for
    it); and for a GIF over :data:`MAX_GIF_FPS`."""
    for name, v in (("--fps", fps), ("--duration", duration), ("--speedup", speedup)):
        if v is not None and not (math.isfinite(v) and v > 0):
            raise UserError(f"{name} {v:g}: expected a positive number")
    if gif and fps > MAX_GIF_FPS:
        raise UserError(f"--fps {fps:g}: a GIF plays at most {MAX_GIF_FPS:g} frames/s (its delays are whole "
                        f"hundredths of a second); take a lower --fps or --format mp4")
    length = animation_length(makespan, duration, speedup)
    frames = length * fps
    if speedup is not None and length > MAX_SPEEDUP_LENGTH:
        x = makespan / MAX_SPEEDUP_LENGTH
        need = math.ceil(x) if x >= 1 else math.ceil(x * 1000) / 1000
        raise UserError(f"--speedup {speedup:g} over the {_hms(makespan)} plan makes an animation of "
                        f"{length_text(length)} ({frames:,.0f} frames at {fps:g} fps), longer than "
                        f"{length_text(MAX_SPEEDUP_LENGTH)}: take --speedup {need:g} or more, or give the "
                        f"length you want with --duration")
    limit = MAX_GIF_FRAMES if gif else MAX_FRAMES
    if not frames <= limit:
        how = (f"--speedup {speedup:g} over the {makespan:.3g} s plan is {length:.3g} s" if speedup is not None
               else f"--duration {length:g} s")
        raise UserError(f"{how} at --fps {fps:g}: {frames:,.0f} frames, more than {limit:,} for "
                        f"{'a GIF' if gif else 'an animation'}; take a shorter --duration, a larger --speedup "
                        f"or a lower --fps")
    return max(2, int(round(frames)))


def frame_times(makespan: float, fps: float, duration: float | None = None, speedup: float | None = None,
                gif: bool = False) -> np.ndarray:
    """Times of the frames of an animation ``duration`` s long (or played ``speedup`` times
    faster than real time), the last frame at the end of the plan (at most ``MAX_FRAMES``,
    :func:`frame_count`)."""
    return np.linspace(0.0, makespan, frame_count(makespan, fps, duration, speedup, gif))


def gif_delays(frames: int, length: float) -> list[int]:
    """Each GIF frame's delay, ms, so that ``frames`` of them last ``length`` s: a GIF holds
    whole hundredths of a second, so frame k lasts from the k-th boundary to the next, each
    boundary ``k * length / frames`` rounded to a hundredth (24 fps: 40, 40, 50, 40, ... ms,
    the sum within 10 ms of ``length``, not 41 ms written as 40 each, 4 % short). At least 20 ms
    each (browsers play shorter delays as 100 ms)."""
    bounds = np.round(np.arange(frames + 1) * (100.0 * length / frames)).astype(np.int64)
    return (np.maximum(np.diff(bounds), 2) * 10).tolist()


class Mp4Encoder:
    """ffmpeg (from imageio-ffmpeg) encoding raw RGB frames from its stdin into an H.264 MP4.

    Quiet: ffmpeg runs at log level ``error`` and its stderr goes to a temporary file, never to
    the user's terminal (a 2-frame video would otherwise print a warning, a full disk six
    lines). A failure (ffmpeg gone, a broken pipe, a non-zero exit) becomes one ``OSError``
    whose text is ffmpeg's last error line, with the errno of a full disk, a read-only file
    system, a permission or quota problem when ffmpeg names one; the atomic writer turns it
    into ``OUT: cannot write: ...`` naming the user's file."""

    #: The OS errors ffmpeg reports by their text (``No space left on device``).
    ERRNOS = (errno.ENOSPC, errno.EDQUOT, errno.EROFS, errno.EACCES, errno.EFBIG, errno.EIO)

    def __init__(self, path: str | Path, size: tuple[int, int], fps: float, crf: int = 15):
        import imageio_ffmpeg

        w, h = size
        cmd = [imageio_ffmpeg.get_ffmpeg_exe(), "-y", "-f", "rawvideo", "-vcodec", "rawvideo",
               "-s", f"{w}x{h}", "-pix_fmt", "rgb24", "-r", f"{fps:.02f}", "-i", "-", "-an",
               "-vcodec", "libx264", "-pix_fmt", "yuv420p", "-crf", str(crf)]
        if w % 8 or h % 8:  # players want whole macro blocks (as imageio-ffmpeg's default)
            cmd += ["-vf", f"scale={-(-w // 8) * 8}:{-(-h // 8) * 8}"]
        cmd += ["-v", "error", "-f", "mp4", str(path)]
        self.log = tempfile.TemporaryFile()
        try:  # its own session: a Ctrl-C reaches cooprint, which stops it, not ffmpeg half-way
            self.proc = subprocess.Popen(cmd, stdin=subprocess.PIPE, stdout=subprocess.DEVNULL,
                                         stderr=self.log, start_new_session=True)
        except OSError as exc:
            self.log.close()
            raise OSError(exc.errno, f"cannot start ffmpeg ({exc.strerror or exc})") from None

    def send(self, frame: bytes) -> None:
        """Encode one frame (``w * h * 3`` bytes, RGB)."""
        try:
            self.proc.stdin.write(frame)  # type: ignore[union-attr]
        except OSError as exc:  # ffmpeg stopped (a full disk): its own reason is the better one
            self._fail(exc)

    def close(self) -> None:
        """Finish the file; an ``OSError`` if ffmpeg did not."""
        try:
            self.proc.stdin.close()  # type: ignore[union-attr]
        except OSError as exc:
            self._fail(exc)
        if self.proc.wait() != 0:
            self._fail(None)
        self.log.close()

    def abort(self) -> None:
        """Stop ffmpeg (on an error or a Ctrl-C elsewhere); the caller removes the file."""
        self._stop(kill=True)
        self.log.close()

    def _stop(self, kill: bool) -> None:
        """Close ffmpeg's input and wait for it (killed at once with ``kill``, else after 10 s)."""
        try:
            self.proc.stdin.close()  # type: ignore[union-attr]
        except OSError:  # a broken pipe: ffmpeg is gone already
            pass
        if kill and self.proc.poll() is None:
            self.proc.kill()
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()

    def _fail(self, exc: OSError | None) -> None:
        """Raise ffmpeg's own last error line as one ``OSError`` (see the class docstring)."""
        self._stop(kill=False)
        self.log.seek(0)
        lines = [ln.strip() for ln in self.log.read().decode("utf-8", "replace").splitlines() if ln.strip()]
        self.log.close()
        said = lines[-1][:200] if lines else None
        for code in self.ERRNOS:
            if said and os.strerror(code) in said:
                raise OSError(code, os.strerror(code)) from None
        if exc is not None and said is None:
            raise OSError(exc.errno, f"ffmpeg stopped ({exc.strerror or exc})") from None
        raise OSError(None, f"ffmpeg failed (exit {self.proc.returncode}): {said or 'no message'}") from None


def render_animation(result: SimResult, path: str | Path, fps: float = 24.0, duration: float | None = None,
                     speedup: float | None = None, size: tuple[int, int] = (1280, 720),
                     azimuth_deg: float = -35.0, elevation_deg: float = 30.0,
                     progress: "Callable[[int, int], None] | None" = None) -> Path:
    """MP4 (``.mp4``, through imageio-ffmpeg) or GIF (``.gif``, through Pillow) of the plan in
    time: each frame draws only the material laid down since the one before onto a kept canvas,
    then the robots, the clock and the progress bars on a copy (seed Fig. 15-16).
    ``progress(frames done, frames)`` after each frame."""
    path = Path(path)
    gif = path.suffix.lower() == ".gif"
    if gif:
        size = (min(size[0], 640), min(size[1], 360))
    scene = _Scene(result, size, azimuth_deg, elevation_deg)
    times = frame_times(result.makespan, fps, duration, speedup, gif)
    canvas = Image.new("RGB", size, BACKGROUND)
    draw = ImageDraw.Draw(canvas)
    done = {r.name: 0 for r in result.robots}  # moves drawn whole so far
    frames: list[Image.Image] = []
    writer = None
    if not gif:
        writer = Mp4Encoder(path, size, fps)
    try:
        for n_done, t in enumerate(times.tolist()):
            if progress:
                progress(n_done, len(times))
            partial = []
            for i, r in enumerate(result.robots):
                tl = result.timelines[r.name]
                k = int(np.searchsorted(tl.t1, t, side="right"))  # moves finished by t
                new = np.flatnonzero(tl.on[done[r.name]:k]) + done[r.name]
                scene.material(draw, np.stack([tl.p0[new], tl.p1[new]], axis=1), np.full(len(new), i), sort=False)
                done[r.name] = k
                if k < len(tl.t0) and tl.on[k] and tl.t0[k] < t:  # the move under way, up to the nozzle
                    partial.append((np.array([[tl.p0[k], tl.position(t)]]), np.array([i])))
            frame = canvas.copy()
            fd = ImageDraw.Draw(frame)
            for seg, col in partial:
                scene.material(fd, seg, col, sort=False)
            scene.robots(fd, t, filled=False)
            _overlay(fd, scene, t, size)
            if gif:
                frames.append(frame.quantize(colors=128))
            else:
                writer.send(np.asarray(frame).tobytes())  # type: ignore[union-attr]
        if writer is not None:
            writer.close()
            writer = None
        if progress:
            progress(len(times), len(times))
    finally:
        if writer is not None:  # an error or a Ctrl-C while drawing: ffmpeg stops, the file is removed
            writer.abort()
    if gif:
        frames[0].save(path, format="GIF", save_all=True, append_images=frames[1:], loop=0,
                       duration=gif_delays(len(frames), animation_length(result.makespan, duration, speedup)))
    return path


def _outline_at(result: SimResult, r, nozzle: np.ndarray, t: float) -> dict[str, np.ndarray]:
    """Part -> (4, 2) world XY corners of a robot's outline (:func:`outline_corners`, no
    tolerance) with its nozzle at ``nozzle`` at time ``t``, in the facing in force then (a robot
    that turns round is drawn as it stands)."""
    facing = r.facing_at(result.timelines[r.name], t) if r.program.turns else r.facing
    return {part: nozzle[:2] + c for part, c in outline_corners(r.profile or result.profile, facing, 0.0).items()}


def _footprint(result: SimResult, r, nozzle: np.ndarray, t: float) -> np.ndarray:
    """(4, 3) corners of a robot's body on the floor with its nozzle at ``nozzle`` at time ``t``."""
    return np.column_stack([_outline_at(result, r, nozzle, t)["body"], np.zeros(4)])


def _upper_parts(result: SimResult, r, nozzle: np.ndarray, t: float) -> list[np.ndarray]:
    """(4, 3) corners of a robot's frame and printhead at the height of the printhead's underside
    (``nozzle_height`` above the tip), with its nozzle at ``nozzle`` at time ``t``."""
    parts = _outline_at(result, r, nozzle, t)
    z = float(nozzle[2]) + (r.profile or result.profile).nozzle_height
    return [np.column_stack([parts[p], np.full(4, z)]) for p in ("frame", "printhead")]


def _overlay(draw: ImageDraw.ImageDraw, scene: _Scene, t: float, size: tuple[int, int]) -> None:
    """Clock and per-robot progress bars at the top: name, bar and state for up to three robots
    side by side; for more, every robot still gets a cell (name and bar, the bar grey while it
    waits), in rows of as many as fit."""
    result = scene.result
    span = max(result.makespan, 1e-9)
    draw.text((20, 15), f"t = {_hms(t)} / {_hms(span)}", fill=(20, 20, 20), font=_font(22))
    states = []
    for i, r in enumerate(result.robots):
        tl = result.timelines[r.name]
        done, total = scene.printed(r.name, t)
        waiting = any(a <= t < b for a, b, _ in tl.waits)
        states.append((i, r.name, done / (total or 1.0), waiting, t >= tl.end))
    x0 = 320
    if len(states) * 300 <= size[0] - x0 + 100:
        font = _font(18)
        for k, (i, name, frac, waiting, finished) in enumerate(states):
            x = x0 + 300 * k
            draw.text((x, 12), f"robot {name}", fill=_colour(i), font=font)
            draw.rectangle([x, 40, x + 160, 54], outline=(90, 90, 90))
            draw.rectangle([x, 40, x + int(160 * frac), 54], fill=_colour(i))
            label = "waiting" if waiting else ("done" if finished else f"{100 * frac:.0f}% printed")
            draw.text((x + 170, 38), label, fill=(60, 60, 60), font=_font(14))
        return
    cell = 90
    per_row = max(1, (size[0] - x0 - 20) // cell)
    font = _font(12)
    for k, (i, name, frac, waiting, finished) in enumerate(states):
        x, y = x0 + cell * (k % per_row), 8 + 26 * (k // per_row)
        draw.text((x, y), name, fill=_colour(i), font=font)
        bar = (150, 150, 150) if waiting else _colour(i)
        draw.rectangle([x + 30, y + 3, x + cell - 8, y + 13], outline=(90, 90, 90))
        draw.rectangle([x + 30, y + 3, x + 30 + int((cell - 38) * frac), y + 13], fill=bar)


#: Gantt rows: the pitch (pixels from one robot's row to the next) for few robots, the least for
#: many; the picture grows with the count rather than squeezing rows below the least.
ROW_PITCH, MIN_ROW_PITCH = 60, 18
#: Least height of the Gantt chart's header (title and legend; a title or legend that wraps
#: makes it taller, :func:`gantt_header`) and the height of its time axis, pixels.
GANTT_TOP, GANTT_AXIS = 80, 60
#: The Gantt chart's margins, pixels: the robots' names left of the bars, room for the last
#: time label right of them.
GANTT_LEFT, GANTT_RIGHT = 110, 30


def gantt_height(robots: int, header: int = GANTT_TOP) -> int:
    """Height of the Gantt chart of ``robots`` rows under a header ``header`` pixels tall (the
    least, :data:`GANTT_TOP`, unless its title or legend wraps): the header, one row per robot,
    the axis."""
    return header + _row_pitch(robots) * robots + GANTT_AXIS


def _row_pitch(robots: int) -> int:
    """Row pitch for ``robots`` rows: 60 px up to 8 robots, then shrinking so that the chart stays
    under about 1000 px, never below ``MIN_ROW_PITCH`` (64 robots: 18 px rows, 1.3k px tall)."""
    return max(MIN_ROW_PITCH, min(ROW_PITCH, 960 // max(robots, 1)))


Box = tuple[float, float, float, float]


@dataclass(frozen=True)
class GanttHeader:
    """Where the Gantt chart's title and legend go: each measured (``textbbox``) and placed below
    or beside the one before, never over it; a title or legend too wide for the picture wraps.

    ``title``: lines ``(x, y, text, font size)``; ``legend``: items ``(key, label, swatch box,
    label's x, y)``, key one of ``printing``, ``travelling``, ``waiting``, ``critical``, ``bound``;
    ``boxes``: the ink box of every line, swatch and label; ``bottom``: where the rows may start."""

    title: list[tuple[float, float, str, int]]
    legend: list[tuple[str, str, Box, float, float]]
    boxes: list[Box]
    bottom: int


def gantt_title(makespan: float, lower_bound: float | None = None) -> list[str]:
    """The Gantt chart's title, in parts that may go on lines of their own: the makespan (and
    the lower bound and how far above it the makespan is), in days from one day on."""
    parts = [f"makespan {_hms(makespan)} ({makespan:.0f} s)"]
    if lower_bound:
        parts.append(f"lower bound {_hms(lower_bound)} ({lower_bound:.0f} s; makespan "
                     f"{makespan / lower_bound - 1:+.1%})")
    return parts


#: The legend's labels.
LEGEND = {"printing": "printing", "travelling": "travelling (strip: share of the time)", "waiting": "waiting",
          "critical": "critical path", "bound": "lower bound"}


def gantt_header(title: Sequence[str], robots: int, width: int, critical: bool = False,
                 bound: bool = False) -> GanttHeader:
    """Lay out the Gantt chart's header in a picture ``width`` pixels wide: the ``title``'s parts
    on one line if they fit, else a line each (a part too wide alone in a smaller font, down to
    11 px), then the legend below it, its items left to right, wrapping. The printing swatch holds
    each of the ``robots``' colours; the critical path's and the lower bound's items are there
    when the chart draws them."""
    draw = ImageDraw.Draw(Image.new("RGB", (1, 1)))
    left, right = GANTT_LEFT, width - GANTT_RIGHT
    boxes: list[Box] = []
    lines: list[tuple[float, float, str, int]] = []
    y = 10.0
    parts = list(title)
    while parts:  # as many parts on a line as fit at 20 px
        k = len(parts)
        while k > 1 and draw.textlength("   ".join(parts[:k]), font=_font(20)) > right - left:
            k -= 1
        text, parts = "   ".join(parts[:k]), parts[k:]
        size = 20
        while size > 11 and draw.textlength(text, font=_font(size)) > right - left:
            size -= 1
        box = draw.textbbox((left, y), text, font=_font(size))
        lines.append((left, y, text, size))
        boxes.append(box)
        y = box[3] + 8
    keys = ["printing", "travelling", "waiting"] + ["critical"] * critical + ["bound"] * bound
    font = _font(16)
    legend = []
    x, row_bottom = float(left), y
    for key in keys:
        sw = _swatch_width(robots) if key == "printing" else 18
        text_w = draw.textlength(LEGEND[key], font=font)
        if x > left and x + sw + 6 + text_w > right:  # the next line of the legend
            x, y = float(left), row_bottom + 6
        swatch = (x, y + 2, x + sw, y + 16)
        label = draw.textbbox((x + sw + 6, y), LEGEND[key], font=font)
        legend.append((key, LEGEND[key], swatch, x + sw + 6, y))
        boxes += [swatch, label]
        row_bottom = max(row_bottom, swatch[3], label[3])
        x = label[2] + 24
    return GanttHeader(lines, legend, boxes, int(math.ceil(row_bottom)) + 12)


def _swatch_width(robots: int) -> int:
    """Width of the printing swatch, pixels: a 14 px square per robot (2 px apart) up to 8
    robots, then stripes of at least 2 px."""
    return 16 * robots - 2 if robots <= 8 else max(2, 112 // robots) * robots


def _legend(draw: ImageDraw.ImageDraw, header: GanttHeader, colours: list[tuple[int, int, int]]) -> None:
    """Draw the header's legend: each robot's colour for printing, the travel strip, the wait,
    the critical path's frame, the lower bound's dashes."""
    font = _font(16)
    for key, label, (x0, y0, x1, y1), tx, ty in header.legend:
        if key == "printing":
            n = len(colours)
            step = 16 if n <= 8 else (x1 - x0) / n
            for i, c in enumerate(colours):
                draw.rectangle([x0 + i * step, y0, x0 + i * step + (14 if n <= 8 else step) - 1, y1], fill=c)
        elif key == "travelling":  # as in the rows: a strip under the bar
            draw.rectangle([x0, y1 - 5, x1, y1], fill=TRAVEL_COLOUR)
            draw.line([(x0, y1 - 7), (x1, y1 - 7)], fill=(215, 215, 215))
        elif key == "waiting":
            draw.rectangle([x0, y0, x1, y1], fill=WAIT_COLOUR)
        elif key == "critical":
            draw.rectangle([x0, y0 - 1, x1, y1 + 1], outline=CRITICAL_COLOUR, width=3)
        else:
            for ya in (y0, y0 + 10):
                draw.line([((x0 + x1) / 2, ya), ((x0 + x1) / 2, ya + 5)], fill=BOUND_COLOUR, width=2)
        draw.text((tx, ty), label, fill=(40, 40, 40), font=font)


def render_gantt(result: SimResult, path: str | Path, size: tuple[int, int] = (1200, 0),
                 critical: Sequence[str] | None = None, lower_bound: float | None = None) -> Path:
    """Per robot, when it prints (its colour), travels (a grey strip under the bar, as tall as
    the share of the time it travels) and waits (yellow), on one time axis.

    One row per robot (any count; rows get thinner from 9 robots on, down to ``MIN_ROW_PITCH``,
    and the picture taller, see :func:`gantt_height`). A row's upper part is the printing, at
    pixel resolution (a column is coloured where the robot printed at all); its lower strip is
    the travel, each column's grey as tall as the share of that column's time spent travelling,
    so that travel between short prints shows instead of vanishing under them. Each chunk's
    printing is labelled with its id where the bar is wide enough. The time axis is in days
    from one day on (``1 d 12:00``); the title (also the PNG's ``Title`` text) is the makespan.

    Parameters
    ----------
    size
        Width and height, pixels; height 0: :func:`gantt_height` (taller when the header wraps).
    critical
        Chunk ids of the schedule's critical path (job.json ``schedule.critical_path``): the
        printing of each is framed in red, so the chain that bounds the makespan can be seen.
    lower_bound
        The schedule's lower bound LB, s (job.json ``schedule.lower_bound_s``): a dashed vertical
        line, so the distance from the simulated makespan to the best possible can be seen.
    """
    from PIL.PngImagePlugin import PngInfo

    rows = len(result.robots)
    pitch = _row_pitch(rows)
    bar = max(10, int(pitch * 2 / 3))
    strip = max(3, round(bar / 4))  # the travel strip at the bottom of the bar
    lane = bar - strip - 1  # the printing above it
    w = size[0]
    marked = set(critical or ())
    title = gantt_title(result.makespan, lower_bound)
    header = gantt_header(title, rows, w, critical=bool(marked), bound=bool(lower_bound))
    top = max(GANTT_TOP, header.bottom)
    h = size[1] or gantt_height(rows, top)
    img = Image.new("RGB", (w, h), BACKGROUND)
    draw = ImageDraw.Draw(img)
    left, right = GANTT_LEFT, w - GANTT_RIGHT
    cols = right - left
    span = max(result.makespan, lower_bound or 0.0, 1e-9)

    def x(t: np.ndarray | float) -> np.ndarray:
        return left + (np.asarray(t) / span) * cols

    for tx, ty, text, fs in header.title:
        draw.text((tx, ty), text, fill=(20, 20, 20), font=_font(fs))
    _legend(draw, header, [_colour(i) for i in range(rows)])
    row_font = _font(min(16, max(10, bar - 2)))
    label_font = _font(min(13, max(9, lane - 4)))
    for i, r in enumerate(result.robots):
        tl = result.timelines[r.name]
        y0 = top + pitch * i
        y1 = y0 + bar
        draw.text((15, y0 + (bar - 16) / 2 if bar >= 16 else y0), f"robot {r.name}", fill=_colour(i), font=row_font)
        printing, travel = _column_shares(tl, span, cols)
        for a, b in _true_runs(printing > 0):
            draw.rectangle([left + a, y0, left + b - 1, y0 + lane - 1], fill=_colour(i))
        tall = np.ceil(np.minimum(travel, 1.0) * strip - 1e-9).astype(int)  # the travel's share, pixels
        if tall.any():
            band = np.arange(strip)[:, None] >= strip - tall[None, :]
            img.paste(Image.fromarray(np.where(band[..., None], np.array(TRAVEL_COLOUR, np.uint8),
                                               np.array(BACKGROUND, np.uint8)).astype(np.uint8)),
                      (left, y1 - strip))
        for a, b, _ in tl.waits:
            if b > a:
                draw.rectangle([float(x(a)), y0, float(x(b)), y1 - 1], fill=WAIT_COLOUR)
        for cid, t_a, t_b in _chunk_spans(r, tl):
            xa, xb = float(x(t_a)), float(x(t_b))
            if cid in marked:  # around the bar and its travel strip, a white line apart from a red robot's bar
                frame = [xa - 3, y0 - 3, max(xb, xa + 1) + 2, y1 + 2]
                draw.rectangle(frame, outline=CRITICAL_COLOUR, width=2)
                draw.rectangle([frame[0] + 2, frame[1] + 2, frame[2] - 2, frame[3] - 2], outline=(255, 255, 255))
            box = draw.textbbox((0, 0), cid, font=label_font)
            if xb - xa > box[2] - box[0] + 6 and lane >= 12:
                draw.text(((xa + xb) / 2, y0 + lane / 2), cid, fill=(255, 255, 255), font=label_font, anchor="mm")
    # time axis: labels centred on their ticks, the last kept inside the picture
    y = top + pitch * rows
    draw.line([(left, y), (right, y)], fill=(60, 60, 60))
    axis_font = _font(13)
    step = _nice_step(span / 8)  # about 8 labels, fewer where they would touch (a narrow picture)
    while step < span and step / span * cols < 16 + max(
            draw.textlength(_axis_label(k * step, span), font=axis_font) for k in range(int(span // step) + 1)):
        step = _nice_step(step * 1.001)
    for k in range(int(span // step) + 1):
        t = k * step
        xt = float(x(t))
        draw.line([(xt, y), (xt, y + 6)], fill=(60, 60, 60))
        text = _axis_label(t, span)
        half = draw.textlength(text, font=axis_font) / 2
        draw.text((min(max(xt, half + 2), w - half - 2), y + 8), text, fill=(60, 60, 60), font=axis_font,
                  anchor="ma")
    if lower_bound:
        xb = float(x(lower_bound))
        for ya in range(top - 6, y, 12):  # dashed
            draw.line([(xb, ya), (xb, min(ya + 6, y))], fill=BOUND_COLOUR, width=2)
    info = PngInfo()
    info.add_text("Title", "   ".join(title))
    path = Path(path)
    img.save(path, format="PNG", pnginfo=info)
    return path


def _column_shares(tl, span: float, cols: int) -> tuple[np.ndarray, np.ndarray]:
    """Per pixel column of a Gantt row (``cols`` columns over ``span`` s): the share of its time
    the robot printed, and travelled (moves with the tool off), a block of moves at a time."""
    shares = np.zeros((2, cols))
    scale = cols / span
    for c in range(0, len(tl.t0), BLOCK_MOVES):
        a, b = tl.t0[c:c + BLOCK_MOVES] * scale, tl.t1[c:c + BLOCK_MOVES] * scale
        on = tl.on[c:c + BLOCK_MOVES]
        for k, sel in enumerate((on, ~on)):
            shares[k] += _coverage(a[sel], b[sel], cols)
    return shares[0], shares[1]


def _coverage(a: np.ndarray, b: np.ndarray, n: int) -> np.ndarray:
    """How much of each unit column ``[c, c + 1)``, ``c < n``, the intervals ``[a, b]`` (within
    ``[0, n]``) cover: an interval inside one column adds its length there; one across several
    adds its part to its first and last column and 1 to each between (a difference array)."""
    a, b = np.clip(a, 0, n), np.clip(b, 0, n)
    ia = np.minimum(np.floor(a), n - 1).astype(np.int64)
    ib = np.minimum(np.floor(b), n - 1).astype(np.int64)
    same = ia == ib
    out = np.zeros(n)  # (bincount of nothing is of integers)
    out += np.bincount(ia[same], weights=b[same] - a[same], minlength=n)
    ia, ib, a, b = ia[~same], ib[~same], a[~same], b[~same]
    out += np.bincount(ia, weights=ia + 1 - a, minlength=n) + np.bincount(ib, weights=b - ib, minlength=n)
    between = np.bincount(ia + 1, minlength=n + 1) - np.bincount(ib, minlength=n + 1)
    return out + np.cumsum(between)[:n]


def _true_runs(mask: np.ndarray) -> list[tuple[int, int]]:
    """``(start, end)`` of each run of True in ``mask`` (end exclusive)."""
    edges = np.flatnonzero(np.diff(np.concatenate([[False], mask, [False]]).astype(np.int8)))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _chunk_spans(robot, tl) -> list[tuple[str, float, float]]:
    """``(chunk id, first print start, last print end)`` of each chunk the robot prints, from its
    program's chunk column (the moves between chunks, chunk -1, belong to none)."""
    prog = robot.program
    if not len(tl.index) or not prog.chunks:
        return []
    first, last = {}, {}  # per chunk: its earliest print start and latest print end, a block of moves at a time
    for a in range(0, len(tl.index), BLOCK_MOVES):
        chunk = prog.chunk[tl.index[a:a + BLOCK_MOVES]]
        sel = tl.on[a:a + BLOCK_MOVES] & (chunk >= 0)
        k, t0, t1 = chunk[sel], tl.t0[a:a + BLOCK_MOVES][sel], tl.t1[a:a + BLOCK_MOVES][sel]
        for c in np.unique(k).tolist():
            m = k == c
            first[c] = min(first.get(c, np.inf), float(t0[m].min()))
            last[c] = max(last.get(c, -np.inf), float(t1[m].max()))
    return [(prog.chunks[c], first[c], last[c]) for c in sorted(first)]


def _runs(bars) -> list[tuple[float, float]]:
    """Intervals ``[a, b]`` (``bars``: pairs of arrays ``a``, ``b``, one after the other, sorted
    by ``a``) merged where they touch within a pixel: a run ends where the next interval starts
    more than a pixel after the furthest end so far."""
    out: list[tuple[float, float]] = []
    lo, hi = None, -np.inf  # the run under way: its start; the furthest end so far
    for a, b in bars:
        if not len(a):
            continue
        top = np.maximum(np.maximum.accumulate(b), hi)  # the furthest end up to each interval
        before = np.concatenate([[hi], top[:-1]])  # ... and before it
        for s in np.flatnonzero(a > before + 1.0).tolist():  # intervals that start a run
            if lo is not None:
                out.append((lo, float(before[s])))
            lo = float(a[s])
        hi = top[-1]
    if lo is not None:
        out.append((lo, float(hi)))
    return out


def _nice_step(raw: float) -> float:
    """The time axis's step, s: the first of 1 s ... 12 h at least ``raw``, then 1, 2, 5, 10, 20,
    50 ... days."""
    for s in (1, 2, 5, 10, 15, 30, 60, 120, 300, 600, 900, 1800, 3600, 7200, 10800, 21600, 43200, 86400):
        if s >= raw:
            return float(s)
    days = raw / DAY
    mag = 10 ** math.floor(math.log10(days))
    return DAY * next(m * mag for m in (1, 2, 5, 10) if m * mag >= days)


def _axis_label(t: float, span: float) -> str:
    """A time axis label: ``H:MM:SS`` on an axis shorter than a day, else days: ``15 d``,
    ``1 d 12:00`` (seconds only when there are any)."""
    if span < DAY:
        return _hms(t)
    d, s = divmod(int(round(t)), int(DAY))
    if not s:
        return f"{d} d"
    return f"{d} d {s // 3600:02d}:{s % 3600 // 60:02d}" + (f":{s % 60:02d}" if s % 60 else "")


__all__ = ["GanttHeader", "frame_times", "gantt_header", "gantt_height", "gantt_title", "gif_delays",
           "render_animation", "render_gantt", "render_snapshot"]
