"""``make fuzz``: hypothesis-driven fuzzing of every reader of user files (issue 12, deliverable 8).

Targets, each fed random bytes and mutations of small valid files (bytes flipped, inserted,
deleted, duplicated, cut; hostile tokens spliced in: NaN, 1e308, Unicode digits, CR, NUL, huge
digit runs, 0-based indices ...):

* ``mesh``     :func:`cooprint.io.mesh.load_mesh` on ``.stl`` (binary, ASCII), ``.obj``, ``.ply``
  (ASCII, binary), ``.3mf``, each also ``.gz``;
* ``coop``     :func:`cooprint.program.parse_coop` (and :func:`read_coop` on a file);
* ``gcode``    :func:`cooprint.simulation.inputs.read_gcode`;
* ``manifest`` :func:`cooprint.simulation.inputs.load_manifest` (a TOML manifest and its programs).

The contract: every input is either read or refused with a :class:`~cooprint.errors.UserError`;
any other exception, a warning (a second line on stderr) or an input that takes more than
``--slow`` seconds is a failure, recorded with a reproducer in ``--failures`` (default
``out/fuzz``). The last line is the summary with the counts; the exit code is 1 when anything
failed. Failures are collected, not shrunk (``--shrink`` raises at the first, so that hypothesis
shrinks it).

    python benchmarks/fuzz.py --inputs 100000 --jobs 2
"""

from __future__ import annotations

import argparse
import gzip
import hashlib
import io
import json
import resource
import sys
import tempfile
import time
import traceback
import warnings
import zipfile
from collections import Counter
from pathlib import Path

from hypothesis import HealthCheck, Phase, given, settings
from hypothesis import seed as hypothesis_seed
from hypothesis import strategies as st

from cooprint.errors import UserError

TARGETS = ("mesh", "coop", "gcode", "manifest")

# ----------------------------------------------------------------------------------------------
# seeds: small valid inputs of each kind

TETRA_V = b"v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\n"
TETRA_F = b"f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
COOP = b"""; cooprint-coop/1 program for robot A
MOVE 0.000, 0.000, 5.000
;@chunk C
;@layer 0 0.2
;@path outer-perimeter 0.45
TOOL ON
MOVE 10.000, 0.000, 0.200
MOVE 10, 10 0.2
move 0,10,0.2 ; a comment
TOOL OFF
NOTIFY C
WAIT B:1, C
;@layer -
;@path travel 0
;@chunk -
MOVE 0, 0, 5
NOTIFY
"""
GCODE = b"""; generated
G21
G90
M82
G92 E0
G28
G1 Z0.2 F1200
G1 X10 Y0 E1.0 F1800
G1 X10 Y10 E2.0
G0 X0 Y0 F7200
M83
G1 X5 Y5 E0.5
G1 E-0.8 F2100
G91
G1 X1 Y1 Z0.2
G90
M0 WAIT C
M118 NOTIFY C
"""
MANIFEST = b"""[robot]
max_print_speed = 40.0
[slicing]
layer_height = 0.2
perimeter_speed = 45.0
[[robots]]
name = "A"
program = "A.coop"
start = [0.0, 0.0, 5.0]
facing_deg = 90.0
[[robots]]
name = "B"
program = "B.coop"
facing_deg = 270
[profiles.B]
max_print_speed = 20.0
body_width = 400.0
"""


def _mesh_seeds() -> list[tuple[str, bytes]]:
    """(extension, bytes) of a tetrahedron / cube in each format."""
    import trimesh

    cube = trimesh.creation.box((20.0, 20.0, 20.0))
    text = cube.export(file_type="stl_ascii")
    seeds = [("stl", cube.export(file_type="stl")), ("stl", text.encode() if isinstance(text, str) else text),
             ("obj", TETRA_V + TETRA_F), ("obj", TETRA_V + b"vt 0 0\nf 1/1 3/1 2/1\nf -4 -3 -1\nf 1 4 3\nf 2//1 3 4\n"),
             ("ply", cube.export(file_type="ply", encoding="binary")),
             ("ply", cube.export(file_type="ply", encoding="ascii")), ("3mf", cube.export(file_type="3mf"))]
    return seeds + [(ext + ".gz", gzip.compress(data, mtime=0)) for ext, data in seeds]


#: Tokens spliced into text inputs: what hostile files hold.
TOKENS = [b"nan", b"-inf", b"inf", b"1e308", b"-1e308", b"1e999", b"1000001", b"999999999999999", b"0", b"-1",
          b"-0", b"0x10", b"1_000", "\uff11".encode(), "\u0663".encode(), "\u2028".encode(), b"\r", b"\r\n", b"\n",
          b"\x00", b"\xff", b"\t", b",", b",,", b" ", b";", b";@", b"#", b"-", b".", b"e", b"1" * 40,
          b"9" * 400, b"MOVE", b"TOOL ON", b"NOTIFY", b"WAIT", b";@layer 0 0.2", b";@path skin 0.4",
          b";@chunk C", b"v 1 2", b"f 0 1 2", b"f 1 2", b"vertex 1 2 3", b"facet", b"endloop", b"solid",
          b"endsolid", b"element vertex 99999999999", b"end_header", b"property list uchar int", b"G1 X",
          b"G92", b"G91", b"M83", b"F0", b"E", b"[[robots]]", b"start = [1e300, 0, 0]", b'program = "/"',
          b"facing_deg = nan", b"name = 1", b"=", b"[", b"]", b'"', b"{"]


@st.composite
def mutated(draw, seeds: list[bytes]) -> bytes:
    """A seed changed by one to eight mutations."""
    data = bytearray(draw(st.sampled_from(seeds)))
    for _ in range(draw(st.integers(1, 8))):
        op = draw(st.integers(0, 6))
        pos = draw(st.integers(0, len(data)))
        if op == 0 and data:  # flip a byte
            data[min(pos, len(data) - 1)] = draw(st.integers(0, 255))
        elif op == 1:  # splice a hostile token
            data[pos:pos] = draw(st.sampled_from(TOKENS))
        elif op == 2:  # delete a run
            del data[pos:pos + draw(st.integers(1, 64))]
        elif op == 3:  # cut the end
            del data[pos:]
        elif op == 4:  # repeat a run
            run = data[pos:pos + draw(st.integers(1, 200))]
            data[pos:pos] = run * draw(st.integers(1, 20))
        elif op == 5:  # replace a token (a word between blanks) by a hostile one
            end = pos
            while end < len(data) and data[end] not in b" \t\n,":
                end += 1
            data[pos:end] = draw(st.sampled_from(TOKENS))
        else:  # random bytes
            data[pos:pos] = draw(st.binary(max_size=32))
    return bytes(data)


def inputs(seeds: list[bytes]) -> st.SearchStrategy[bytes]:
    """Random bytes, random text, and (mostly) mutated seeds."""
    return st.one_of(st.binary(max_size=600), st.text(max_size=300).map(lambda s: s.encode("utf-8", "replace")),
                     mutated(seeds), mutated(seeds), mutated(seeds), mutated(seeds))


# ----------------------------------------------------------------------------------------------
# one input through one reader


class Tally:
    """Counts of one target and its failures (kind -> count, with one reproducer each)."""

    def __init__(self, target: str, folder: Path, slow: float, shrink: bool):
        self.target, self.folder, self.slow, self.shrink = target, folder, slow, shrink
        self.counts: Counter[str] = Counter()
        self.failures: Counter[str] = Counter()
        self.examples: dict[str, str] = {}

    def run(self, call, data: bytes, name: str) -> None:
        """``call()`` reads the input: count it as parsed or refused, or record the failure."""
        t0 = time.perf_counter()
        failure = None
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                call()
                outcome = "parsed"
            except UserError as exc:
                outcome = "refused"
                if "\n" in str(exc):
                    failure = f"UserError of more than one line: {str(exc)[:120]!r}"
            except (KeyboardInterrupt, SystemExit):
                raise
            except BaseException as exc:  # noqa: BLE001 - any other exception is what is looked for
                outcome = "crash"
                tb = traceback.extract_tb(exc.__traceback__)
                where = next((f"{Path(f.filename).name}:{f.lineno}" for f in reversed(tb)
                              if "cooprint" in f.filename), "?")
                failure = f"{type(exc).__name__} at {where}: {str(exc)[:100]}"
                if self.shrink:
                    raise
        if caught and failure is None:
            w = caught[0]
            failure = f"warning {w.category.__name__} at {Path(w.filename).name}:{w.lineno}: {str(w.message)[:80]}"
        dt = time.perf_counter() - t0
        if failure is None and dt > self.slow:
            failure = f"slow: {dt:.1f} s"
        self.counts[outcome] += 1
        if failure is not None:
            self.counts["failed"] += 1
            key = failure.split(":")[0] + ":" + failure.split(":")[1] if failure.count(":") > 1 else failure
            self.failures[key] += 1
            if key not in self.examples:
                digest = hashlib.sha1(data).hexdigest()[:12]
                path = self.folder / f"{self.target}-{digest}-{name}"
                path.write_bytes(data)
                self.examples[key] = f"{failure} [{path}]"


def _mesh_target(tally: Tally, tmp: Path):
    seeds = _mesh_seeds()
    exts = sorted({e for e, _ in seeds})
    from cooprint.io.mesh import load_mesh

    @st.composite
    def mesh_input(draw):
        ext = draw(st.sampled_from(exts))
        own = [d for e, d in seeds if e == ext]
        if ext.endswith(".gz") and draw(st.booleans()):  # a mutation under the compression
            inner = ext[:-3]
            raw = draw(mutated([d for e, d in seeds if e == inner]))
            return ext, gzip.compress(raw, mtime=0)
        if ext == "3mf" and draw(st.booleans()):  # a mutation inside the zip
            z = zipfile.ZipFile(io.BytesIO(own[0]))
            buf = io.BytesIO()
            with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as out:
                for n in z.namelist():
                    data = z.read(n)
                    out.writestr(n, draw(mutated([data])) if n.endswith(".model") else data)
            return ext, buf.getvalue()
        return ext, draw(inputs(own))

    for k, (ext, data) in enumerate(seeds):  # imports and compiled code loaded before any input's clock runs
        (tmp / f"warm{k}.{ext}").write_bytes(data)
        load_mesh(tmp / f"warm{k}.{ext}")

    def one(item):
        ext, data = item
        path = tmp / f"m.{ext}"
        path.write_bytes(data)
        tally.run(lambda: load_mesh(path), data, f"m.{ext}")

    return mesh_input(), one


def _coop_target(tally: Tally, tmp: Path):
    from cooprint.program.commands import parse_coop, read_coop

    parse_coop(COOP, "A")  # warm: the sweep's compiled code loaded
    def one(data: bytes):
        if data[:1] == b"M":  # one in a few through the file reader (mmap)
            path = tmp / "A.coop"
            path.write_bytes(data)
            tally.run(lambda: read_coop(path), data, "A.coop")
        else:
            tally.run(lambda: parse_coop(data, "A", "A.coop"), data, "A.coop")

    return inputs([COOP]), one


def _file_reader(tally: Tally, tmp: Path, name: str, read, seed: bytes):
    """Each input written to ``tmp / name`` and read by ``read(path)``; one warm-up read of
    ``seed`` first (imports and compiled code are not timed)."""
    (tmp / f"warm_{name}").write_bytes(seed)
    read(tmp / f"warm_{name}")

    def one(data: bytes):
        path = tmp / name
        path.write_bytes(data)
        tally.run(lambda: read(path), data, name)

    return inputs([seed]), one


def _gcode_target(tally: Tally, tmp: Path):
    from cooprint.simulation.inputs import read_gcode

    return _file_reader(tally, tmp, "A.gcode", read_gcode, GCODE)


def _manifest_target(tally: Tally, tmp: Path):
    from cooprint.simulation.inputs import load_manifest

    (tmp / "A.coop").write_bytes(COOP)
    (tmp / "B.coop").write_bytes(b"WAIT C\nMOVE 0, 0, 5\n")
    return _file_reader(tally, tmp, "m.toml", load_manifest, MANIFEST)


MAKERS = {"mesh": _mesh_target, "coop": _coop_target, "gcode": _gcode_target, "manifest": _manifest_target}


def fuzz_target(target: str, n: int, seed: int, folder: str, slow: float, shrink: bool) -> dict:
    """Run ``n`` inputs through one target; return its counts, failures and time."""
    resource.setrlimit(resource.RLIMIT_AS, (6 * 1024**3, resource.RLIM_INFINITY))  # a blow-up is a MemoryError
    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    tally = Tally(target, out, slow, shrink)
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix=f"cooprint-fuzz-{target}-") as tmp:
        strategy, one = MAKERS[target](tally, Path(tmp))

        @settings(max_examples=n, deadline=None, database=None, derandomize=False, print_blob=False,
                  phases=[Phase.generate] + ([Phase.shrink] if shrink else []),
                  suppress_health_check=list(HealthCheck))
        @given(strategy)
        def run(item):
            one(item)

        hypothesis_seed(seed)(run)()  # reproducible: the seed names the inputs
    return {"target": target, "counts": dict(tally.counts), "failures": dict(tally.failures),
            "examples": tally.examples, "seconds": time.perf_counter() - t0}


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--inputs", type=int, default=100_000, help="Inputs in total, shared by the targets.")
    ap.add_argument("--targets", default=",".join(TARGETS), help="Comma-separated: " + ", ".join(TARGETS))
    ap.add_argument("--jobs", type=int, default=2, help="Processes.")
    ap.add_argument("--seed", type=int, default=12)
    ap.add_argument("--slow", type=float, default=5.0, help="Seconds an input may take.")
    ap.add_argument("--failures", default="out/fuzz", help="Folder for reproducers.")
    ap.add_argument("--shrink", action="store_true", help="Stop at the first crash and let hypothesis shrink it.")
    args = ap.parse_args(argv)
    targets = [t for t in args.targets.split(",") if t]
    unknown = set(targets) - set(TARGETS)
    if unknown:
        ap.error(f"unknown target(s) {', '.join(sorted(unknown))}")
    # work items: each target in chunks, so that the jobs share the work evenly
    per = args.inputs // len(targets)
    chunk = max(1, min(per, 5_000))
    items = [(t, min(chunk, per - k), args.seed + 1000 * i + k // chunk, args.failures, args.slow, args.shrink)
             for i, t in enumerate(targets) for k in range(0, per, chunk)]
    t0 = time.time()
    if args.jobs > 1 and not args.shrink:
        import multiprocessing as mp

        with mp.get_context("fork").Pool(args.jobs) as pool:
            results = pool.starmap(fuzz_target, items, chunksize=1)
    else:
        results = [fuzz_target(*item) for item in items]
    total: Counter[str] = Counter()
    by_target: dict[str, Counter[str]] = {t: Counter() for t in targets}
    failures: Counter[str] = Counter()
    examples: dict[str, str] = {}
    for r in results:
        total.update(r["counts"])
        by_target[r["target"]].update(r["counts"])
        for k, v in r["failures"].items():
            failures[f"{r['target']}: {k}"] += v
        for k, v in r["examples"].items():
            examples.setdefault(f"{r['target']}: {k}", v)
    for key, count in failures.most_common():
        print(f"FAIL {count:6d} x {examples[key]}")
    summary = {t: {"inputs": sum(c[k] for k in ("parsed", "refused", "crash")), **c} for t, c in by_target.items()}
    Path(args.failures).mkdir(parents=True, exist_ok=True)
    (Path(args.failures) / "summary.json").write_text(json.dumps(
        {"inputs": args.inputs, "seconds": time.time() - t0, "targets": summary,
         "failures": {k: [v, examples[k]] for k, v in failures.items()}}, indent=1))
    n = sum(total[k] for k in ("parsed", "refused", "crash"))
    parts = ", ".join(f"{t} {summary[t]['inputs']}" for t in targets)
    print(f"fuzz: {n} inputs ({parts}) in {time.time() - t0:.0f} s: {total['parsed']} parsed, {total['refused']} "
          f"refused with one line, {total['failed']} failures ({total['crash']} exceptions other than UserError, "
          f"{len(failures)} distinct)")
    return 1 if total["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
