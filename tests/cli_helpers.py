"""Running refused command lines for the ``test_cli_errors_<command>.py`` files.

Bad command-line input must give one ``error:`` line naming the option or file, exit
code 2, no traceback, be refused before any work, and lose nothing already stored.
The commands run for real, outside the test process, so the tests see exactly what a
user sees on the terminal. To stay fast, each test file's refused command lines share
ONE subprocess that calls :func:`snapcore.cli.main.main` (the console script's entry
point) once per case, each in its own folder, with its stdout and stderr split by
markers (:func:`run_batch`); a few cases that used to print a traceback also run alone
as ``python -m snapcore.cli.main`` (:func:`alone`).
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

#: Placeholder for the path of the real clip in the case tables.
W = "{walk}"


def walk_clip(motions_dir: Path) -> Path:
    """A small real clip (CMU 02_01, one character)."""
    return motions_dir / "walk_run" / "02_01.bvh"


@dataclass
class Run:
    rc: object
    stdout: str
    stderr: str
    folder: Path

    @property
    def output(self) -> str:
        return self.stdout + self.stderr

    def files(self) -> dict:
        return {p.name: p.read_bytes() for p in self.folder.iterdir()}


_DRIVER = r"""
import json, os, sys, traceback
from snapcore.cli.main import main
for cid, folder, args in json.load(sys.stdin):
    os.chdir(folder)
    try:
        rc = main(args)
    except BaseException:  # a crash must show up as this case's traceback
        traceback.print_exc()
        rc = "crashed"
    sys.stdout.flush()
    sys.stderr.flush()
    print(f"@@RC {rc}", flush=True)
    print("@@END", flush=True)
    print("@@END", file=sys.stderr, flush=True)
"""


def _env() -> dict:
    return {k: v for k, v in os.environ.items() if k != "SNAPSHOT_DEBUG"}


def run_batch(cases: dict, walk: Path, root: Path) -> dict:
    """Run every case in one subprocess; case id → :class:`Run`.

    ``cases`` maps an id to ``(args, files)``: the command line (``W`` stands for the
    clip) and the files to create in the case's folder first (name → bytes, or None
    for a copy of the clip).
    """
    todo, folders = [], {}
    for i, (cid, (args, files)) in enumerate(cases.items()):
        folder = root / f"case{i:03d}"
        folder.mkdir()
        for name, data in files.items():
            (folder / name).write_bytes(walk.read_bytes() if data is None else data)
        folders[cid] = folder
        todo.append([cid, str(folder), [a.format(walk=walk) for a in args]])
    proc = subprocess.run(
        [sys.executable, "-c", _DRIVER],
        input=json.dumps(todo),
        env=_env(),
        capture_output=True,
        text=True,
        timeout=300,
    )
    outs = proc.stdout.split("@@END\n")
    errs = proc.stderr.split("@@END\n")
    assert len(outs) == len(errs) == len(todo) + 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    result = {}
    for (cid, _, _), out, err in zip(todo, outs, errs):
        body, _, rc = out.rpartition("@@RC ")
        rc = rc.strip()
        result[cid] = Run(int(rc) if rc.isdigit() else rc, body, err, folders[cid])
    return result


def alone(*args, cwd) -> Run:
    """One command in its own process, as a user runs it."""
    r = subprocess.run(
        [sys.executable, "-m", "snapcore.cli.main", *map(str, args)],
        cwd=cwd,
        env=_env(),
        capture_output=True,
        text=True,
        timeout=120,
    )
    return Run(r.returncode, r.stdout, r.stderr, Path(cwd))


def one_error_line(r: Run, *names) -> str:
    """The single ``error:`` line of a refused command; it names each of ``names``."""
    out = r.output
    assert r.rc == 2, out
    assert "Traceback" not in out
    lines = [ln for ln in out.splitlines() if ln.strip()]
    assert len(lines) == 1, out
    assert lines[0].startswith("error: "), out
    assert "Usage:" not in out and "Try '" not in out
    for name in names:
        assert name in lines[0], lines[0]
    return lines[0]
