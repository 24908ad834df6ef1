"""Bad command-line input: one ``error:`` line naming the option or file, exit code 2,
no traceback, refused before any work, and nothing already stored is lost.

The commands run for real, outside the test process, so the tests see exactly what a
user sees on the terminal. To stay fast, the many refused command lines share ONE
subprocess that calls :func:`snapcore.cli.main.main` (the console script's entry point) once
per case, each in its own folder, with its stdout and stderr split by markers; a few
cases that used to print a traceback also run alone as ``python -m snapcore.cli.main``.
"""

from __future__ import annotations

import json
import os
import re
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest
from click.testing import CliRunner

from snapcore.cli.main import cli

#: Placeholder for the path of the real clip in the case tables.
W = "{walk}"

# --------------------------------------------------------------------- the cases

#: 1. Outputs the command cannot write: (args, output as given, what the line says).
SUFFIX_CASES = {
    "plot-entropy-txt": (["plot-entropy", W, "-o", "ent.txt"], "-o/--output ent.txt",
                         "plot-entropy writes .png, .pdf or .svg"),
    "plot-views-txt": (["plot-views", W, "-o", "pv.txt"], "-o/--output pv.txt",
                       "plot-views writes .png, .pdf or .svg"),
    "sheet-txt": (["sheet", W, "-o", "sh.txt"], "-o/--output sh.txt", "sheet writes .png"),
    "render-txt": (["render", W, "-o", "r.txt"], "-o/--output r.txt", "render writes .png"),
    "render-noext": (["render", W, "-o", "noext"], "-o/--output noext", "render writes .png"),
    "render-jpg": (["render", W, "-o", "x.jpg"], "-o/--output x.jpg", "render writes .png"),
    "video-txt": (["video", W, "-o", "v.txt"], "-o/--output v.txt", "video writes .mp4"),
    "video-avi": (["video", W, "-o", "v.avi"], "-o/--output v.avi", "video writes .mp4"),
    "relief-png": (["relief", W, "-o", "r.png"], "-o/--output r.png", "relief writes .stl"),
    "video-frame-map-txt": (["video", W, "-o", "v.mp4", "--frame-map", "map.txt"],
                            "--frame-map map.txt", "the frame map is written as .json"),
    "relief-preview-jpg": (["relief", W, "-o", "r.stl", "--preview", "p.jpg"],
                           "--preview p.jpg", "relief writes its preview as .png"),
}

#: 1. Outputs in a folder that does not exist: (args, option and output).
FOLDER_CASES = {
    "render": (["render", W, "-o", "missing/x.png"], "-o/--output missing/x.png"),
    "plot-entropy": (["plot-entropy", W, "-o", "missing/e.pdf"], "-o/--output missing/e.pdf"),
    "video": (["video", W, "-o", "missing/v.mp4"], "-o/--output missing/v.mp4"),
    "relief": (["relief", W, "-o", "missing/r.stl"], "-o/--output missing/r.stl"),
    "relief-preview": (["relief", W, "--preview", "missing/p.png"], "--preview missing/p.png"),
    "select": (["select", W, "-o", "missing/s.json"], "-o/--output missing/s.json"),
}

#: 3. Numbers: (args, what the line names).
NUMBER_CASES = {
    f"info{opt}={v}": (["info", W, opt, v], [f"'{opt}'", "positive finite number", f"'{v}'"])
    for opt in ("--fps", "--scale") for v in ("nan", "inf", "0", "-1")
} | {
    "video--motion-fps=0": (["video", W, "-o", "v.mp4", "--motion-fps", "0"], ["'--motion-fps'"]),
    "video--motion-fps=nan": (["video", W, "-o", "v.mp4", "--motion-fps", "nan"],
                              ["'--motion-fps'"]),
    "video--scale=-1": (["video", W, "-o", "v.mp4", "--scale", "-1"], ["'--scale'"]),
    "video--fps=nan": (["video", W, "-o", "v.mp4", "--fps", "nan"], ["'--fps'", "finite"]),
    "relief--depth=0": (["relief", W, "--depth", "0"], ["'--depth'"]),
    "relief--base=inf": (["relief", W, "--base", "inf"], ["'--base'"]),
    "render--fps=inf": (["render", W, "-o", "x.png", "--fps", "inf"], ["'--fps'"]),
    "select--smooth=inf": (["select", W, "--smooth", "inf"], ["'--smooth'", "finite"]),
    "select--min-separation=nan": (["select", W, "--min-separation", "nan"],
                                   ["'--min-separation'", "finite"]),
    "plot-views--window=nan": (["plot-views", W, "-o", "v.png", "--window", "nan"],
                               ["'--window'", "finite"]),
}

#: 4. Click's own errors, and a click.BadParameter raised by a command.
USAGE_CASES = {
    "unknown-option": (["info", W, "--frame", "3"], ["No such option", "--frame"]),
    "misspelt-option": (["info", W, "--fpz", "3"], ["No such option", "--fpz", "--fps"]),
    "missing-argument": (["info"], ["Missing argument", "PATHS"]),
    "unknown-command": (["nope"], ["No such command", "nope"]),
    "unknown-group-option": (["--bogus"], ["No such option", "--bogus"]),
    "not-an-integer": (["render", W, "--frame", "x", "-o", "x.png"], ["'--frame'", "'x'"]),
    "bad-choice": (["render", W, "--fit", "bad", "-o", "x.png"], ["'--fit'", "'bad'"]),
    "bad-size": (["render", W, "--size", "3x3", "-o", "x.png"], ["'--size'", "3x3"]),
    "unknown-subcommand": (["stimuli", "bogus"], ["No such command", "bogus"]),
    "frame-outside-scene": (["render", W, "--frame", "99999", "--view", "0,0,1", "-o", "x.png"],
                            ["--frame", "frame 99999 is not in this scene"]),
}

#: 5. Malformed vectors (without --frame the commands would select the pose first).
VECTOR_CASES = {
    "render-two-numbers": (["render", W, "-o", "x.png", "--view", "1,2"], ["'--view'", "'1,2'"]),
    "render-letters": (["render", W, "-o", "x.png", "--view", "a,b,c"], ["'--view'", "'a,b,c'"]),
    "render-nan": (["render", W, "-o", "x.png", "--view", "nan,1,0"], ["'--view'", "'nan,1,0'"]),
    "sheet-zero": (["sheet", W, "-o", "x.png", "--view", "0,0,0"], ["'--view'", "'0,0,0'"]),
    "sheet-views": (["sheet", W, "-o", "x.png", "--views", "a=0,0,1", "--views", "b=1,2"],
                    ["'--views'", "'1,2'"]),
    "sheet-views-no-name": (["sheet", W, "-o", "x.png", "--views", "a0,0,1"],
                            ["'--views'", "NAME=x,y,z"]),
    "video": (["video", W, "-o", "v.mp4", "--view", "1,2,x"], ["'--view'", "'1,2,x'"]),
    "relief": (["relief", W, "--view", "1,2"], ["'--view'", "'1,2'"]),
}

#: Files that exist before a case runs, and must be unchanged after it.
OLD_PNG, OLD_STL = b"an older picture", b"an older STL"
RELIEF_CASES = {
    "png-output": (["relief", W, "-o", "r4.png"], ["-o/--output r4.png", "relief writes .stl"]),
    "preview-is-output": (["relief", W, "-o", "r5.stl", "--preview", "r5.stl"],
                          ["--preview r5.stl", "relief writes its preview as .png"]),
}
RELIEF_FILES = {"r4.png": OLD_PNG, "r5.stl": OLD_STL}


def _all_cases() -> dict:
    """Every batched case: id → (args, files to create first)."""
    cases = {}
    for group, table in (("suffix", SUFFIX_CASES), ("folder", FOLDER_CASES),
                         ("number", NUMBER_CASES), ("usage", USAGE_CASES),
                         ("vector", VECTOR_CASES)):
        for cid, row in table.items():
            cases[f"{group}:{cid}"] = (row[0], {})
    for cid, row in RELIEF_CASES.items():
        cases[f"relief:{cid}"] = (row[0], RELIEF_FILES)
    cases["select:input"] = (["select", "walk.bvh", "-o", "walk.bvh", "--no-view"],
                             {"walk.bvh": None})  # None: a copy of the clip
    cases["help:none"] = ([], {})
    cases["help:--help"] = (["--help"], {})
    cases["help:render"] = (["render", "--help"], {})
    cases["help:--version"] = (["--version"], {})
    cases["help:study"] = (["study", "--help"], {})
    return cases


# ------------------------------------------------------------------- the runner


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


@pytest.fixture(scope="module")
def walk(motions_dir):
    """A small real clip (CMU 02_01, one character)."""
    return motions_dir / "walk_run" / "02_01.bvh"


@pytest.fixture(scope="module")
def runs(walk, tmp_path_factory) -> dict:
    """Run every case of the tables in one subprocess; case id → :class:`Run`."""
    root = tmp_path_factory.mktemp("cli_errors")
    todo, folders = [], {}
    for i, (cid, (args, files)) in enumerate(_all_cases().items()):
        folder = root / f"case{i:03d}"
        folder.mkdir()
        for name, data in files.items():
            (folder / name).write_bytes(walk.read_bytes() if data is None else data)
        folders[cid] = folder
        todo.append([cid, str(folder), [a.format(walk=walk) for a in args]])
    proc = subprocess.run([sys.executable, "-c", _DRIVER], input=json.dumps(todo), env=_env(),
                          capture_output=True, text=True, timeout=300)
    outs = proc.stdout.split("@@END\n")
    errs = proc.stderr.split("@@END\n")
    assert len(outs) == len(errs) == len(todo) + 1, proc.stdout[-2000:] + proc.stderr[-2000:]
    result = {}
    for (cid, _, _), out, err in zip(todo, outs, errs):
        body, _, rc = out.rpartition("@@RC ")
        rc = rc.strip()
        result[cid] = Run(int(rc) if rc.isdigit() else rc, body, err, folders[cid])
    return result


def _alone(*args, cwd) -> Run:
    """One command in its own process, as a user runs it."""
    r = subprocess.run([sys.executable, "-m", "snapcore.cli.main", *map(str, args)], cwd=cwd,
                       env=_env(), capture_output=True, text=True, timeout=120)
    return Run(r.returncode, r.stdout, r.stderr, Path(cwd))


def _one_error_line(r: Run, *names) -> str:
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


# ------------------------------------------------------------------ 1. output paths


@pytest.mark.parametrize("cid", sorted(SUFFIX_CASES))
def test_unsupported_output_suffix_is_refused_up_front(runs, cid):
    _, output, allowed = SUFFIX_CASES[cid]
    r = runs[f"suffix:{cid}"]
    assert _one_error_line(r, allowed) == f"error: {output}: {allowed}"
    assert r.files() == {}  # nothing written, not even the other outputs


@pytest.mark.parametrize("args", [["plot-entropy", "-o", "ent.txt"], ["video", "-o", "v.txt"],
                                  ["sheet", "-o", "sh.txt"]])
def test_unsupported_suffix_alone_in_a_process(walk, tmp_path, args):
    """The cases that printed a traceback (or ffmpeg's log) after all the work."""
    r = _alone(args[0], walk, *args[1:], cwd=tmp_path)
    _one_error_line(r, f"-o/--output {args[-1]}: {args[0]} writes .")
    assert r.files() == {}


@pytest.mark.parametrize("cid", sorted(FOLDER_CASES))
def test_output_folder_must_exist(runs, cid):
    r = runs[f"folder:{cid}"]
    _one_error_line(r, f"{FOLDER_CASES[cid][1]}: folder missing does not exist")
    assert r.files() == {}  # and the folder is not created either


def test_select_does_not_overwrite_its_input(runs, walk):
    r = runs["select:input"]
    _one_error_line(r, "-o/--output walk.bvh: is one of the input files")
    assert r.files() == {"walk.bvh": walk.read_bytes()}


# ---------------------------------------------------------------- 2. relief outputs


@pytest.mark.parametrize("cid", sorted(RELIEF_CASES))
def test_relief_never_overwrites_the_stl_with_its_preview(runs, cid):
    """-o must be .stl and --preview .png: existing files of either name are untouched."""
    r = runs[f"relief:{cid}"]
    _one_error_line(r, *RELIEF_CASES[cid][1])
    assert r.files() == RELIEF_FILES


def test_relief_writes_stl_and_preview_where_asked(walk, tmp_path):
    r = CliRunner().invoke(cli, ["relief", str(walk), "--frame", "10", "--view", "0,0,1",
                                 "--resolution", "16", "-o", str(tmp_path / "a.stl"),
                                 "--preview", str(tmp_path / "look.png"), "-q"])
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.stl", "look.png"]
    assert (tmp_path / "look.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


# ------------------------------------------------------------------------ 3. numbers


@pytest.mark.parametrize("cid", sorted(NUMBER_CASES))
def test_numbers_must_be_positive_and_finite(runs, cid):
    r = runs[f"number:{cid}"]
    _one_error_line(r, *NUMBER_CASES[cid][1])
    assert r.files() == {}


def test_number_error_alone_in_a_process(walk, tmp_path):
    """`info --fps nan` crashed with a traceback in scene.py."""
    _one_error_line(_alone("info", walk, "--fps", "nan", cwd=tmp_path), "'--fps'", "'nan'")


def test_tiny_positive_numbers_are_the_users_call(walk):
    """Only 'positive and finite' is enforced: no invented plausibility limits."""
    r = CliRunner().invoke(cli, ["info", str(walk), "--fps", "1e-3", "--json"])
    assert r.exit_code == 0, r.output
    assert json.loads(r.stdout)["fps"] == 0.001


# ------------------------------------------------------------- 4. click usage errors


@pytest.mark.parametrize("cid", sorted(USAGE_CASES))
def test_usage_errors_are_one_line(runs, cid):
    r = runs[f"usage:{cid}"]
    _one_error_line(r, *USAGE_CASES[cid][1])
    assert r.files() == {}


def test_help_version_and_no_arguments_are_unchanged(runs):
    r = runs["help:none"]  # `snapshot` alone: the help, as before
    assert r.output.startswith("Usage: snapshot [OPTIONS] COMMAND")
    assert "Commands:" in r.output and "render" in r.output and "error:" not in r.output
    r = runs["help:--help"]
    assert r.rc == 0 and r.stdout.startswith("Usage: snapshot [OPTIONS] COMMAND")
    assert "Commands:" in r.stdout
    r = runs["help:render"]
    assert r.rc == 0 and r.stdout.startswith("Usage: snapshot render [OPTIONS] PATHS...")
    assert "PNG file to write (.png)." in r.stdout
    r = runs["help:--version"]
    assert r.rc == 0 and r.stdout.startswith("snapshot, version ")


# ------------------------------------------------------------- 5. vectors, up front


@pytest.mark.parametrize("cid", sorted(VECTOR_CASES))
def test_bad_vector_is_refused_before_pose_selection(runs, cid):
    """Without --frame these commands first select the pose and say so on stderr
    ('frame N (selected pose)', then 'view [...]'); a bad vector stops them before."""
    r = runs[f"vector:{cid}"]
    _one_error_line(r, *VECTOR_CASES[cid][1])
    assert "selected pose" not in r.output and "view [" not in r.output
    assert r.files() == {}


# ------------------------------------------------------------------- 6. --columns


def test_sheet_columns_apply_to_view_comparisons(walk, tmp_path):
    from PIL import Image

    from snapcore.render.composites import PANEL_GAP

    def size(name, *args):
        out = tmp_path / name
        r = CliRunner().invoke(cli, ["sheet", str(walk), "-o", str(out), "--size", "64x80",
                                     "--frame", "10", *args])
        assert r.exit_code == 0, r.output
        return Image.open(out).size

    views = ["--views", "a=0,0,1", "--views", "b=1,0,0"]
    w1, h1 = size("one.png", *views, "--columns", "1")
    w2, h2 = size("row.png", *views)
    assert w1 == 64 + 2 * PANEL_GAP and w2 == 2 * 64 + 3 * PANEL_GAP
    assert h1 > h2 + 80  # two rows
    w3, h3 = size("compare.png", "--compare", "--columns", "1")
    assert w3 == 64 + 2 * PANEL_GAP and h3 > h1  # three rows


# -------------------------------------------------------------- 7. study --help


def test_study_help_shows_prolific_placeholders_with_double_braces(runs):
    r = runs["help:study"]
    assert r.rc == 0, r.output
    url = "?PROLIFIC_PID={{%PROLIFIC_PID%}}&STUDY_ID={{%STUDY_ID%}}&SESSION_ID={{%SESSION_ID%}}"
    assert any(line.strip() == url for line in r.stdout.splitlines()), r.stdout


def test_readme_shows_export_table_options_with_their_paths():
    """README: --participants and --events take a path, as `snapshot export` wants."""
    from pathlib import Path

    readme = (Path(__file__).resolve().parents[1] / "README.md").read_text()
    # the export command's lines (select's --events, the paper's event mode, is another option)
    text = "\n".join(ln for ln in readme.splitlines() if "export" in ln)
    for opt in ("--participants", "--events"):
        uses = [text[m.start():m.start() + 40] for m in re.finditer(re.escape(opt), text)]
        assert uses and all(re.match(rf"{opt} (PATH|\S+\.(csv|jsonl))", u) for u in uses), uses
