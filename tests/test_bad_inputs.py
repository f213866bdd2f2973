"""The bad-input corpus (issue 12, deliverable 8): hundreds of generated hostile inputs, each
through the command line in-process, each refused by the reader or parser that should refuse
it: exit 2, one line naming the file (and line, where there is one), no traceback, nothing
written (:func:`badinput.assert_rejected`).

Mesh files of every format (binary and ASCII STL, OBJ, PLY, 3MF, each also gzipped) broken in
every way the hunt for failures found; ``.coop`` programs (bad, huge and Unicode numbers, bad
annotations, unknown words, control characters); ``render`` options asking for unbounded work.
"""

from __future__ import annotations

import gzip
import io
import struct
import zipfile

import numpy as np
import pytest
import trimesh

from badinput import assert_rejected

# ----------------------------------------------------------------------------------------------
# meshes


def _cube() -> trimesh.Trimesh:
    return trimesh.creation.box((20.0, 20.0, 20.0))


def _valid() -> dict[str, tuple[str, bytes]]:
    """A 20 mm cube in each format: kind -> (extension, bytes)."""
    tm = _cube()
    text = tm.export(file_type="stl_ascii")
    obj = tm.export(file_type="obj")
    return {"stl": ("stl", tm.export(file_type="stl")),
            "astl": ("stl", text.encode() if isinstance(text, str) else text),
            "obj": ("obj", obj.encode() if isinstance(obj, str) else obj),
            "ply": ("ply", tm.export(file_type="ply", encoding="binary")),
            "aply": ("ply", tm.export(file_type="ply", encoding="ascii")),
            "3mf": ("3mf", tm.export(file_type="3mf"))}


VALID = _valid()
GARBAGE = bytes(np.random.default_rng(7).integers(0, 256, 3000, dtype=np.uint8))
TETRA_V = b"v 0 0 0\nv 10 0 0\nv 0 10 0\nv 0 0 10\n"
TETRA_F = b"f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"
PLY_HEAD = (b"ply\nformat ascii 1.0\nelement vertex %d\nproperty float x\nproperty float y\nproperty float z\n"
            b"element face %d\nproperty list uchar int vertex_indices\nend_header\n")
PLY_BODY = b"0 0 0\n10 0 0\n0 10 0\n0 0 10\n3 0 2 1\n3 0 1 3\n3 0 3 2\n3 1 2 3\n"


def _stl_records(mutate) -> bytes:
    """The binary STL cube with its records changed by ``mutate(records)``."""
    data = VALID["stl"][1]
    rec = np.frombuffer(data[84:], dtype=[("n", "<f4", 3), ("v", "<f4", (3, 3)), ("a", "<u2")]).copy()
    mutate(rec)
    return data[:84] + rec.tobytes()


def _ascii_stl_vertex(value: str) -> bytes:
    """The ASCII STL cube with the first coordinate of its first vertex replaced by ``value``."""
    text = VALID["astl"][1].decode()
    head, rest = text.split("vertex ", 1)
    return (head + "vertex " + value + " " + rest.split(" ", 1)[1]).encode()


def _zip(members: dict[str, bytes]) -> bytes:
    buf = io.BytesIO()
    with zipfile.ZipFile(buf, "w", zipfile.ZIP_DEFLATED) as z:
        for name, data in members.items():
            z.writestr(name, data)
    return buf.getvalue()


def _3mf_model(old: bytes, new: bytes) -> bytes:
    """The 3MF cube with its model part's first ``old`` replaced by ``new``."""
    src = zipfile.ZipFile(io.BytesIO(VALID["3mf"][1]))
    return _zip({n: src.read(n).replace(old, new, 1) if n.endswith(".model") else src.read(n)
                 for n in src.namelist()})


def _mesh_cases() -> list[tuple[str, str, bytes, str | None]]:
    """(id, file name, bytes, a piece of the expected message or None)."""
    cases: list[tuple[str, str, bytes, str | None]] = []
    for kind, (ext, data) in VALID.items():
        cases += [
            (f"{kind}-empty", f"m.{ext}", b"", "file is empty"),
            (f"{kind}-blank", f"m.{ext}", b"  \n\t\n", "file is empty"),
            (f"{kind}-garbage", f"m.{ext}", GARBAGE, None),
            (f"{kind}-nul", f"m.{ext}", b"\0" * 600, None),
            (f"{kind}-gz-garbage", f"m.{ext}.gz", GARBAGE, "cannot read gzip"),
            (f"{kind}-gz-truncated", f"m.{ext}.gz", gzip.compress(data)[:-12], "cannot read gzip"),
            (f"{kind}-gz-of-gz", f"m.{ext}.gz", gzip.compress(gzip.compress(data)), None),
        ]
        cases += [(f"{kind}-truncated-{int(100 * f)}", f"m.{ext}", data[:int(len(data) * f)], None)
                  for f in (0.05, 0.5, 0.97)]
        cases.append((f"{kind}-truncated-gz", f"m.{ext}.gz", gzip.compress(data[:len(data) // 2]), None))
    stl = VALID["stl"][1]
    n = struct.unpack("<I", stl[80:84])[0]
    cases += [(f"stl-count-{lie}", "m.stl", stl[:80] + struct.pack("<I", lie) + stl[84:], f"header says {lie} triangles")
              for lie in (0, 1, n - 1, n + 1, 2**31, 2**32 - 1)]
    cases += [
        ("stl-header-only", "m.stl", stl[:84], "header says 12 triangles"),
        ("stl-short", "m.stl", stl[:50], "too short for a binary STL"),
        ("stl-nan", "m.stl", _stl_records(lambda r: r["v"].__setitem__((0, 0, 0), np.nan)), "NaN or infinite"),
        ("stl-inf", "m.stl", _stl_records(lambda r: r["v"].__setitem__((3, 1, 2), -np.inf)), "NaN or infinite"),
        ("stl-huge", "m.stl", _stl_records(lambda r: r["v"].__setitem__((0, 0, 0), 3e38)), "wrong units"),
        ("stl-flat", "m.stl", _stl_records(lambda r: r["v"].__setitem__((slice(None), slice(None), 2), 0.0)), None),
        ("stl-all-zero", "m.stl", _stl_records(lambda r: r["v"].__setitem__(slice(None), 0.0)), None),
        ("stl-open", "m.stl", stl[:80] + struct.pack("<I", n - 2) + stl[84:84 + 50 * (n - 2)], "not watertight"),
    ]
    for value in ("nan", "inf", "-inf", "1e400", "1e308", "1000001", "0x10", "\uff11", "1_0", "1,5"):
        needle = (f"coordinate '{value}' is NaN or infinite" if "n" in value and "x" not in value
                  else f"coordinate {value} is beyond 1e+06 mm" if value[0] == "1" and value.isdigit() or "e" in value
                  else f"'{value}' is not a number")
        cases.append((f"astl-vertex-{value.encode('unicode_escape').decode()}", "m.stl", _ascii_stl_vertex(value),
                      "m.stl:4: " + needle))
    text = VALID["astl"][1].decode()
    cases += [
        ("astl-two-coordinates", "m.stl", text.replace("vertex", "vertex 1 2\n#", 1).encode(), "got 2"),
        ("astl-four-vertices", "m.stl", text.replace("endloop", "vertex 1 1 1\nendloop", 1).encode(),
         "a loop of 4 vertices"),
        ("astl-no-endsolid", "m.stl", text.rsplit("endsolid", 1)[0].encode(), "no 'endsolid'"),
        ("astl-no-facet", "m.stl", b"solid x\nendsolid x\n", "m.stl: empty file (an ASCII STL without triangles)"),
        ("astl-one-facet", "m.stl", b"solid x\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\nvertex 1 0 0\n"
         b"vertex 0 1 0\nendloop\nendfacet\nendsolid x\n", "not a solid"),
        ("astl-not-utf8", "m.stl", text.encode()[:60] + b"\xff\xfe" + text.encode()[62:], "not UTF-8"),
    ]
    cases += [
        ("obj-0-based", "m.obj", TETRA_V + b"f 0 2 1\nf 0 1 3\nf 0 3 2\nf 1 2 3\n",
         "m.obj:5: vertex index 0: OBJ indices start at 1"),
        ("obj-one-0-index", "m.obj", TETRA_V + TETRA_F.replace(b"f 2 3 4", b"f 0 3 4"), "m.obj:8: vertex index 0"),
        ("obj-2-coordinates", "m.obj", b"v 0 0\n" + TETRA_V[6:] + TETRA_F, "m.obj:1: a vertex needs 3 coordinates"),
        ("obj-1-coordinate", "m.obj", b"v 0\n" + TETRA_V[6:] + TETRA_F, "got 1"),
        ("obj-bare-v", "m.obj", b"v\n" + TETRA_V + TETRA_F, "got 0"),
        ("obj-no-faces", "m.obj", TETRA_V, "no triangles"),
        ("obj-faces-only", "m.obj", TETRA_F, "vertex index 1 but the file has 0 vertices"),
        ("obj-index-past-end", "m.obj", TETRA_V + TETRA_F.replace(b"f 2 3 4", b"f 2 3 9"), "m.obj:8: vertex index 9"),
        ("obj-negative-past-start", "m.obj", TETRA_V + b"f -5 -2 -3\n" + TETRA_F[8:], "reaches before the first"),
        ("obj-2-index-face", "m.obj", TETRA_V + b"f 1 3\n" + TETRA_F[8:], "a face needs at least 3 vertices"),
        ("obj-nan", "m.obj", b"v nan 0 0\n" + TETRA_V[8:] + TETRA_F, "NaN or infinite"),
        ("obj-inf", "m.obj", b"v 0 -inf 0\n" + TETRA_V[8:] + TETRA_F, "NaN or infinite"),
        ("obj-huge", "m.obj", b"v 1e300 0 0\n" + TETRA_V[8:] + TETRA_F, "beyond 1e+06 mm"),
        ("obj-word", "m.obj", b"v a b c\n" + TETRA_V[8:] + TETRA_F, "'a' is not a number"),
        ("obj-full-width-digit", "m.obj", "v \uff11 0 0\n".encode() + TETRA_V[8:] + TETRA_F, "is not a number"),
        ("obj-underscore", "m.obj", b"v 1_0 0 0\n" + TETRA_V[8:] + TETRA_F, "'1_0' is not a number"),
        ("obj-float-index", "m.obj", TETRA_V + b"f 1.5 3 2\n" + TETRA_F[8:], "'1.5' is not a vertex index"),
        ("obj-bad-texture-index", "m.obj", TETRA_V + b"f 1/a 3 2\n" + TETRA_F[8:], "'1/a' is not a vertex index"),
        ("obj-huge-index", "m.obj", TETRA_V + b"f 99999999999999999999 3 2\n" + TETRA_F[8:], "but the file has 4"),
        ("obj-unknown-statement", "m.obj", b"hello world\n" + TETRA_V + TETRA_F, "unknown OBJ statement 'hello'"),
        ("obj-not-utf8", "m.obj", TETRA_V + b"# \xff\n" + TETRA_F, "m.obj:5: not UTF-8"),
        ("obj-long-token", "m.obj", b"v " + b"1" * 200_000 + b" 0 0\n" + TETRA_V[6:] + TETRA_F, "(200000 characters)"),
        ("obj-open", "m.obj", TETRA_V + TETRA_F[:-8], "not a solid"),
        ("ply-huge-vertex-count", "m.ply", PLY_HEAD % (10**12, 4) + PLY_BODY, "PLY header declares"),
        ("ply-huge-face-count", "m.ply", PLY_HEAD % (4, 10**12) + PLY_BODY, "PLY header declares"),
        ("ply-negative-count", "m.ply", PLY_HEAD % (-4, 4) + PLY_BODY, "m.ply:3: expected 'element NAME COUNT'"),
        ("ply-one-more-vertex", "m.ply", PLY_HEAD % (5, 4) + PLY_BODY, "but the body has 8 lines"),
        ("ply-index-past-end", "m.ply", PLY_HEAD % (4, 4) + PLY_BODY.replace(b"3 1 2 3", b"3 1 2 9"), "out of range"),
        ("ply-negative-index", "m.ply", PLY_HEAD % (4, 4) + PLY_BODY.replace(b"3 1 2 3", b"3 1 2 -1"), "out of range"),
        ("ply-nan", "m.ply", PLY_HEAD % (4, 4) + PLY_BODY.replace(b"10 0 0", b"nan 0 0"), "NaN or infinite"),
        ("ply-no-end-header", "m.ply", (PLY_HEAD % (4, 4)).replace(b"end_header\n", b"") + PLY_BODY, "not a PLY"),
        ("ply-unknown-format", "m.ply", (PLY_HEAD % (4, 4)).replace(b"ascii", b"weird") + PLY_BODY,
         "unknown PLY format"),
        ("ply-unknown-type", "m.ply", (PLY_HEAD % (4, 4)).replace(b"float x", b"banana x") + PLY_BODY, "PLY type"),
        ("ply-header-only", "m.ply", b"ply\n", "not a PLY"),
        ("ply-binary-huge-count", "m.ply", VALID["ply"][1].replace(b"element vertex 8", b"element vertex 99999999", 1),
         "more than the"),
        ("ply-binary-truncated-body", "m.ply", VALID["ply"][1][:-40], None),
        ("3mf-not-a-zip", "m.3mf", b"PK\x03\x04" + GARBAGE, "not a 3MF file"),
        ("3mf-no-model", "m.3mf", _zip({"x.txt": b"hello"}), "no model part"),
        ("3mf-bad-xml", "m.3mf", _zip({"3D/3dmodel.model": b"<<<<"}), "cannot read as 3MF"),
        ("3mf-nan", "m.3mf", _3mf_model(b'x="', b'x="nan" y0="'), "NaN or infinite"),
        ("3mf-huge", "m.3mf", _3mf_model(b'x="', b'x="1e300" y0="'), "wrong units"),
        ("3mf-index-past-end", "m.3mf", _3mf_model(b'v1="', b'v1="999'), "out of range"),
        ("3mf-negative-index", "m.3mf", _3mf_model(b'v1="', b'v1="-'), "out of range"),
    ]
    return cases


MESH_CASES = _mesh_cases()
#: Every mesh case goes through one command (in turn), so that each command sees every kind.
COMMANDS = ("info", "chunk", "slice", "run")


def _mesh_args(command: str, mesh, out) -> list:
    if command == "info":
        return ["info", mesh]
    if command == "slice":
        return ["slice", mesh, "--out", out / "m.gcode", "-q"]
    return [command, mesh, "--out", out / "job", "-q", "--no-picture"]


@pytest.mark.parametrize("case", range(len(MESH_CASES)), ids=[c[0] for c in MESH_CASES])
def test_a_broken_mesh_is_refused_in_one_line(tmp_path, capsys, case):
    _, name, data, needle = MESH_CASES[case]
    src, out = tmp_path / "in", tmp_path / "out"
    src.mkdir()
    out.mkdir()
    (src / name).write_bytes(data)
    line = assert_rejected(_mesh_args(COMMANDS[case % len(COMMANDS)], src / name, out), capsys, watch=[tmp_path],
                           contains=needle)
    assert str(src / name) in line


def test_the_valid_meshes_of_the_corpus_load(tmp_path):
    """The corpus breaks valid files: each of them loads as the same cube (and an OBJ with
    negative indices, quads and v/t/n references reads as OBJ says)."""
    from cooprint.io.mesh import load_mesh

    files = {f"m_{kind}.{ext}": data for kind, (ext, data) in VALID.items()}
    files["neg.obj"] = TETRA_V + b"f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n"
    files["refs.obj"] = TETRA_V + b"vt 0 0\nvn 0 0 1\nf 1/1/1 3/1/1 2/1/1\nf 1//1 2//1 4//1\nf 1/1 4/1 3/1\nf 2 3 4\n"
    files["quads.obj"] = (b"v 0 0 0\nv 10 0 0\nv 10 10 0\nv 0 10 0\nv 0 0 10\nv 10 0 10\nv 10 10 10\nv 0 10 10\n"
                          b"f 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n")
    files["tetra.ply"] = PLY_HEAD % (4, 4) + PLY_BODY
    for name, data in files.items():
        (tmp_path / name).write_bytes(data)
        solid = load_mesh(tmp_path / name)
        want = 1000 / 6 if name in ("neg.obj", "refs.obj", "tetra.ply") else (1000.0 if name == "quads.obj" else 8000.0)
        assert solid.volume == pytest.approx(want, rel=1e-9), name


# ----------------------------------------------------------------------------------------------
# .coop programs

COOP = """MOVE 0, 0, 5
;@chunk C
;@layer 0 0.2
;@path perimeter 0.45
TOOL ON
MOVE 10, 0, 0.2
MOVE 10, 10, 0.2
MOVE 0, 10, 0.2
TOOL OFF
NOTIFY C
"""
MANIFEST = '[[robots]]\nname = "A"\nprogram = "A.coop"\nstart = [0.0, 0.0, 5.0]\nfacing_deg = 90.0\n'


def _coop_cases() -> list[tuple[str, str, str | None]]:
    """(id, program text, a piece of the expected message)."""
    at_move = "MOVE 10, 10, 0.2"  # line 7
    cases = []
    for num, needle in (("1e308", "A.coop:7:6: coordinate 1e308 is beyond +-1e+06 mm"),
                        ("-1e308", "coordinate -1e308 is beyond"), ("1e7", "coordinate 1e7 is beyond"),
                        ("1000000.5", "coordinate 1000000.5 is beyond"),
                        ("999999999999999", "coordinate 999999999999999 is beyond"),
                        ("\uff11", "A.coop:7:6: '\uff11' is not a number (ASCII digits"),
                        ("\u0663", "is not a number"), ("1\uff10", "is not a number"), ("\U0001d7ce", "is not a number"),
                        ("1_000", "'1_000' is not a number"), ("nan", "'nan' is not a finite number"),
                        ("-inf", "'-inf' is not a finite number"), ("infinity", "is not a finite number"),
                        ("1e999", "'1e999' is not a finite number"), ("0x10", "'0x10' is not a number"),
                        ("1e", "'1e' is not a number"), (".", "'.' is not a number"), ("-", "'-' is not a number"),
                        ("1.2.3", "is not a number"), ("1" * 400, "(400 characters)"),
                        ("x" * 10_000_000, "(10000000 characters)")):
        cases.append((f"move-{num[:12].encode('unicode_escape').decode()}-{len(num)}",
                      COOP.replace(at_move, f"MOVE {num}, 10, 0.2"), needle))
    at_ann = ";@path perimeter 0.45"  # line 4
    for ann, needle in ((";@chunk", "A.coop:4:3: malformed annotation ';@chunk'"), (";@chunk a b", "malformed"),
                        (";@chunk a$b", ";@chunk ID 'a$b'"), (";@chunk " + "c" * 100_000, "(100000 characters)"),
                        (";@chunk \u2460", ";@chunk ID"), (";@layer", "malformed annotation ';@layer'"),
                        (";@layer 0", "malformed"), (";@layer 0 0.2 7", "malformed"),
                        (";@layer -1 0.2", "A.coop:4:9: ;@layer INDEX '-1'"),
                        (";@layer \uff11 0.2", ";@layer INDEX"), (";@layer 1_0 0.2", ";@layer INDEX '1_0'"),
                        (";@layer 99999999999 0.2", ";@layer INDEX '99999999999'"),
                        (";@layer 0 0", "A.coop:4:11: ;@layer HEIGHT 0: expected mm above 0"),
                        (";@layer 0 -0.2", ";@layer HEIGHT -0.2"), (";@layer 0 nan", "'nan' is not a finite"),
                        (";@layer 0 inf", "'inf' is not a finite"), (";@layer 0 1e308", ";@layer HEIGHT 1e308"),
                        (";@layer 0 60", ";@layer HEIGHT 60"), (";@layer 0 \uff10.2", "is not a number"),
                        (";@path", "malformed annotation ';@path'"), (";@path wall 0.4", ";@path ROLE 'wall'"),
                        (";@path Perimeter 0.4", ";@path ROLE 'Perimeter'"),
                        (";@path perimeter nan", "is not a finite number"),
                        (";@path perimeter -1", ";@path WIDTH -1: expected mm from 0"),
                        (";@path perimeter inf", "is not a finite"), (";@path perimeter 1e308", ";@path WIDTH 1e308"),
                        (";@path perimeter 1e3", ";@path WIDTH 1e3"), (";@path perimeter \uff10.4", "is not a number"),
                        (";@path perimeter 0.4 extra", "malformed")):
        cases.append((f"ann-{ann[:28].encode('unicode_escape').decode()}-{len(ann)}", COOP.replace(at_ann, ann),
                      needle))
    cases += [
        ("unknown-word", COOP + "JUMP 1\n", "A.coop:11:1: unknown word 'JUMP'"),
        ("unknown-long-word", COOP + "J" * 10_000_000 + "\n", "(10000000 characters)"),
        ("move-two-numbers", COOP + "MOVE 1, 2\n", "MOVE needs 3 numbers"),
        ("move-four-numbers", COOP + "MOVE 1, 2, 3, 4\n", "extra token '4'"),
        ("move-double-comma", COOP + "MOVE 1,, 2, 3\n", "a comma where a number was expected"),
        ("tool-nothing", COOP + "TOOL\n", "TOOL needs ON or OFF"),
        ("tool-maybe", COOP + "TOOL MAYBE\n", "TOOL needs ON or OFF, got 'MAYBE'"),
        ("notify-two", COOP + "NOTIFY a b\n", "NOTIFY takes at most one event name"),
        ("wait-nothing", "WAIT\n" + COOP, "A.coop:1:6: WAIT needs at least one event name"),
        ("wait-bad-name", "WAIT a$b\n" + COOP, "'a$b' is not an event name"),
        ("wait-long-name", "WAIT " + "e" * 65 + "\n" + COOP, "is not an event name"),
        ("not-utf8", COOP + "MOVE 1, 2, \udcff\n", "not UTF-8 text"),
        ("nul-bytes", COOP + "\0\0\0\n", "control character U+0000"),
        ("cr-line-ends", COOP.replace("\n", "\r"), "A.coop:1:13: control character U+000D"),
        ("cr-line-ends-comment-first", "; header\r" + COOP.replace("\n", "\r"), "control character U+000D"),
        ("form-feed", COOP.replace(";@chunk C", ";@chunk C\f"), "control character U+000C"),
        ("line-separator", COOP.replace("\n", "\u2028", 2), "control character U+2028"),
        ("binary", GARBAGE.decode("latin-1"), None),
        # a leading byte-order mark is skipped; one anywhere else is a character of the line
        ("bom-then-bad-word", "\ufeff" + COOP + "JUMP 1\n", "A.coop:11:1: unknown word 'JUMP'"),
        ("bom-then-bad-move", "\ufeff" + "MOVE 1, 2\n" + COOP, "A.coop:1:10: MOVE needs 3 numbers"),
        ("second-bom", "\ufeff\ufeff" + COOP, "A.coop:1:1: unknown word"),
    ]
    return cases


COOP_CASES = _coop_cases()


def _write_program(folder, text: str) -> None:
    folder.mkdir()
    (folder / "A.coop").write_bytes(text.encode("utf-8", "surrogateescape"))
    (folder / "m.toml").write_text(MANIFEST)


@pytest.mark.parametrize("case", range(len(COOP_CASES)), ids=[c[0] for c in COOP_CASES])
def test_a_broken_program_is_refused_in_one_line(tmp_path, capsys, case):
    _, text, needle = COOP_CASES[case]
    _write_program(tmp_path / "in", text)
    (tmp_path / "out").mkdir()  # render --out FILE writes into a folder that exists
    if case % 4 == 3:  # render reads the same programs
        args = ["render", "--manifest", tmp_path / "in" / "m.toml", "--out", tmp_path / "out" / "x.png"]
    else:
        args = ["simulate", "--manifest", tmp_path / "in" / "m.toml", "--out", tmp_path / "out", "-q"]
    line = assert_rejected(args, capsys, watch=[tmp_path], contains=needle)
    assert "A.coop" in line


def test_a_program_with_a_byte_order_mark_reads_as_without(tmp_path):
    """Windows editors start UTF-8 files with a BOM: the compiled sweep and the line parser
    (an annotation with an odd spacing goes to the latter) both read past it."""
    from cooprint.program.commands import parse_coop, read_coop

    for text in (COOP, COOP.replace(";@layer 0 0.2", ";@layer  0   0.2"), ";@chunk C\n" + COOP):
        plain = parse_coop(text, "A")
        (tmp_path / "A.coop").write_bytes(b"\xef\xbb\xbf" + text.encode())
        marked = read_coop(tmp_path / "A.coop")
        assert parse_coop("\ufeff" + text, "A") == plain and marked == plain
        assert len(plain) == 7


def test_a_program_spanning_two_kilometres_simulates(tmp_path, capsys):
    """Issue 12: coordinates at the bound make a plan of 2 km: the checks finish (rasters and
    overhang bands bounded) instead of crashing or allocating terabytes."""
    from cooprint.cli import main

    _write_program(tmp_path / "in", "MOVE -999999, -999999, 0.2\nTOOL ON\nMOVE 999999, 999999, 0.2\n"
                                    "MOVE 999999, -999999, 0.2\n")
    assert main(["simulate", "--manifest", str(tmp_path / "in" / "m.toml"), "--out", str(tmp_path / "out"),
                 "-q"]) in (0, 1)
    assert (tmp_path / "out" / "sim" / "summary.json").is_file()


# ----------------------------------------------------------------------------------------------
# render options

RENDER_CASES = [
    (["--speedup", "0.001", "--fps", "120", "--format", "mp4"], "--speedup 0.001 over the"),
    (["--duration", "3600", "--fps", "120", "--format", "mp4"], "--duration 3600 s at --fps 120: 432,000 frames, more "
                                                                "than 20,000"),
    (["--duration", "200", "--fps", "120", "--format", "mp4"], "24,000 frames"),
    (["--duration", "60", "--fps", "24", "--format", "gif"], "1,440 frames, more than 1,000 for a GIF"),
    (["--speedup", "0.0011", "--fps", "2", "--format", "gif"], "--speedup 0.0011"),
    (["--fps", "nan", "--format", "mp4"], "--fps nan"),
    (["--duration", "nan", "--format", "gif"], "--duration nan"),
    (["--speedup", "nan", "--format", "gif"], "--speedup nan"),
    (["--speedup", "inf", "--format", "mp4"], "--speedup inf"),
    (["--duration", "20", "--speedup", "2", "--format", "mp4"], "not both"),
    (["--at", "-1"], "--at -1"),
    (["--at", "nan"], "--at nan"),
    (["--at", "inf"], "--at inf"),
    (["--at", "1e308"], "--at 1e+308"),
    (["--fps", "0", "--format", "mp4"], None),
    (["--fps", "1e9", "--format", "mp4"], None),
    (["--format", "webm"], None),
    # options the format does not use: refused, not ignored
    (["--at", "5", "--format", "gantt"], "--at is the time of a png snapshot; --format gantt does not use it"),
    (["--at", "1", "--format", "mp4"], "--format mp4 does not use it"),
    (["--at", "1", "--format", "gif"], "--format gif does not use it"),
    (["--duration", "5"], "--duration shapes an animation (--format mp4 or gif); --format png does not use it"),
    (["--speedup", "2", "--format", "gantt"], "--speedup shapes an animation"),
    (["--fps", "10"], "--fps shapes an animation"),
    (["--fps", "24", "--format", "gantt"], "--fps shapes an animation"),
]


@pytest.mark.parametrize("opts, needle", RENDER_CASES, ids=[" ".join(o) for o, _ in RENDER_CASES])
def test_render_options_asking_for_unbounded_work_are_refused(tmp_path, capsys, opts, needle):
    _write_program(tmp_path / "in", COOP)
    (tmp_path / "out").mkdir()
    suffix = next((opts[i + 1] for i, o in enumerate(opts) if o == "--format" and opts[i + 1] != "webm"), "png")
    out = tmp_path / "out" / f"x.{suffix}"
    assert_rejected(["render", "--manifest", tmp_path / "in" / "m.toml", "--out", out, *opts], capsys,
                    watch=[tmp_path], contains=needle)


def test_a_frame_count_at_the_cap_is_accepted():
    from cooprint.render.sim import MAX_FRAMES, frame_count, frame_times

    assert frame_count(100.0, 10.0, duration=MAX_FRAMES / 10.0) == MAX_FRAMES
    assert len(frame_times(100.0, 24.0, speedup=25)) == 96
