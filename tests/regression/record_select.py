"""Record `snapshot select --json` on every shared clip and both salsa pairs.

The recorded documents are the reference for the no-behaviour-change tests
(tests/test_regression_select.py): run this on the commit whose outputs are the
reference, and commit the JSON together with the commit hash it names.

    .venv/bin/python tests/regression/record_select.py  # writes select_outputs.json
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

# (name, paths relative to SNAPSHOT_DATA, extra CLI arguments)
CASES = [
    ("jumpshot", ["basketball/06_15_jumpshot_excerpt.bvh"], []),
    ("boxing_01_01", ["boxing_jump/01_01.bvh"], []),
    ("boxing_toes", ["boxing_jump/Boxing_Toes.bvh"], []),
    ("punch", ["boxing_jump/dataset-1_punch_normal_001.bvh"], []),
    ("dance_05_06", ["dance/05_06.bvh"], []),
    ("dance_bandai", ["dance/dataset-1_dance-short_normal_001.bvh"], []),
    ("soccer_10_01", ["soccer/10_01.bvh"], []),
    ("soccer_11_01", ["soccer/11_01.bvh"], []),
    ("walk_02_01", ["walk_run/02_01.bvh"], []),
    ("run_02_03", ["walk_run/02_03.bvh"], []),
    ("walk_131_01", ["walk_run/131_01.bvh"], []),
    ("run_bandai", ["walk_run/dataset-2_run_normal_001.bvh"], []),
    ("salsa_01", ["two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"], ["--fps", "60"]),
    ("salsa_12", ["two_person/60_12_scaled.bvh", "two_person/61_12_scaled.bvh"], ["--fps", "60"]),
]

# What must not change; timings and the version stamp may.
KEYS = (
    "frame",
    "frames",
    "peaks",
    "pose_entropy",
    "events",
    "fps",
    "n_frames",
    "frame_offset",
    "view",
    "view_refined",
    "baselines",
    "pma",
    "window",
)


def data_dir() -> Path:
    return Path(os.environ.get("SNAPSHOT_DATA", ROOT.parent / "shared" / "motions"))


def run_case(paths: list[str], extra: list[str], method_args: list[str] | None = None) -> dict:
    exe = Path(sys.executable).with_name("snapshot")
    cmd = [str(exe), "select", *[str(data_dir() / p) for p in paths], *extra, "--json"]
    cmd += method_args or []
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def main() -> None:
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout.strip()
    cases = {}
    for name, paths, extra in CASES:
        doc = run_case(paths, extra)
        cases[name] = {
            "paths": paths,
            "args": extra,
            "output": {k: doc[k] for k in KEYS if k in doc},
        }
        print(name, doc["frame"], file=sys.stderr)
    out = {"commit": commit, "cases": cases}
    (HERE / "select_outputs.json").write_text(json.dumps(out, indent=1) + "\n")


if __name__ == "__main__":
    main()
