"""The bad-input contract, in one place for every corpus test.

A rejected input must give exit code 2, exactly one line on stderr (``cooprint: error: ...``),
no traceback, and leave the watched folders exactly as they were (nothing written, nothing
half-written, nothing deleted).
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Iterable

from cooprint.cli import main


def snapshot(*folders: Path) -> dict[str, tuple[int, int]]:
    """Every entry under ``folders`` (hidden ones too): path -> (size, mtime_ns) of a file, (0, 0)
    of a folder (a folder's own time changes when a file is made and removed in it: the output
    check's write probe does that before the work, and that writes nothing)."""
    seen: dict[str, tuple[int, int]] = {}
    for folder in folders:
        if not os.path.lexists(folder):
            continue
        for root, dirs, files in os.walk(folder):
            for name in dirs + files:
                p = os.path.join(root, name)
                st = os.lstat(p)
                seen[p] = (0, 0) if os.path.isdir(p) else (st.st_size, st.st_mtime_ns)
    return seen


def assert_rejected(args: Iterable[object], capsys, watch: Iterable[Path] = (), *,
                    contains: str | None = None) -> str:
    """Run ``cooprint ARGS`` in-process and check the bad-input contract; return the line."""
    watch = [Path(w) for w in watch]
    before = snapshot(*watch)
    code = main([str(a) for a in args])
    out = capsys.readouterr()
    err = out.err
    assert code == 2, f"exit {code} for {list(args)}; stderr: {err[-500:]!r}"
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 1, f"expected one line on stderr, got {len(lines)}: {err[-800:]!r}"
    assert lines[0].startswith("cooprint: error: "), lines[0]
    assert "Traceback" not in err
    assert len(lines[0]) <= 400, f"error line of {len(lines[0])} characters"
    assert snapshot(*watch) == before, f"files changed by a rejected run: {list(args)}"
    if contains is not None:
        assert contains in lines[0], (contains, lines[0])
    return lines[0]


def restate_counts(bundle: Path) -> None:
    """Make job.json's per-robot counts (``stats``: commands, moves, NOTIFY, WAIT) those of the
    bundle's programs as they are now: for tests that edit a program on purpose (the simulator
    refuses a program whose counts job.json does not state, as a truncated file)."""
    import json

    from cooprint.program.commands import parse_coop
    from cooprint.simulation.inputs import program_counts

    record = json.loads((bundle / "job.json").read_text())
    for robot in record["robots"]:
        path = bundle / robot["program"]
        if "stats" in robot and path.exists():
            robot["stats"].update(program_counts(parse_coop(path.read_text(), robot["name"], str(path))))
    (bundle / "job.json").write_text(json.dumps(record, indent=1))
