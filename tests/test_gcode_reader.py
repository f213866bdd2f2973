"""The compiled G-code sweep (cooprint.simulation.gcode) against the line reader it replaces."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from cooprint.program.commands import MOVE, TOOL_OFF, TOOL_ON
from cooprint.simulation.gcode import _widths, gcode_rows
from cooprint.simulation.inputs import SimInputError, _gcode_text, _read_gcode_lines, read_gcode
from cooprint.slicing.paths import extrusion_width


def _outcome(read, path):
    try:
        return read(path)
    except SimInputError as exc:
        return str(exc)


def _reference(path):
    return _read_gcode_lines(path, path.read_text(encoding="utf-8", errors="replace"))


def _same(path):
    """read_gcode and the line reader give the same robot, or the same error."""
    fast, ref = _outcome(read_gcode, path), _outcome(_reference, path)
    if isinstance(ref, str):
        assert fast == ref
        return
    assert not isinstance(fast, str), fast
    assert fast.name == ref.name and fast.program == ref.program and fast.notes == ref.notes
    for f in ("start", "facing", "speed", "de"):
        assert np.array_equal(getattr(fast, f), getattr(ref, f)), f


# ------------------------------------------------------------------------------------------------
# random G-code

_digits = st.integers(-300000, 300000)


@st.composite
def _number(draw, positive=False):
    v = draw(st.integers(1, 300000) if positive else _digits)
    k = draw(st.integers(0, 4))
    s = f"{abs(v) / 10 ** k:.{k}f}"
    if s.startswith("0.") and draw(st.booleans()):
        s = s[1:]  # '.25'
    if k == 0 and draw(st.integers(0, 4)) == 0:
        s += "."  # '7.'
    sign = "-" if v < 0 else draw(st.sampled_from(["", "", "+"]))
    return sign + s


def _case(draw, word):
    return "".join(c.lower() if draw(st.booleans()) else c for c in word)


@st.composite
def _line(draw, odd=False):
    kind = draw(st.sampled_from(["move"] * 8 + ["mode", "g92", "comment", "blank", "other", "host"]
                                + (["odd"] * 2 if odd else [])))
    if kind == "move":
        axes = draw(st.lists(st.sampled_from("XYZEF"), max_size=5))
        words = [_case(draw, a) + draw(_number(positive=a == "F")) for a in axes]
        text = " ".join([_case(draw, draw(st.sampled_from(["G0", "G1", "G1"])))] + words)
    elif kind == "mode":
        text = _case(draw, draw(st.sampled_from(["G90", "G91", "M82", "M83"])))
    elif kind == "g92":
        text = _case(draw, "G92 ") + draw(st.sampled_from(["E0", "E", "e", "E" + draw(_number()), "X0 E"]))
    elif kind == "comment":
        text = "; " + draw(st.sampled_from(["LAYER_CHANGE", "Z:0.2", "G1 X5 E9", "héllo"]))
    elif kind == "blank":
        text = draw(st.sampled_from(["", " ", "\t"]))
    elif kind == "other":
        text = draw(st.sampled_from(["M104 S200", "T0", "G28", "G1X5 E3", "G21", "M117 Héllo", "G01 X5"]))
    elif kind == "host":  # a fleet host's NOTIFY / WAIT, operator pauses, echoes (noted by the sweep)
        text = _case(draw, draw(st.sampled_from(["M118", "M0", "M1", "M00", "M01"]))) + draw(st.sampled_from(
            [" NOTIFY C", " notify e:1", " WAIT C", " WAIT C, D", " wait a.b,c-d", "", " S5", " Press resume",
             " hello", " NOTIFY L1 ; after"]))
    else:  # the sweep leaves these to the line reader
        text = draw(st.sampled_from(["G1 X1e1", "G1 X5 \x0b G1 Y3", "; a\x1cG1 X3 E2", "G1\xa0X5 E1",
                                     "G1 X1_0 E1", "\ufeffG1 X5", "G1 X0.1234567890123456 E1", "G1 X5 *12",
                                     "G1 X1000000.5 E1", "G91", "G1 Z-999999.9", "M118 NOTIFY", "M0 WAIT a b"]))
    if kind in ("move", "mode", "g92") and draw(st.booleans()):
        text += draw(st.sampled_from(["", " ", "\t"])) + "; " + draw(st.sampled_from(["c", "é", "X9"]))
    return draw(st.sampled_from(["", " ", "\t"])) + text if kind != "blank" else text


@st.composite
def _gcode(draw, odd=False):
    lines = draw(st.lists(_line(odd=odd), max_size=40))
    ends = draw(st.sampled_from(["\n", "\r\n", "mixed"]))
    text = "".join(x + (draw(st.sampled_from(["\n", "\r\n", "\r"])) if ends == "mixed" else ends) for x in lines)
    if draw(st.booleans()) and text:
        text = text.rstrip("\r\n")  # no line break at the end
    return text


_settings = settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture])


@_settings
@given(text=_gcode())
def test_plain_gcode_is_read_by_the_sweep_as_by_the_line_reader(tmp_path, text):
    p = tmp_path / "part.gcode"
    p.write_bytes(text.encode())
    assert gcode_rows(p.read_bytes(), 1.75) is not None  # plain lines: no fallback
    _same(p)


@_settings
@given(text=_gcode(odd=True))
def test_any_gcode_is_read_as_by_the_line_reader(tmp_path, text):
    p = tmp_path / "part.gcode"
    p.write_bytes(text.encode())
    _same(p)


def test_widths_are_the_line_readers_for_any_layer_height():
    # the line reader calls extrusion_width with a scalar height, whose (h / 2) ** 2 is C's pow:
    # not always the square an array's ** 2 gives (here at a few of the heights)
    rng = np.random.default_rng(0)
    h = np.round(rng.uniform(0.001, 1.0, 20000), 4)
    area = rng.uniform(0.01, 1.0, len(h))
    ref = np.array([float(extrusion_width(a, v)) for a, v in zip(area.tolist(), h.tolist())])
    assert np.array_equal(_widths(area, h), ref)


def test_the_sweep_reads_what_the_line_reader_decodes():
    data = b"G1 X1\r\nG1 X2\rG1 X3\n\xff; \xe2\x80G1\n"
    assert _gcode_text(data) == "G1 X1\nG1 X2\nG1 X3\n\ufffd; \ufffdG1\n"


# ------------------------------------------------------------------------------------------------
# errors


@pytest.mark.parametrize("bad, message", [
    ("G1 X", "'X' is not a G-code word with a number"),
    ("G1 Xabc E1", "'Xabc' is not a G-code word with a number"),
    ("G0 Y5 Z", "'Z' is not a G-code word with a number"),
    ("G1 Xnan", "a coordinate that is not a finite number"),
    ("G1 X1 Einf", "a coordinate that is not a finite number"),
    ("G1 X1 F0", "feed rate F0 is not positive"),
    ("G1 X1 F-1200", "feed rate F-1200 is not positive"),
    ("G92 Eabc", "'Eabc' is not a G-code word with a number"),
    ("G92 E-nan", "a coordinate that is not a finite number"),
])
@pytest.mark.parametrize("end", ["\n", "\r\n"])
def test_bad_gcode_gives_the_line_readers_error(tmp_path, bad, message, end):
    p = tmp_path / "bad.gcode"
    p.write_bytes(end.join(["; top", "G90", "G1 X1 Y2 E0.5 F1200", "", bad + " ; here", "G1 X3"]).encode())
    with pytest.raises(SimInputError) as fast:
        read_gcode(p)
    with pytest.raises(SimInputError) as ref:
        _reference(p)
    assert str(fast.value) == str(ref.value) == f"{p}:5: {message}"


# ------------------------------------------------------------------------------------------------
# a hand-written file

_HAND = """; a hand-written file
G90
M83
G92 E0
G1 Z0.2 F600
G1 X10 Y0 E0.5 F1200 ; 10 mm at 20 mm/s
g1 x10 y10 e.5
G1 E-0.8 F2400       ; retract
G0 X20 Y10 F6000
G1 E0.8
M82
G92 E
G1 X30 Y10 E1.0 F1200 ; absolute E: 1 mm of filament over 10 mm
G91
G1 X-5 E0.25          ; relative (G91): 0.25 mm over 5 mm
"""


@pytest.mark.parametrize("end", ["\n", "\r\n"])
def test_a_hand_written_file(tmp_path, end):
    p = tmp_path / "hand.gcode"
    p.write_bytes(_HAND.replace("\n", end).encode())
    assert gcode_rows(p.read_bytes(), 1.75) is not None
    r = read_gcode(p)
    prog = r.program
    assert r.name == prog.robot == "hand"
    assert prog.kind.tolist() == [MOVE, TOOL_ON, MOVE, MOVE, TOOL_OFF, MOVE, MOVE, MOVE, TOOL_ON, MOVE, MOVE]
    m = prog.kind == MOVE
    assert prog.xyz[m].tolist() == [[0, 0, 0.2], [10, 0, 0.2], [10, 10, 0.2], [10, 10, 0.2], [20, 10, 0.2],
                                    [20, 10, 0.2], [30, 10, 0.2], [25, 10, 0.2]]
    assert np.isnan(prog.xyz[~m]).all()
    assert r.speed.tolist() == [10, 0, 20, 20, 0, 40, 100, 100, 0, 20, 20]
    assert r.de.tolist() == [0, 0, 0.5, 0.5, 0, -0.8, 0, 0.8, 0, 1.0, 0.25]
    assert prog.tool_on().tolist() == [False, True, True, True, False, False, False, False, True, True, True]
    fil = math.pi * 0.875 ** 2

    def width(filament, length, h=0.2):  # the bead whose cross-section carries the filament pushed
        return (filament * fil / length - math.pi * (h / 2) ** 2) / h + h

    w1, w2 = width(0.5, 10), width(1.0, 10)
    assert prog.width.tolist() == pytest.approx([0, 0, w1, w1, 0, 0, 0, 0, 0, w2, w1], rel=1e-12)
    assert 0.644 < w1 < 0.645 and 1.245 < w2 < 1.246
    assert prog.height.tolist() == [0, 0, 0.2, 0.2, 0, 0, 0, 0, 0, 0.2, 0.2]
    assert r.start.tolist() == [0, 0, 0]
    _same(p)


def test_empty_and_comment_only_files(tmp_path):
    for text in ("", "; nothing\n\n   \n", "M104 S200\r\nG28\r\n"):
        p = tmp_path / "empty.gcode"
        p.write_text(text)
        r = read_gcode(p)
        assert len(r.program) == 0 and len(r.speed) == 0 and len(r.de) == 0
        _same(p)


def test_each_layer_is_as_thick_as_the_step_from_the_layer_below(tmp_path):
    p = tmp_path / "layers.gcode"
    p.write_text("G1 Z0.3 F600\nG1 X10 E0.5\nG1 Z0.5\nG1 X0 E1\nG1 Z0.7 F600\nG1 Z0.9\n"  # a hop: no layer
                 "G1 Z0.7\nG1 X10 E1.5\nG1 Z0.95\nG1 X0 E2\n")
    prog = read_gcode(p).program
    h = prog.height[(prog.kind == MOVE) & prog.tool_on()]
    assert h == pytest.approx([0.3, 0.2, 0.2, 0.25])
    _same(p)
