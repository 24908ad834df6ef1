"""One error edge for every ``snapshot`` command: NaN (or infinity), a negative count, a
missing file and a wrong database URL each give one ``error:`` line, exit code 2 and no traceback,
for snapcore's commands, the study's and the analysis's alike (the runner and the
rules: ``cli_helpers``).

The table below has a row for every command the ``snapshot`` group lists (subcommands
of a group too): a new command without its row fails
:func:`test_every_command_has_its_bad_input_cases`. A kind of bad input a command has
no option for (a command without a database has no URL to get wrong) is left out of its
row; every command has at least one case.
"""

from __future__ import annotations

import click
import pytest
from cli_helpers import W, one_error_line, run_batch, walk_clip

#: A database URL no driver reads (the scheme is nobody's).
BAD_URL = "nosuch://nobody@nowhere/db"

#: command (as typed after ``snapshot``) → kind of bad input → its command line.
CASES: dict[str, dict[str, list[str]]] = {
    "info": {
        "nan": ["info", W, "--fps", "nan"],
        "negative": ["info", W, "--scale", "-2"],
        "missing": ["info", "nope.bvh"],
    },
    "bench": {"negative": ["bench", "--repeats", "-1"]},
    "batch": {
        "nan": ["batch", W, "-o", "lib", "--min-separation", "nan"],
        "negative": ["batch", W, "-o", "lib", "--jobs", "-2"],
        "missing": ["batch", "nope.bvh", "-o", "lib"],
    },
    "gallery": {
        "negative": ["gallery", ".", "--port", "-1"],
        "missing": ["gallery", "nope"],
    },
    "select": {
        "nan": ["select", W, "--smooth", "nan"],
        "negative": ["select", W, "-k", "-1"],
        "missing": ["select", "nope.bvh"],
    },
    "keymoments": {
        "negative": ["keymoments", W, "-k", "-1"],
        "missing": ["keymoments", "nope.json"],
    },
    "plot-entropy": {
        "nan": ["plot-entropy", W, "--w-local", "nan", "-o", "e.png"],
        "negative": ["plot-entropy", W, "--strip", "-1", "-o", "e.png"],
        "missing": ["plot-entropy", "nope.bvh", "-o", "e.png"],
    },
    "plot-views": {
        "nan": ["plot-views", W, "--window", "nan", "-o", "v.png"],
        "negative": ["plot-views", W, "--n-views", "-12", "-o", "v.png"],
        "missing": ["plot-views", "nope.bvh", "-o", "v.png"],
    },
    "render": {
        "nan": ["render", W, "--fps", "nan", "-o", "r.png"],
        "negative": ["render", W, "--frame", "-5", "-o", "r.png"],
        "missing": ["render", "nope.bvh", "-o", "r.png"],
    },
    "video": {
        "nan": ["video", W, "--fps", "nan", "-o", "v.mp4"],
        "negative": ["video", W, "--fps", "-24", "-o", "v.mp4"],
        "missing": ["video", "nope.bvh", "-o", "v.mp4"],
    },
    "sheet": {
        "nan": ["sheet", W, "--scale", "nan", "-o", "s.png"],
        "negative": ["sheet", W, "--top", "-1", "-o", "s.png"],
        "missing": ["sheet", "nope.bvh", "-o", "s.png"],
    },
    "relief": {
        "nan": ["relief", W, "--depth", "nan", "-o", "r.stl"],
        "negative": ["relief", W, "--resolution", "-1", "-o", "r.stl"],
        "missing": ["relief", "nope.bvh", "-o", "r.stl"],
    },
    "blender-addon": {"missing": ["blender-addon", "-o", "no/such/folder/addon.zip"]},
    "stimuli build": {"missing": ["stimuli", "build", "nope.toml", "-o", "out"]},
    "stimuli sheet": {"missing": ["stimuli", "sheet", "nope", "-o", "s.png"]},
    "stimuli verify": {"missing": ["stimuli", "verify", "nope"]},
    "study": {
        "negative": ["study", "--port", "-1", "--db", "sqlite:///s.db"],
        "missing": ["study", "--config", "nope.toml", "--db", "sqlite:///s.db"],
        "url": ["study", "--db", BAD_URL, "--stimuli", "."],
    },
    "export": {
        "missing": ["export", "--db", "sqlite:///nope.db", "-o", "out.csv"],
        "url": ["export", "--db", BAD_URL, "-o", "out.csv"],
    },
    "loadtest": {
        "nan": ["loadtest", "--url", "http://127.0.0.1:9", "--ramp", "nan"],
        "negative": ["loadtest", "--url", "http://127.0.0.1:9", "-n", "-1"],
        "url": ["loadtest", "--url", "http://127.0.0.1:9", "--db", BAD_URL],
    },
    "serve": {
        "negative": ["serve", "--replicas", "-1"],
        "missing": ["serve", "--config", "nope.toml", "--db", "sqlite:///s.db"],
        "url": ["serve", "--db", BAD_URL, "--stimuli", "."],
    },
    "withdraw": {"url": ["withdraw", "--db", BAD_URL, "--pid", "x"]},
    "backup": {
        "missing": ["backup", "--verify", "nope.dump"],
        "url": ["backup", "--db", BAD_URL, "-o", "b.dump"],
    },
    "restore": {
        "missing": ["restore", "nope.dump", "--db", "sqlite:///r.db"],
        "url": ["restore", "b.dump", "--db", BAD_URL],
    },
    "anonymise": {"url": ["anonymise", "--db", BAD_URL, "--study", "s", "--yes"]},
    "analyze": {
        "nan": ["analyze", "--db", "sqlite:///a.db", "--alpha", "nan"],
        "negative": ["analyze", "--db", "sqlite:///a.db", "--boot", "-1"],
        "missing": ["analyze", "--input", "nope.csv"],
        "url": ["analyze", "--db", BAD_URL],
    },
    "simulate": {
        "nan": ["simulate", "--n", "3", "--db", "sqlite:///sim.db", "--lapse", "nan"],
        "negative": ["simulate", "--n", "-3", "--db", "sqlite:///sim.db"],
        "missing": ["simulate", "--n", "3", "--db", "sqlite:///sim.db", "--stimuli", "nope"],
        "url": ["simulate", "--n", "3", "--db", BAD_URL],
        "infinite": [
            "simulate",
            "--n",
            "3",
            "--db",
            "sqlite:///sim.db",
            "--strengths",
            "ours=inf,viewpoint_entropy=1,motion_area=1",
        ],
    },
    "power": {
        "nan": ["power", "--ours", "nan", "--baseline", "0.4"],
        "infinite": ["power", "--ours", "0.5", "--baseline", "inf"],
        "negative": ["power", "--comparisons", "-1"],
    },
    "figures": {
        "negative": ["figures", "--repeats", "-1"],
        "missing": ["figures", "--input", "nope.csv"],
        "url": ["figures", "--db", BAD_URL],
    },
    "calibrate": {
        "nan": ["calibrate", "--alpha", "nan"],
        "negative": ["calibrate", "--participants", "-1"],
        "missing": ["calibrate", "--stimuli", "nope"],
    },
}

#: Files a case's folder holds first (name → bytes; None: a copy of the clip).
FILES = {"restore:url": {"b.dump": b"not a backup"}}


def _commands() -> set[str]:
    """Every command the ``snapshot`` group lists, a group's subcommands by full name."""
    from snapcore.cli.main import cli

    ctx = click.Context(cli)
    out = set()

    def walk(group, prefix):
        for name in group.list_commands(ctx):
            cmd = group.get_command(ctx, name)
            full = f"{prefix} {name}".strip()
            if isinstance(cmd, click.Group):
                walk(cmd, full)
            else:
                out.add(full)

    walk(cli, "")
    return out


def test_every_command_has_its_bad_input_cases():
    """A command added to ``snapshot`` without a row here fails: its error edge is untested."""
    assert set(CASES) == _commands()
    assert all(CASES.values())


IDS = sorted(f"{cmd}:{kind}" for cmd, kinds in CASES.items() for kind in kinds)


@pytest.fixture(scope="module")
def runs(motions_dir, tmp_path_factory) -> dict:
    cases = {}
    for cid in IDS:
        cmd, kind = cid.split(":")
        cases[cid] = (CASES[cmd][kind], FILES.get(cid, {}))
    return run_batch(cases, walk_clip(motions_dir), tmp_path_factory.mktemp("cli_errors_all"))


@pytest.mark.parametrize("cid", IDS)
def test_bad_input_is_one_line_exit_2(runs, cid):
    one_error_line(runs[cid])
