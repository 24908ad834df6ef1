"""Record what the speed work of issue 41 must not change, on every shared clip.

For each clip: a digest of the loaded scene's joint positions and rotations (parse + FK
must stay bit-identical, since every later stage reads them), the ``story`` method's
picks and its score curve, the ``paper`` method's picks and a digest of its score
curve (bit-identical), and the PMA view (grid and refined direction, scores).

Run on the commit whose outputs are the reference (the base of the issue-41 speed
work, before any of it) and commit the JSON with the hash it names:

    .venv/bin/python tests/regression/record_speed41.py  # writes speed41_outputs.json

tests/test_regression_speed41.py recomputes the same values and compares.
"""

from __future__ import annotations

import hashlib
import json
import os
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
ROOT = HERE.parents[1]

# (name, paths relative to SNAPSHOT_DATA, load_scene keyword arguments): every clip in
# the shared data (BVH and glTF), the salsa pairs at their true 60 fps.
CASES = [
    ("jumpshot", ["basketball/06_15_jumpshot_excerpt.bvh"], {}),
    ("boxing_01_01", ["boxing_jump/01_01.bvh"], {}),
    ("boxing_toes", ["boxing_jump/Boxing_Toes.bvh"], {}),
    ("punch", ["boxing_jump/dataset-1_punch_normal_001.bvh"], {}),
    ("dance_05_06", ["dance/05_06.bvh"], {}),
    ("dance_bandai", ["dance/dataset-1_dance-short_normal_001.bvh"], {}),
    ("soccer_10_01", ["soccer/10_01.bvh"], {}),
    ("soccer_11_01", ["soccer/11_01.bvh"], {}),
    ("walk_02_01", ["walk_run/02_01.bvh"], {}),
    ("run_02_03", ["walk_run/02_03.bvh"], {}),
    ("walk_131_01", ["walk_run/131_01.bvh"], {}),
    ("run_bandai", ["walk_run/dataset-2_run_normal_001.bvh"], {}),
    ("cc_base_002_01", ["cc_base/002_01.bvh"], {}),
    ("salsa_01", ["two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"], {"fps": 60}),
    ("salsa_12", ["two_person/60_12_scaled.bvh", "two_person/61_12_scaled.bvh"], {"fps": 60}),
    ("gltf_cesium_man", ["gltf/CesiumMan.glb"], {}),
    ("gltf_fox", ["gltf/Fox.glb"], {}),
    ("gltf_brainstem", ["gltf/BrainStem.glb"], {}),
]


def data_dir() -> Path:
    return Path(os.environ.get("SNAPSHOT_DATA", ROOT.parent / "shared" / "motions"))


def digest(*arrays) -> str:
    """SHA-256 of the arrays' bytes (C order, their own dtype): equal only when bit-identical."""
    h = hashlib.sha256()
    for a in arrays:
        h.update(np.ascontiguousarray(a).tobytes())
    return h.hexdigest()


def outputs(paths: list[str], kwargs: dict) -> dict:
    """The values the reference keeps for one clip (see the module docstring)."""
    from snapcore.motion.load import load_scene
    from snapcore.select.pose_methods import select_pose
    from snapcore.select.view import select_view

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the salsa unit is fitted, which warns
        scene = load_scene([str(data_dir() / p) for p in paths], **kwargs)
        story = select_pose(scene, method="story", k=3)
        paper = select_pose(scene, method="paper", k=3)
        view = select_view(scene)
    chars = scene.characters
    return {
        "n_frames": scene.n_frames,
        "motion_digest": digest(*[c.positions for c in chars], *[c.rotations for c in chars]),
        "story": {
            "index": story.index,
            "indices": list(story.indices),
            "total": story.scores.total.tolist(),
        },
        "paper": {
            "index": paper.index,
            "indices": list(paper.indices),
            "total_digest": digest(paper.scores.total),
        },
        "view": {
            "view": view.view.tolist(),
            "view_grid": view.view_grid.tolist(),
            "score": float(view.score),
            "score_grid": float(view.score_grid),
        },
    }


def main() -> None:
    commit = subprocess.run(
        ["git", "rev-parse", "HEAD"], cwd=ROOT, check=True, capture_output=True, text=True
    ).stdout.strip()
    cases = {}
    for name, paths, kwargs in CASES:
        cases[name] = {"paths": paths, "kwargs": kwargs, "output": outputs(paths, kwargs)}
        print(name, cases[name]["output"]["story"]["indices"], file=sys.stderr)
    doc = {"commit": commit, "cases": cases}
    (HERE / "speed41_outputs.json").write_text(json.dumps(doc, indent=1) + "\n")


if __name__ == "__main__":
    main()
