"""Programs for the writer tests: random but realistic command streams (travel runs of every
length, short and long, some of zero length; extrusion runs with role, width, layer and chunk
changes, some climbing in Z; NOTIFY / WAIT inside travel runs; turns, one after the last
command), made with ``make_program`` from a seed (numpy's PCG64 stream is stable)."""

from __future__ import annotations

import numpy as np

from cooprint.program.commands import MOVE, NOTIFY, TOOL_OFF, TOOL_ON, WAIT, Program, make_program


def random_program(seed: int, n_runs: int = 40, robot: str = "A") -> Program:
    rng = np.random.default_rng(seed)
    kind, xyz, role, width, layer, height, chunk, events, turns = [], [], [], [], [], [], [], [], []
    pos = rng.uniform(-50, 50, 3)
    pos[2] = abs(pos[2])
    c, la, h = -1, -1, 0.0
    notifies = 0

    def add(k, p=(np.nan,) * 3, r=4, w=0.0):
        kind.append(k)
        xyz.append(p)
        role.append(r)
        width.append(w)
        layer.append(la)
        height.append(h)
        chunk.append(c)

    for _ in range(n_runs):
        what = rng.integers(0, 10)
        if rng.random() < 0.1:
            turns.append((len(kind), float(np.round(rng.uniform(-180, 180), 3))))
        if what < 3:  # a travel run: steps short or long, some of zero length, maybe a sync inside
            for _ in range(int(rng.integers(1, 6))):
                step = rng.choice([0.0, 0.3, 1.1, 5.0]) * rng.uniform(0.5, 1.5, 3) * (rng.random() < 0.9)
                pos = pos + step * np.array([1, 1, 0.2])
                add(MOVE, tuple(pos))
                if rng.random() < 0.15:
                    if rng.random() < 0.5:
                        notifies += 1
                        add(NOTIFY)
                        events.append((f"{robot}:{notifies}",))
                    else:
                        add(WAIT)
                        events.append(tuple(f"B:{int(i)}" for i in rng.integers(1, 9, rng.integers(1, 3))))
        elif what < 4:
            add(TOOL_OFF)
        elif what < 5:  # a chunk / layer change
            if rng.random() < 0.3:
                c = int(rng.integers(-1, 3))
            la = int(rng.integers(-1, 4)) if rng.random() < 0.8 else la
            h = float(rng.choice([0.2, 0.3])) if la >= 0 else 0.0
        else:  # an extrusion run, maybe in several roles, maybe climbing
            add(TOOL_ON)
            r = int(rng.integers(0, 4))
            w = float(rng.choice([0.4, 0.45]))
            climb = rng.random() < 0.2
            for _ in range(int(rng.integers(1, 30))):
                if rng.random() < 0.1:
                    r = int(rng.integers(0, 4))
                pos = pos + rng.uniform(-3, 3, 3) * np.array([1, 1, 0.05 if climb else 0])
                add(MOVE, tuple(pos), r, w)
            if rng.random() < 0.7:
                add(TOOL_OFF)
    if rng.random() < 0.5:
        turns.append((len(kind), 90.0))
    return make_program(robot, np.array(kind, dtype=np.uint8), np.array(xyz, dtype=float).reshape(-1, 3),
                        role=np.array(role), width=np.array(width), layer=np.array(layer), height=np.array(height),
                        chunk=np.array(chunk), chunks=("C", "L1", "R1"), events=tuple(events), turns=tuple(turns))
