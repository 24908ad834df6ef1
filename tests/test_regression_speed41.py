"""The speed work of issue 41 changes no result: parse + FK, story, paper and PMA view.

The reference ``tests/regression/speed41_outputs.json`` was recorded by
``tests/regression/record_speed41.py`` on the commit it names, the base of that work,
before any of it (recorded twice there: byte-identical files). Every clip of the shared
data is loaded and selected again here and compared:

- joint positions and rotations bit-identical (a digest): every later stage reads them;
- ``paper``: picks equal and the score curve bit-identical (a digest);
- ``story``: picks equal, the score curve within 1e-9 (relative) — reordered sums may
  move the last bits, never the picks;
- PMA view: the grid and refined directions and their scores within 1e-9.
"""

from __future__ import annotations

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

HERE = Path(__file__).resolve().parent
REFERENCE = json.loads((HERE / "regression" / "speed41_outputs.json").read_text())

pytestmark = pytest.mark.slow


def _recorder():
    spec = importlib.util.spec_from_file_location(
        "record_speed41", HERE / "regression" / "record_speed41.py"
    )
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


@pytest.mark.parametrize("name", list(REFERENCE["cases"]))
def test_outputs_match_base_commit(motions_dir, monkeypatch, name):
    """One clip's motion, picks, score curves and PMA view equal the recording."""
    monkeypatch.setenv("SNAPSHOT_DATA", str(motions_dir))
    case = REFERENCE["cases"][name]
    want = case["output"]
    got = _recorder().outputs(case["paths"], case["kwargs"])
    assert got["n_frames"] == want["n_frames"]
    assert got["motion_digest"] == want["motion_digest"], "positions/rotations changed"
    assert got["paper"] == want["paper"], "paper is no longer bit-identical"
    assert got["story"]["index"] == want["story"]["index"]
    assert got["story"]["indices"] == want["story"]["indices"]
    np.testing.assert_allclose(got["story"]["total"], want["story"]["total"], rtol=1e-9, atol=1e-12)
    for key in ("view", "view_grid", "score", "score_grid"):
        np.testing.assert_allclose(got["view"][key], want["view"][key], rtol=1e-9, atol=1e-12)
