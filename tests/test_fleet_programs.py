"""Programs for N robots from a schedule, safe at any speeds (issue 14, item 4).

Layouts are boxes made by hand (tests/fleet_layouts.py), sliced in one layer grid, with a DAG and
a schedule made by hand; ``fleet_programs`` makes the programs and the simulator plays them with
each robot at its own speed (``SimRobot.profile``): no collision, no body on material, no chunk
out of order, no deadlock, whatever the speeds. The outline checks of the parking tests are the
test's own (tests/test_parking.py: rectangles and separating axes, sharing no code with the
planner).
"""

from __future__ import annotations

import numpy as np
import pytest

from cooprint.jobs import robot_names
from cooprint.program.commands import MOVE, WAIT, Program, coop_text, parse_coop
from cooprint.program.fleet import FleetError, fleet_programs
from cooprint.simulation import simulate
from cooprint.simulation.inputs import SimInput
from cooprint.simulation.timeline import SimRobot

from fleet_layouts import SLICING, SMALL, box_chunk, layout, scaled
from test_parking import outline_rects, overlapping, quads

CLEARANCE = 5.0
ERRORS = {"robots-collide", "body-on-material", "deadlock", "chunk-order", "printhead-hits-material",
          "nozzle-in-material", "double-deposit", "below-floor"}


def _row(n: int, width: float, depth: float = 50.0, gap_after: dict[int, float] | None = None) -> list:
    """``n`` boxes ``width`` wide side by side along x (``gap_after[i]``: a gap after box i), all
    printed facing +y (their robots stand at y < 0)."""
    out, x = [], 0.0
    for i in range(n):
        out.append(box_chunk(f"X{i}", (x, 0.0, 0.0), (x + width, depth, 3.0), (0.0, 1.0), 0, i))
        x += width + (gap_after or {}).get(i, 0.0)
    return out


def _simulate(programs, placements, dag, speeds: dict[str, float] | None = None):
    robots = [SimRobot(r, programs[r], np.asarray(placements[r].start), np.asarray(placements[r].facing),
                       profile=scaled(SMALL, (speeds or {}).get(r, 1.0))) for r in programs]
    res = simulate(SimInput(robots, SMALL, SLICING, "test", deps={c: dag.preds(c) for c in dag.ids}))
    assert {"robots-collide", "body-on-material", "chunk-order", "deadlock"} <= set(res.checked)
    return res, [(f.kind, f.robot, f.chunk, f.detail) for f in res.findings if f.kind in ERRORS]


SPEEDS = [{}, {"A": 0.5, "B": 1.7, "C": 1.0}, {"A": 1.7, "B": 0.5, "C": 3.0}, {"A": 3.0, "B": 1.0, "C": 0.4}]


@pytest.fixture(scope="module")
def row_plan():
    """Six 150 mm boxes in a row, three robots: even columns first (side by side, at once), odd
    columns leaning on both neighbours (SPAR3's rule)."""
    chunks = _row(6, 150.0)
    deps = {f"X{i}": tuple(f"X{j}" for j in (i - 1, i + 1) if 0 <= j < 6) for i in range(1, 6, 2)}
    seqs = {"A": ("X0", "X1"), "B": ("X2", "X3"), "C": ("X4", "X5")}
    dag, sched, layers, material = layout(chunks, deps, seqs)
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in seqs}, CLEARANCE, SLICING)
    return dag, programs, placements


@pytest.mark.parametrize("speeds", SPEEDS)
def test_a_row_of_chunks_is_clean_whatever_the_speeds(row_plan, speeds):
    dag, programs, placements = row_plan
    res, errors = _simulate(programs, placements, dag, speeds)
    assert errors == []
    # every chunk printed by its robot, in its order
    for r, p in programs.items():
        printed = [p.chunks[c] for c in np.unique(p.chunk[p.chunk >= 0])]
        assert sorted(printed) == sorted(c for c in dag.ids if c in {"A": ("X0", "X1"), "B": ("X2", "X3"),
                                                                   "C": ("X4", "X5")}[r])


def test_the_robots_work_at_once_where_they_may(row_plan):
    """The even columns are apart by more than the outlines: printed at the same time (the plan
    takes well under the sum of the robots' work)."""
    dag, programs, placements = row_plan
    res, _ = _simulate(programs, placements, dag)
    spans = _spans(res, programs)
    assert spans["X2"][0] < spans["X0"][1] and spans["X4"][0] < spans["X0"][1]  # the even columns overlap
    assert res.makespan < 0.75 * float(dag.work.sum())


def _spans(res, programs) -> dict[str, tuple[float, float]]:
    """When each chunk's material is laid: its first and last deposit, s."""
    spans = {}
    for r, tl in res.timelines.items():
        p = programs[r]
        on = tl.on
        for c in set(p.chunk[tl.index[on]].tolist()):
            sel = on & (p.chunk[tl.index] == c)
            spans[p.chunks[c]] = (float(tl.t0[sel].min()), float(tl.t1[sel].max()))
    return spans


def test_the_programs_are_valid_coop_and_name_their_events(row_plan):
    dag, programs, _ = row_plan
    for r, p in programs.items():
        assert parse_coop(coop_text(p), r) == p
        names = [e for i in np.flatnonzero(p.event >= 0) for e in p.events[p.event[i]]]
        assert all(e in dag.ids or e.split(":")[0] in programs for e in names)
    # every WAIT names an event some other robot announces
    told = {e for p in programs.values() for i in np.flatnonzero(p.kind != WAIT) if p.event[i] >= 0
            for e in p.events[p.event[i]]}
    for r, p in programs.items():
        for i in np.flatnonzero(p.kind == WAIT):
            assert set(p.events[p.event[i]]) <= told


# ------------------------------------------------------------------------------------------------
# two sides: robots that turn round


@pytest.fixture(scope="module")
def two_sided():
    """Two rows of boxes: the south row printed facing +y, the north row (leaning on it) facing
    -y; each of two robots prints both sides, so it turns round; two more robots are idle."""
    chunks = []
    for i in range(4):
        chunks.append(box_chunk(f"S{i}", (i * 100.0, -50.0, 0.0), (i * 100.0 + 100, 0.0, 3.0), (0.0, 1.0), -1, i))
        chunks.append(box_chunk(f"N{i}", (i * 100.0, 0.0, 0.0), (i * 100.0 + 100, 50.0, 3.0), (0.0, -1.0), 1, i))
    deps = {f"N{i}": (f"S{i}",) for i in range(4)}
    seqs = {"A": ("S0", "N1", "S2", "N3"), "B": ("S1", "N0", "S3", "N2"), "C": (), "D": ()}
    dag, sched, layers, material = layout(chunks, deps, seqs)
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in seqs}, CLEARANCE, SLICING)
    return dag, programs, placements, material


@pytest.mark.parametrize("speeds", SPEEDS[:3])
def test_robots_that_turn_round_are_clean_whatever_the_speeds(two_sided, speeds):
    dag, programs, placements, _ = two_sided
    _, errors = _simulate(programs, placements, dag, speeds)
    assert errors == []


def test_a_robot_turns_round_on_the_highway_clear_of_the_part(two_sided):
    dag, programs, placements, material = two_sided
    boxes = np.vstack(list(material.boxes.values()))
    lo, hi = boxes[:, :2].min(0), boxes[:, 2:4].max(0)
    radius = max(np.hypot(r[i], r[j]) for r in outline_rects(SMALL) for i in (0, 1) for j in (2, 3))
    for r in ("A", "B"):
        p = programs[r]
        assert len(p.turns) >= 6  # three times round (via a quarter turn each), and back to face home
        assert placements[r].side == "both"
        mv = np.flatnonzero(p.kind == MOVE)
        for i, _ in p.turns:
            at = p.xyz[mv[mv < i][-1], :2]  # where it turns: the last move's end before the turn
            outside = np.maximum(lo - at, at - hi).max()
            assert outside >= radius + CLEARANCE  # its whole outline, turning, is off the part


def test_idle_robots_stay_home_and_are_told_apart(two_sided):
    dag, programs, placements, material = two_sided
    for r in ("C", "D"):
        assert len(programs[r]) == 0
    _, errors = _simulate(programs, placements, dag)
    assert errors == []


# ------------------------------------------------------------------------------------------------
# the guard WAITs matter


def _strip_guards(p: Program) -> Program:
    """The program without its guard WAITs (those on '<robot>:<n>' events; the chunk ones stay)."""
    lines = coop_text(p).splitlines(keepends=True)
    kept = [ln for ln in lines if not (ln.startswith("WAIT ") and ":" in ln)]
    return parse_coop("".join(kept), p.robot)


def test_without_its_guard_waits_a_plan_collides_when_one_robot_is_faster():
    """A prints X0 then X1; B prints X3, far off, then X2 beside X1 (the robots' outlines meet
    there). At the planned speeds B is still at X3 while A prints X1; only a guard WAIT keeps a
    faster B from X2 until A has left. No chunk depends on another: no chunk WAIT does it."""
    chunks = _row(4, 60.0, gap_after={2: 150.0})
    chunks[3] = box_chunk("X3", (330.0, 0.0, 0.0), (570.0, 50.0, 3.0), (0.0, 1.0), 0, 3)  # B is busy for longer
    seqs = {"A": ("X0", "X1"), "B": ("X3", "X2")}
    dag, sched, layers, material = layout(chunks, {}, seqs)
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in seqs}, CLEARANCE, SLICING)
    assert any(":" in e for i in np.flatnonzero(programs["B"].kind == WAIT)
               for e in programs["B"].events[programs["B"].event[i]])
    for speeds in ({}, {"B": 3.0}, {"A": 0.5, "B": 1.7}):
        assert _simulate(programs, placements, dag, speeds)[1] == [], speeds
    bare = {r: _strip_guards(p) for r, p in programs.items()}
    assert (bare["B"].kind == WAIT).sum() < (programs["B"].kind == WAIT).sum()
    assert [k for k, *_ in _simulate(bare, placements, dag)[1]] == []  # as planned, no harm done
    kinds = {k for k, *_ in _simulate(bare, placements, dag, {"B": 3.0})[1]}
    assert "robots-collide" in kinds


# ------------------------------------------------------------------------------------------------
# parking


def test_64_robots_park_round_a_small_part_without_meeting():
    chunks = _row(4, 150.0)
    names = robot_names(64)
    seqs = {r: () for r in names}
    seqs.update({"A": ("X0",), "B": ("X2",), "C": ("X1",), "D": ("X3",)})
    deps = {"X1": ("X0", "X2"), "X3": ("X2",)}
    dag, sched, layers, material = layout(chunks, deps, seqs)
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in seqs}, CLEARANCE, SLICING)
    assert [r for r in names if len(programs[r]) == 0] == [r for r in names if r not in "ABCD"]
    rects = outline_rects(SMALL)
    spots = [quads(rects, np.asarray(placements[r].start)[None, :2], placements[r].facing) for r in names]
    for i in range(64):
        others = np.concatenate([q for j, q in enumerate(spots) if j != i])
        assert not overlapping(spots[i], others, CLEARANCE - 1e-6).any(), names[i]
    # every spot is beyond a working robot's reach of the part
    lo = np.array([0.0, 0.0])
    hi = np.array([600.0, 50.0])
    reach = SMALL.build_depth + SMALL.body_length + SMALL.nozzle_depth + CLEARANCE
    for r in names:
        xy = np.asarray(placements[r].start[:2])
        assert np.maximum(lo - xy, xy - hi).max() >= reach
    for speeds in ({}, {"A": 0.5, "B": 1.7, "C": 2.0, "D": 0.6}):
        assert _simulate(programs, placements, dag, speeds)[1] == []


def test_a_chunk_under_the_body_of_a_chunk_printed_later_is_refused():
    """The outer row (under the body of the robot printing the inner one) scheduled first: its
    material would be under that body. The chunk rules (body_deps) must prevent it; if they do
    not, the planner says so instead of driving a body over it."""
    chunks = [box_chunk("IN", (0.0, 0.0, 0.0), (100.0, 50.0, 3.0), (0.0, 1.0)),
              box_chunk("OUT", (0.0, -120.0, 0.0), (100.0, -60.0, 3.0), (0.0, 1.0))]
    dag, sched, layers, material = layout(chunks, {}, {"A": ("OUT", "IN")})
    with pytest.raises(FleetError, match=r"\bA\b.* body over chunk OUT"):
        fleet_programs(sched, dag, layers, material, {"A": SMALL}, CLEARANCE, SLICING)


# ------------------------------------------------------------------------------------------------
# the seed's cut of a long bar (cut_chunks), for 2 and 4 robots


def _seed2_sequences(n: int):
    def make(ids):
        left = sorted((c for c in ids if c.startswith("L")), key=lambda c: int(c[1:]))
        right = sorted((c for c in ids if c.startswith("R")), key=lambda c: int(c[1:]))
        if n == 2:
            return {"A": ("C", *left), "B": tuple(right)}
        return {"A": ("C", *left[0::2]), "B": tuple(right[0::2]), "C": tuple(left[1::2]), "D": tuple(right[1::2])}
    return make


@pytest.mark.parametrize("n", [2, 4])
def test_the_seed_cut_of_a_bar_is_clean_for_2_and_4_robots_whatever_the_speeds(n):
    from fleet_layouts import seed2_bar

    cs, (dag, sched, layers, material) = seed2_bar(900.0, _seed2_sequences(n), height=6.0 if n == 4 else 30.0)
    assert len(cs.chunks) >= 7
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in sched.sequences},
                                          CLEARANCE, SLICING)
    for speeds in ({}, {"A": 0.5, "B": 1.7, "C": 1.0, "D": 3.0}, {"A": 1.7, "B": 0.5, "C": 3.0, "D": 0.4}):
        res, errors = _simulate(programs, placements, dag, speeds)
        assert errors == [], speeds
        if not speeds and n == 2:
            spans = _spans(res, programs)
            # L1 and R1 lean on C from either side, their printheads meet only near its top (30 mm
            # tall, C is wider below): the robots print their lower layers at the same time
            assert spans["R1"][0] < spans["L1"][1] and spans["L1"][0] < spans["R1"][1]


def test_a_robot_with_only_an_empty_chunk_keeps_its_word_from_home():
    """B's only chunk has nothing to print (an empty slice): B stays home and announces it, A's
    chunk that depends on it goes on; nothing else waits for B."""
    chunks = _row(3, 150.0)
    seqs = {"A": ("X0", "X2"), "B": ("X1",)}
    dag, sched, layers, material = layout(chunks, {"X2": ("X1",)}, seqs)
    layers["X1"] = []
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in seqs}, CLEARANCE, SLICING)
    b = programs["B"]
    assert not (b.kind == MOVE).any()
    assert [b.events[b.event[i]] for i in np.flatnonzero(b.event >= 0)] == [("X1",)]
    a = programs["A"]
    assert ("X1",) in [a.events[a.event[i]] for i in np.flatnonzero(a.kind == WAIT)]
    assert _simulate(programs, placements, dag)[1] == []


def test_a_grid_dealt_round_robin_is_clean_at_random_speeds():
    """Four rows of boxes on both sides of the centre line, six columns dealt round-robin to four
    robots (neighbours belong to different robots, every robot prints on both sides): clean with
    each robot at its own speed from 0.4x to 2.5x."""
    from fleet_layouts import grid_boxes

    names = robot_names(4)
    dag, sched, layers, material = grid_boxes(4, 6, names)
    programs, placements = fleet_programs(sched, dag, layers, material, {r: SMALL for r in names}, CLEARANCE, SLICING)
    rng = np.random.default_rng(14)
    for speeds in ({}, *({r: float(x) for r, x in zip(names, rng.uniform(0.4, 2.5, 4))} for _ in range(2))):
        assert _simulate(programs, placements, dag, speeds)[1] == [], speeds


def test_a_parked_robot_in_the_way_is_a_bug_named_not_a_deadlock(monkeypatch):
    """The parking ring keeps parked robots out of every way; if a spot were in the way (here an
    idle robot put over the part by hand), the planner names both robots instead of waiting for
    ever."""
    import cooprint.program.fleet as fleet

    real = fleet.parking

    def misplaced(*args, **kwargs):
        rings = real(*args, **kwargs)
        rings.spots["Z"] = (np.array([75.0, -20.0]), np.array([0.0, 1.0]))
        return rings

    monkeypatch.setattr(fleet, "parking", misplaced)
    chunks = _row(2, 150.0)
    dag, sched, layers, material = layout(chunks, {}, {"A": ("X0", "X1"), "Z": ()})
    with pytest.raises(FleetError, match=r"^robot A cannot get to chunk X0: robot Z, parked for good at "
                                         r"\[75\.0, -20\.0\], is in its way"):
        fleet_programs(sched, dag, layers, material, {"A": SMALL, "Z": SMALL}, CLEARANCE, SLICING)


def test_the_plan_as_a_bundle_loads_and_simulates_clean(two_sided, tmp_path):
    """What `cooprint run` will write for N robots: job.json with each robot's placement record
    (side, facing, start, facings naming its own chunks), profile and chunks, the chunks' deps,
    and robots/<name>.coop; the simulator reads it back (its checks of the record included)."""
    import dataclasses
    import json

    from cooprint.config import load_settings
    from cooprint.program.commands import write_coop
    from cooprint.simulation import load_inputs

    dag, programs, placements, _ = two_sided
    settings = dataclasses.replace(load_settings(), robot=SMALL, slicing=SLICING)
    (tmp_path / "robots").mkdir()
    robots = []
    owner = {"A": ("S0", "N1", "S2", "N3"), "B": ("S1", "N0", "S3", "N2"), "C": (), "D": ()}
    for r, p in programs.items():
        with open(tmp_path / "robots" / f"{r}.coop", "w", encoding="utf-8") as fh:
            write_coop(fh, p)
        robots.append({**placements[r].to_dict(), "program": f"robots/{r}.coop", "chunks": list(owner[r]),
                       "profile": dataclasses.asdict(SMALL)})
    record = {"format": "cooprint-job/2", "settings": settings.to_dict(), "robots": robots,
              "chunks": [{"id": c, "deps": list(dag.preds(c))} for c in dag.ids]}
    (tmp_path / "job.json").write_text(json.dumps(record))
    assert [f["from_chunk"] for f in placements["A"].to_dict()["facings"]] == ["S0", "N1", "S2", "N3"]
    res = simulate(load_inputs([str(tmp_path)]))
    assert "chunk-order" in res.checked
    assert [(f.kind, f.robot) for f in res.findings if f.severity == "error"] == []


def test_a_mixed_fleet_keeps_each_robots_own_outline_apart():
    """B is wider (body and frame 130 mm) and C has a longer reach (printhead 20 mm, body 140 mm
    behind its front): each robot's own outline is swept, and the plan is clean with each robot
    simulated with its own profile, at very different speeds."""
    import dataclasses

    profiles = {"A": SMALL, "B": dataclasses.replace(SMALL, body_width=130.0, frame_width=130.0),
                "C": dataclasses.replace(SMALL, nozzle_depth=20.0, body_length=140.0)}
    chunks = _row(6, 150.0)
    deps = {f"X{i}": tuple(f"X{j}" for j in (i - 1, i + 1) if 0 <= j < 6) for i in range(1, 6, 2)}
    seqs = {"A": ("X0", "X1"), "B": ("X2", "X3"), "C": ("X4", "X5")}
    dag, sched, layers, material = layout(chunks, deps, seqs)
    programs, placements = fleet_programs(sched, dag, layers, material, profiles, CLEARANCE, SLICING)
    for speeds in ({}, {"A": 0.5, "B": 1.7, "C": 3.0}, {"A": 3.0, "B": 0.5, "C": 1.0}):
        robots = [SimRobot(r, programs[r], np.asarray(placements[r].start), np.asarray(placements[r].facing),
                           profile=scaled(profiles[r], speeds.get(r, 1.0))) for r in seqs]
        res = simulate(SimInput(robots, SMALL, SLICING, "test", deps={c: dag.preds(c) for c in dag.ids}))
        assert [(f.kind, f.robot) for f in res.findings if f.kind in ERRORS] == [], speeds


def test_a_chunk_without_a_facing_or_a_robot_without_a_profile_is_refused():
    import dataclasses

    chunks = _row(2, 150.0)
    dag, sched, layers, material = layout(chunks, {}, {"A": ("X0", "X1")})
    with pytest.raises(ValueError, match=r"^fleet_programs: no profile for robot A$"):
        fleet_programs(sched, dag, layers, material, {}, CLEARANCE, SLICING)
    facing = dag.facing.copy()
    facing[1] = np.nan
    with pytest.raises(ValueError, match=r"^fleet_programs: chunk X1 \(robot A\) has no facing"):
        fleet_programs(sched, dataclasses.replace(dag, facing=facing), layers, material, {"A": SMALL}, CLEARANCE, SLICING)
