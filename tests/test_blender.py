"""The Blender add-on in real Blender (the ``bpy`` module, headless) on three shared BVH
clips, and Blender's own FBX export of them read back by the FBX reader."""

from __future__ import annotations

import importlib.util
import json
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.cli.blender import build_addon
from tests.conftest import need

SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
DRIVER = Path(__file__).with_name("blender_driver.py")
#: A CMU clip (cgspeed, zero-length end sites), a Daz-style one, a Bandai Namco one.
CLIPS = {
    "cmu": "walk_run/02_01.bvh",
    "daz": "soccer/11_01.bvh",
    "bandai": "walk_run/dataset-2_run_normal_001.bvh",
}


def _angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    c = a @ b / np.linalg.norm(a) / np.linalg.norm(b)
    return float(np.degrees(np.arccos(np.clip(c, -1.0, 1.0))))


def _start_select(path: Path) -> subprocess.Popen:
    """`snapshot select` on a file, started (it runs beside Blender)."""
    return subprocess.Popen(
        [SNAPSHOT, "select", str(path), "--json", "--no-baselines", "-k", "3"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )


def _finish_select(proc: subprocess.Popen) -> dict:
    out, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    return json.loads(out)


@pytest.fixture(scope="module")
def blender_run(motions_dir, tmp_path_factory):
    """One Blender process: each clip imported by Blender's BVH importer, exported by its
    FBX exporter, and snapshot by the add-on's operator (what Blender shows, per clip),
    with `snapshot select` on the BVH file itself (run beside it)."""
    need(importlib.util.find_spec("bpy") is not None, "bpy is not installed (make test does)")
    folder = tmp_path_factory.mktemp("blender")
    clips = []
    for key, rel in CLIPS.items():
        scene = load_scene(motions_dir / rel)
        clips.append(
            {
                "key": key,
                "bvh": str(motions_dir / rel),
                "scale": scene.characters[0].scale,  # Blender units = metres
                "fbx": str(folder / f"{key}.fbx"),
            }
        )
    spec = {
        "addon": str(build_addon(folder / "action_snapshot.zip")),
        "snapshot": SNAPSHOT,
        "out": str(folder / "result.json"),
        "clips": clips,
        "pair": str(folder / "pair.fbx"),
    }
    (folder / "spec.json").write_text(json.dumps(spec), encoding="utf-8")
    # `snapshot select` on each BVH file itself, beside the Blender process
    selects = {key: _start_select(motions_dir / rel) for key, rel in CLIPS.items()}
    r = subprocess.run(
        [sys.executable, str(DRIVER), str(folder / "spec.json")],
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert r.returncode == 0, r.stdout[-3000:] + r.stderr[-3000:]
    results = json.loads((folder / "result.json").read_text(encoding="utf-8"))
    chosen = {key: _finish_select(p) for key, p in selects.items()}
    # `snapshot select` on Blender's own FBX export of each imported clip: the armature
    # as Blender holds it (its importer gives zero-length BVH end sites a length).
    exported = {c["key"]: _start_select(Path(c["fbx"])) for c in clips}
    in_blender = {key: _finish_select(p) for key, p in exported.items()}
    out = {c["key"]: (c, res, chosen[c["key"]]) for c, res in zip(clips, results)}
    out["pair"] = spec["pair"]
    out["in_blender"] = in_blender
    return out


@pytest.mark.slow
@pytest.mark.parametrize("key", list(CLIPS))
def test_blender_fbx_export_reads_back_to_the_bvhs_own_kinematics(blender_run, key):
    """Blender's FBX of the imported BVH: every BVH joint within 1 mm of the BVH's own
    forward kinematics on every frame, same frame count, rate and T-pose cut."""
    clip, _, _ = blender_run[key]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        bvh = load_scene(clip["bvh"], drop_tpose=False)
        fbx = load_scene(clip["fbx"], drop_tpose=False)
    cb, cf = bvh.characters[0], fbx.characters[0]
    assert (cf.n_frames, cf.fps) == (cb.n_frames, cb.fps)
    joints = [n for n, end in zip(cb.joint_names, cb.skeleton.end_site) if not end]
    assert set(joints) <= set(cf.joint_names)
    ib = [cb.joint_names.index(n) for n in joints]
    jf = [cf.joint_names.index(n) for n in joints]
    err = np.linalg.norm(cb.positions[:, ib] - cf.positions[:, jf], axis=-1)
    assert err.max() < 1e-3, f"{err.max() * 1000:.3f} mm"
    assert load_scene(clip["bvh"]).frame_offset == load_scene(clip["fbx"]).frame_offset


@pytest.mark.slow
@pytest.mark.parametrize("key", list(CLIPS))
def test_addon_markers_are_snapshot_selects_top_k(blender_run, key):
    """The add-on's timeline markers sit on `snapshot select`'s top-k of the FBX it
    exported, Blender frame = the action's first frame + snapshot's 0-based source frame;
    that selection's story pick is the BVH file's, and its other top-k poses within one
    frame of the BVH's."""
    _, res, sel = blender_run[key]
    assert res["operator"] == ["FINISHED"]
    markers = [frame for _, frame in res["markers"]]
    picked = res["result"]["snapshot_frames"]
    assert markers == [res["action_start"] + f for f in picked]
    assert picked[0] == sel["frames"][0]
    # The re-exported joints differ from the BVH's by micrometres (test_blender_fbx_export_reads_back_to_the_bvhs_own_kinematics);
    # a speed peak between two nearly equal frames (the story's strikes term) may then
    # fall one frame over, so the lesser poses may move by a frame, never further.
    assert len(picked) == len(sel["frames"])
    assert all(abs(a - b) <= 1 for a, b in zip(picked, sel["frames"], strict=True))


@pytest.mark.slow
@pytest.mark.parametrize(
    "key",
    [
        pytest.param(
            "cmu",
            marks=pytest.mark.xfail(
                strict=True,
                reason="CMU end sites have zero length; Blender's importer cannot make "
                "zero-length bones, so its tips sit 5.6 mm off and the PMA view of the "
                "re-exported clip turns by 2.2 degrees (docs/fbx.md)",
            ),
        ),
        "daz",
        "bandai",
    ],
)
def test_addon_camera_looks_along_the_pma_view(blender_run, key):
    """The add-on's camera looks along `snapshot select`'s PMA view of the BVH file
    (within 2 degrees), at the character (its bones' centre within 10 degrees of the
    line of sight)."""
    _, res, sel = blender_run[key]
    assert _angle_deg(res["camera_view"], res["result"]["view"]) < 0.01  # placed as computed
    assert res["centre_angle_deg"] < 10
    assert _angle_deg(res["camera_view"], sel["view"]) < 2.0


@pytest.mark.slow
@pytest.mark.parametrize("key", list(CLIPS))
def test_addon_camera_looks_along_the_pma_view_of_the_armature_in_blender(blender_run, key):
    """The add-on's camera looks along the PMA view (within 2 degrees) of the armature as
    Blender holds it, read from Blender's FBX export by `snapshot select` in its own
    process: on every clip, CMU's included, whose BVH end sites Blender cannot keep at
    zero length (the test above holds the camera to the BVH file's view where Blender's
    armature is the BVH's)."""
    _, res, _ = blender_run[key]
    assert _angle_deg(res["camera_view"], blender_run["in_blender"][key]["view"]) < 2.0


@pytest.mark.slow
def test_two_armatures_in_one_fbx_file_are_two_characters(blender_run):
    """Blender's FBX of two armatures (the CMU clip, the Daz clip moved 2 m along x):
    two characters, each one's joints within 1 mm of its own BVH's on every frame."""
    from snapcore.motion.fbx import fbx_characters

    path = blender_run["pair"]
    assert len(fbx_characters(path)) == 2
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        pair = load_scene(path, drop_tpose=False).characters
        for k, key in enumerate(("cmu", "daz")):
            bvh = load_scene(blender_run[key][0]["bvh"], drop_tpose=False).characters[0]
            joints = [n for n, end in zip(bvh.joint_names, bvh.skeleton.end_site) if not end]
            fbx = next(c for c in pair if set(joints) <= set(c.joint_names))
            ib = [bvh.joint_names.index(n) for n in joints]
            jf = [fbx.joint_names.index(n) for n in joints]
            moved = bvh.positions[:, ib] + np.array([2.0 * k, 0.0, 0.0])
            n = min(fbx.n_frames, bvh.n_frames)
            assert np.abs(fbx.positions[:n, jf] - moved[:n]).max() < 1e-3
