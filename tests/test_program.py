"""The command language: records, writer, parser (fast pass and line parser), G-code from it."""

import re

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from cooprint.config import SlicingSettings
from cooprint.program import scan
from cooprint.program.scan import LAYER_LINE, PATH_LINE, Sweep, sweep
from cooprint.program.commands import (MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, ProgramError, coop_text,
                                       make_program, parse_coop, quantize, read_coop)
from cooprint.program.gcode import Feeds, gcode_text
from cooprint.slicing.paths import INFILL, PERIMETER_OUTER, TRAVEL, extrusion_area

SEED_SAMPLE = "MOVE 0, 0, 0  \nTOOL ON  \nMOVE 1, 0, 0  \nMOVE 1, 1, 0  \nMOVE 0, 1, 0  \nTOOL OFF\n"


def test_the_seed_sample_parses_as_written():
    p = parse_coop(SEED_SAMPLE, "A")
    assert p.kind.tolist() == [MOVE, TOOL_ON, MOVE, MOVE, MOVE, TOOL_OFF]
    np.testing.assert_array_equal(p.xyz[p.moves], [[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]])
    assert p.tool_on().tolist() == [False, True, True, True, True, False]
    assert parse_coop(coop_text(p), "A") == p


def _sample_program() -> Program:
    kind = [MOVE, WAIT, MOVE, TOOL_ON, MOVE, MOVE, TOOL_OFF, MOVE, TOOL_ON, MOVE, TOOL_OFF, NOTIFY, MOVE]
    xyz = np.zeros((len(kind), 3))
    xyz[[0, 2, 4, 5, 7, 9, 12]] = [[0, 0, 9], [0, 0, 0.2], [10.0004, 0, 0.2], [10, 10, 0.2], [3, -2.5, 0.4],
                                   [1e3, 1 / 3, 0.4], [1e3, 1 / 3, 5]]
    role = [TRAVEL, TRAVEL, TRAVEL, PERIMETER_OUTER, PERIMETER_OUTER, PERIMETER_OUTER, PERIMETER_OUTER, TRAVEL,
            INFILL, INFILL, INFILL, TRAVEL, TRAVEL]
    width = [0.45 if r != TRAVEL else 0.0 for r in role]
    layer = [-1, -1, 0, 0, 0, 0, 0, 1, 1, 1, 1, -1, -1]
    height = [0.2 if la >= 0 else 0.0 for la in layer]
    chunk = [-1, -1, 0, 0, 0, 0, 0, 0, 0, 0, 0, -1, -1]
    return make_program("B", np.array(kind), xyz, role=role, width=width, layer=layer, height=height,
                        chunk=chunk, chunks=("R1",), events=(("C", "L1"), ("R1",)))


def test_write_then_parse_is_exact():
    p = _sample_program()
    text = coop_text(p, header=["a test"])
    assert "WAIT C, L1\n" in text and "NOTIFY R1\n" in text and ";@chunk R1\n" in text
    assert "MOVE 10.000, 0.000, 0.200\n" in text  # the 1 µm grid
    back = parse_coop(text, "B")
    assert back == p
    assert coop_text(back, header=["a test"]) == text


def test_bare_notify_counts_the_robots_notifies():
    p = parse_coop("NOTIFY\nnotify done\n# comment\nNOTIFY ; after\n", "A")
    assert p.events == (("A:1",), ("done",), ("A:3",))
    assert p.kind.tolist() == [NOTIFY] * 3


def test_commas_case_blanks_and_comments_are_free():
    text = "move 1 2 3\n  MOVE\t4,5 ,6 # c\nMOVE 7 ,8, 9;x\n\n; only a comment\r\nWAIT a b,c\r\nTool  off\n"
    p = parse_coop(text, "A")
    np.testing.assert_array_equal(p.xyz[p.moves], [[1, 2, 3], [4, 5, 6], [7, 8, 9]])
    assert p.events == (("a", "b", "c"),) and p.kind.tolist() == [MOVE, MOVE, MOVE, WAIT, TOOL_OFF]


@pytest.mark.parametrize("line, col, needle", [
    ("JUMP 1 2 3", 1, "unknown word 'JUMP' (expected MOVE, TOOL, NOTIFY or WAIT)"),
    ("MOVE 1 2", 9, "MOVE needs 3 numbers (x, y, z), got 2"),
    ("MOVE 1 2 3 4", 12, "MOVE takes 3 numbers (x, y, z), extra token '4'"),
    ("MOVE 1 nan 3", 8, "'nan' is not a finite number"),
    ("MOVE 1 2 1e999", 10, "'1e999' is not a finite number"),
    ("MOVE 1 x 3", 8, "'x' is not a number"),
    ("MOVE 1,,2,3", 8, "MOVE: a comma where a number was expected"),
    ("MOVE 1, 2, 3,", 13, "MOVE: a comma with no number after it"),
    ("TOOL", 6, "TOOL needs ON or OFF, got nothing"),
    ("TOOL ON OFF", 6, "TOOL needs ON or OFF, got 'ON OFF'"),
    ("NOTIFY a b", 10, "NOTIFY takes at most one event name, extra token 'b'"),
    ("WAIT", 6, "WAIT needs at least one event name"),
    ("WAIT a$b", 6, "'a$b' is not an event name"),
    (";@layer x 0.2", 9, ";@layer INDEX 'x': expected a whole number from 0 to 2147483647"),
    (";@path wobble 0.4", 8, ";@path ROLE 'wobble': expected one of outer-perimeter"),
    (";@layer 1 2 3", 3, "malformed annotation ';@layer 1 2 3': expected ';@layer INDEX HEIGHT'"),
    # issue 12: huge but finite coordinates, Unicode digits, annotation fields, long tokens
    ("MOVE 1e308, 0, 0", 6, "coordinate 1e308 is beyond +-1e+06 mm"),
    ("MOVE 0, 1000000.001, 0", 9, "coordinate 1000000.001 is beyond +-1e+06 mm"),
    ("MOVE 0, 999999999999999, 0", 9, "coordinate 999999999999999 is beyond"),
    ("MOVE \uff11, 2, 3", 6, "'\uff11' is not a number (ASCII digits"),
    ("MOVE 1_000, 2, 3", 6, "'1_000' is not a number"),
    ("MOVE \u0663, 2, 3", 6, "'\u0663' is not a number"),
    ("MOVE " + "9" * 100, 6, "coordinate 9999999999999999999999999999999999999999... (100 characters)"),
    ("JUMP" + "x" * 100_000, 1, "unknown word 'JUMPxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxxx... (100004 characters)'"),
    (";@layer \uff11 0.2", 9, ";@layer INDEX '\uff11'"),
    (";@layer -1 0.2", 9, ";@layer INDEX '-1'"),
    (";@layer 99999999999 0.2", 9, ";@layer INDEX '99999999999'"),
    (";@layer 0 0", 11, ";@layer HEIGHT 0: expected mm above 0 and at most 50"),
    (";@layer 0 nan", 11, ";@layer HEIGHT 'nan' is not a finite number"),
    (";@layer 0 1e308", 11, ";@layer HEIGHT 1e308: expected mm above 0"),
    (";@layer 0 51", 11, ";@layer HEIGHT 51: expected mm above 0"),
    (";@layer 0 \uff10.2", 11, ";@layer HEIGHT '\uff10.2' is not a number"),
    (";@path skin -0.4", 13, ";@path WIDTH -0.4: expected mm from 0 to 50"),
    (";@path skin inf", 13, ";@path WIDTH 'inf' is not a finite number"),
    (";@path skin 1e3", 13, ";@path WIDTH 1e3: expected mm from 0 to 50"),
    (";@path Skin 0.4", 8, ";@path ROLE 'Skin'"),
    (";@chunk a$b", 9, ";@chunk ID 'a$b': expected a chunk name"),
    (";@chunk " + "c" * 65, 9, ";@chunk ID 'cccc"),
    (";@chunk", 3, "malformed annotation ';@chunk'"),
])
@pytest.mark.parametrize("among_moves", [False, True])
def test_every_malformed_line_names_file_line_and_column(line, col, needle, among_moves):
    good = "MOVE 1.000, 2.000, 3.000\n" * 50 if among_moves else "TOOL OFF\n"
    with pytest.raises(ProgramError) as err:
        parse_coop(good + line + "\n" + good, "A", "robots/A.coop")
    n = good.count("\n") + 1
    assert str(err.value).startswith(f"robots/A.coop:{n}:{col}: {needle}"), str(err.value)
    assert "\n" not in str(err.value)


def test_a_missing_file_is_a_clear_error(tmp_path):
    with pytest.raises(ProgramError, match="no such command file"):
        read_coop(tmp_path / "X.coop")


_num = st.one_of(st.floats(-1e4, 1e4, allow_nan=False).map(lambda v: float(np.round(v, 3))),
                 st.floats(-1e6, 1e6, allow_nan=False),  # up to 17 significant digits
                 st.sampled_from(["+3", ".25", "-.5", "7.", "-0", "0.000", "1e3", "2.5E-2", "00012.50",
                                  "123456789012345", "1234567890123456", "0.1234567890123456789012",
                                  "1.2.3", "--1", ".", "1x"]))
_sep = st.sampled_from([" ", ", ", ",", " ,", "\t", " , "])


@st.composite
def _program_texts(draw):
    lines = []
    for _ in range(draw(st.integers(0, 40))):
        what = draw(st.sampled_from(["move", "move", "move", "tool", "notify", "wait", "comment", "ann"]))
        if what == "move":
            x, y, z = (draw(_num) for _ in range(3))
            a, b = draw(_sep), draw(_sep)
            word = draw(st.sampled_from(["MOVE ", "MOVE\t", "move ", "  MOVE "]))
            tail = draw(st.sampled_from(["", "  ", " ; c", "\r"]))
            lines.append(f"{word}{x}{a}{y}{b}{z}{tail}")
        elif what == "tool":
            lines.append(draw(st.sampled_from(["TOOL ON", "TOOL OFF", "tool on"])))
        elif what == "notify":
            lines.append(draw(st.sampled_from(["NOTIFY", "NOTIFY C", "NOTIFY B:2"])))
        elif what == "wait":
            lines.append(draw(st.sampled_from(["WAIT C", "WAIT A:1, C", "WAIT x y"])))
        elif what == "comment":
            lines.append(draw(st.sampled_from(["", "; hello", "# MOVE 1 2 3"])))
        else:
            lines.append(draw(st.sampled_from([";@chunk L2", ";@chunk -", ";@layer 3 0.2", ";@layer -",
                                               ";@path skin 0.5", ";@future thing", ";@layer 12 0.25",
                                               ";@layer  3\t0.2\r", ";@path outer-perimeter 0.45",
                                               ";@layer 99999999999 0.2",
                                               ";@path perimeter 0", ";@path infill 0.30000000000000004",
                                               ";@layer 0012 .2", ";@LAYER 3 0.2", ";@ layer 4 0.2",
                                               ";@path travel 0.0", ";@layerx 1 0.2", ";@facing -90.0",
                                               ";@facing 12.5", ";@facing 0", ";@facing nan"])))
    return "\n".join(lines) + draw(st.sampled_from(["", "\n"]))


def test_the_sweep_reads_plain_lines_itself():
    text = (b"MOVE 1, -2.5, .25\nTOOL ON\n;@layer 3 0.2\n;@layer -\n;@path outer-perimeter 0.45\n; note\n\n"
            b";@chunk C\nNOTIFY\nMOVE 1 2 3 ; c\n")
    swept = sweep(text)
    assert swept.kind.tolist() == [MOVE, TOOL_ON, -1, -1, -1]  # then ;@chunk, NOTIFY and the commented MOVE
    assert swept.xyz[0].tolist() == [1.0, -2.5, 0.25] and np.isnan(swept.xyz[1:]).all()
    assert [text[a:b] for _, a, b, _ in swept.other] == [b";@chunk C", b"NOTIFY", b"MOVE 1 2 3 ; c"]
    assert swept.other[:, [0, 3]].tolist() == [[7, 2], [8, 3], [9, 4]]  # lines (from 0) and slots
    assert swept.notes.tolist() == [[2, 2, LAYER_LINE], [3, 2, LAYER_LINE], [4, 2, PATH_LINE]]
    assert swept.values.tolist() == [[3, 0.2], [-1, 0], [PERIMETER_OUTER, 0.45]]


@settings(max_examples=150, deadline=None)
@given(_program_texts())
def test_the_fast_pass_reads_exactly_what_the_line_parser_reads(text):
    def every_line_to_the_line_parser(data):
        data = bytes(data)
        starts = np.r_[0, np.flatnonzero(np.frombuffer(data, np.uint8) == 10) + 1]
        ends = np.r_[starts[1:] - 1, len(data)]
        lines = np.arange(len(starts))
        return Sweep(np.full(len(starts), -1, np.int8), np.full((len(starts), 3), np.nan),
                     np.column_stack([lines, starts, ends, lines]), np.zeros((0, 3), np.int64), np.zeros((0, 2)))

    def parse(text):
        try:
            return parse_coop(text, "A")
        except ProgramError as exc:
            return str(exc)

    fast = parse(text)
    with pytest.MonkeyPatch.context() as m:
        m.setattr(scan, "sweep", every_line_to_the_line_parser)
        slow = parse(text)
    assert fast == slow
    if isinstance(fast, Program) and np.array_equal(quantize(fast.xyz), fast.xyz, equal_nan=True):
        assert parse_coop(coop_text(fast), "A") == fast  # on the writer's 1 µm grid: a round trip


def test_gcode_from_a_program_extrudes_the_flow_and_speaks_to_the_host():
    p = _sample_program()
    s = SlicingSettings()
    text = gcode_text([p], s, Feeds.of_slicer(s), name="t")
    assert "; WAIT C, L1\nM400\nM0 WAIT C, L1\n" in text
    assert "; NOTIFY R1\nM400\nM118 NOTIFY R1\n" in text
    # independent reading: sum of E on G1 moves, positions tracked from G0/G1
    e_total, pos = 0.0, {}
    for line in text.splitlines():
        code = line.split(";")[0].split()
        if code and code[0] in ("G0", "G1"):
            words = {w[0]: float(w[1:]) for w in code[1:]}
            if "E" in words and ("X" in words or "Y" in words):
                e_total += words["E"]
            pos.update({k: v for k, v in words.items() if k in "XYZ"})
    on = p.tool_on()
    mv = np.flatnonzero(p.moves)
    seg = np.linalg.norm(np.diff(p.xyz[mv], axis=0), axis=1)
    vol = (extrusion_area(p.width[mv][1:], p.height[mv][1:]) * seg * on[mv][1:]).sum()
    assert e_total == pytest.approx(vol / (np.pi * 0.875 ** 2), rel=1e-4)
    assert pos == {"X": 1000.0, "Y": pytest.approx(1 / 3, abs=1e-3), "Z": 5.0}
    assert re.search(r"G1 X10\.000 Y10\.000 E[0-9.]+\n", text)


def _layer_program_numpy(layer, here, index=0):
    """layer_program as it was written in numpy before its compiled pass: the reference."""
    from cooprint.program.commands import make_program, quantize

    z = float(quantize(layer.z))
    m = len(layer)
    pts, off, role = layer.points, layer.offsets, layer.role
    n_pts = np.diff(off)
    extr = role != TRAVEL
    on = extr & ~np.r_[False, extr[:-1]]
    offc = extr & ~np.r_[extr[1:], False]
    count = on + (n_pts - 1) + offc
    start = np.r_[0, np.cumsum(count)[:-1]]
    total = int(count.sum())
    kind = np.full(total, MOVE, dtype=np.uint8)
    kind[start[on]] = TOOL_ON
    kind[(start + count - 1)[offc]] = TOOL_OFF
    keep_pt = np.ones(len(pts), dtype=bool)
    keep_pt[off[:-1]] = False
    xyz = np.zeros((total, 3))
    xyz[kind == MOVE, :2] = pts[keep_pt]
    xyz[:, 2] = z
    k = np.arange(m)
    nxt = np.minimum.accumulate(np.where(extr, k, m)[::-1])[::-1]
    before = np.maximum.accumulate(np.where(extr, k, -1))
    owner = np.where(nxt < m, nxt, before)
    owner = np.where(owner >= 0, owner, k)
    path_of = np.repeat(owner, count)
    width = np.where(extr, layer.width, 0.0)[path_of]
    lead = [np.r_[here[:2], z], np.r_[pts[0], z]] if np.isfinite(here).all() else [np.r_[pts[0], z]]
    kind = np.r_[np.full(len(lead), MOVE, np.uint8), kind]
    xyz = quantize(np.vstack([*lead, xyz]))
    path_of = np.r_[np.full(len(lead), owner[0]), path_of]
    width = np.r_[np.full(len(lead), width[0] if len(width) else 0.0), width]
    mv = np.flatnonzero(kind == MOVE)
    prev = np.vstack([quantize(here)[None], xyz[mv[:-1]]])
    still = np.zeros(len(kind), dtype=bool)
    still[mv[(xyz[mv] == prev).all(axis=1)]] = True
    keep = ~still
    prog = make_program("", kind[keep], xyz[keep], role=role[path_of][keep], width=width[keep], layer=index,
                        height=layer.height)
    return prog, xyz[mv[-1]]


@settings(max_examples=150, deadline=None)
@given(st.lists(st.tuples(st.integers(1, 4), st.sampled_from([TRAVEL, INFILL, PERIMETER_OUTER])), min_size=1, max_size=7),
       st.lists(st.integers(0, 3), min_size=40, max_size=40),
       st.sampled_from(["nowhere", "first point", "elsewhere"]))
def test_layer_program_matches_its_numpy_form(paths, coords, start):
    """The compiled layer_program makes the same commands as the whole-array version it
    replaced, whatever the paths: travels first or last or alone, one-point paths, repeated
    points (moves that go nowhere are dropped), a nozzle from nowhere, on the first point or
    elsewhere."""
    from cooprint.program.build import layer_program
    from cooprint.slicing.paths import LayerPaths

    grid = np.array(coords, dtype=np.float64).reshape(-1, 2) * 0.7
    made, at = [], 0
    for n, role in paths:
        pts = np.array([grid[(at + i) % len(grid)] for i in range(n)])
        at += n
        made.append((pts, role, 0.0 if role == TRAVEL else 0.45))
    layer = LayerPaths.build(0.6, 0.2, made)
    here = {"nowhere": np.full(3, np.nan), "first point": np.r_[layer.points[0], 0.6],
            "elsewhere": np.array([5.0, -3.0, 0.4])}[start]
    got, got_end = layer_program(layer, here, index=3)
    want, want_end = _layer_program_numpy(layer, here, index=3)
    assert got == want
    assert np.array_equal(got_end, want_end)
