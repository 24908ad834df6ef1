"""FBX input: the ufbx reader against Maya's own evaluation, the shared FBX files, the CLI
and `snapshot batch` over a folder mixing BVH, glTF and FBX."""

from __future__ import annotations

import csv
import shutil
import subprocess
import sys
import warnings
from pathlib import Path

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.errors import FBXError
from snapcore.motion.fbx import fbx_characters, fbx_unit, read_fbx
from tests.conftest import need

SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
KENNEY = "maya_kenney_character_7700_binary.fbx"
#: The files of ../shared/fbx/ that hold an animated skeleton; the rest are refused: the
#: fuzzed ones, three without a skeleton, and four rigs whose take moves nothing.
READABLE = {
    "blender_293_barbarian_7400_binary.fbx",
    "maya_dq_weights_7500_ascii.fbx",
    KENNEY,
}
STILL = ("maya_character_7500_binary.fbx", "maya_human_ik_7400_binary.fbx")


@pytest.fixture(scope="module")
def fbx_dir(motions_dir) -> Path:
    d = motions_dir.parent / "fbx"
    need((d / KENNEY).is_file(), f"no shared FBX files in {d}")
    return d


def _obj_vertices(path: Path) -> np.ndarray:
    rows = [ln.split()[1:4] for ln in path.read_text().splitlines() if ln.startswith("v ")]
    return np.asarray(rows, dtype=float)


@pytest.mark.parametrize("frame", [4, 9])
def test_kenney_skinned_vertices_match_mayas_own_evaluation(fbx_dir, frame):
    """Maya's OBJ of the Kenney character at frames 4 and 9: every skinned vertex within
    0.1 file units (1 mm; the file is in cm), vertex order as Maya wrote it."""
    c = read_fbx(fbx_dir / KENNEY)
    assert c.meta["first_frame"] == 0 and c.meta["unit_meters"] == 0.01
    maya = _obj_vertices(fbx_dir / f"maya_kenney_character_{frame}.obj")
    ours = c.mesh.vertices(c, frame)
    assert ours.shape == maya.shape
    assert np.abs(ours - maya).max() < 0.1
    # and the pose differs between the two frames by far more than that
    other = _obj_vertices(fbx_dir / f"maya_kenney_character_{13 - frame}.obj")
    assert np.abs(ours - other).max() > 5.0


@pytest.mark.slow
def test_every_shared_fbx_loads_or_is_refused_in_one_line(fbx_dir, tmp_path):
    """`snapshot info` on every file of ../shared/fbx/ (and a truncated copy): either it
    lists the character, joints, frames and animations, or one error line, exit 2."""
    files = sorted(fbx_dir.glob("*.fbx"))
    cut = tmp_path / "truncated.fbx"
    cut.write_bytes((fbx_dir / KENNEY).read_bytes()[:300_000])
    for f in [*files, cut]:
        r = subprocess.run([SNAPSHOT, "info", str(f)], capture_output=True, text=True, timeout=120)
        out = r.stdout + r.stderr
        assert "Traceback" not in out, out
        if f.name in READABLE:
            assert r.returncode == 0, out
            assert "joints" in r.stdout and "frames" in r.stdout and "animations" in r.stdout
        else:
            assert r.returncode == 2, out
            lines = [ln for ln in out.splitlines() if ln.strip()]
            assert len(lines) == 1 and lines[0].startswith("error: ") and f.name in lines[0]


def test_units_are_the_files_and_a_misstated_unit_is_caught(fbx_dir):
    """Kenney's file is in cm and read so; HumanIK's sample states metres for a rig in cm
    (174 m tall) and is read in cm with the reason, the same person as the Maya rig."""
    assert load_scene(fbx_dir / KENNEY).characters[0].meta["unit"] == "cm"
    rig = read_fbx(fbx_dir / "maya_character_7500_binary.fbx")
    ik = read_fbx(fbx_dir / "maya_human_ik_7400_binary.fbx")
    assert fbx_unit(rig) == (0.01, "cm", None)
    metres, unit, why = fbx_unit(ik)
    assert (metres, unit) == (0.01, "cm") and "would be 174 m tall" in why
    assert ik.rescaled(metres).height == pytest.approx(rig.rescaled(0.01).height, rel=0.05)
    assert 1.6 < rig.rescaled(0.01).height < 1.9


@pytest.mark.parametrize("name", STILL)
def test_a_take_that_moves_nothing_is_refused(fbx_dir, name):
    """A rig saved with an empty take (every joint still) is no animation: one line."""
    with pytest.raises(FBXError, match="moves no joint: there is no animation"):
        load_scene(fbx_dir / name)


def test_binary_and_ascii_of_one_rig_read_alike(fbx_dir):
    """The 6100 ASCII and 7500 binary exports of one Maya character: same joints, same
    motion (within 0.1 mm)."""
    a = read_fbx(fbx_dir / "maya_character_6100_ascii.fbx")
    b = read_fbx(fbx_dir / "maya_character_7500_binary.fbx")
    assert a.joint_names == b.joint_names and a.n_frames == b.n_frames
    assert np.abs(a.positions - b.positions).max() < 0.01  # file units: cm


def test_animation_by_name_or_index_and_an_unknown_one(fbx_dir):
    """--animation takes the take's name or index; an unknown name lists the takes."""
    path = fbx_dir / "blender_293_barbarian_7400_binary.fbx"
    by_name = read_fbx(path, animation="Armature|idle")
    by_index = read_fbx(path, animation=0)
    assert by_name.meta["animation"] == by_index.meta["animation"] == "Armature|idle"
    assert np.array_equal(by_name.positions, by_index.positions)
    with pytest.raises(FBXError, match=r"no animation 'run' \(it has: Armature\|idle\)"):
        read_fbx(path, animation="run")


def test_up_axis_is_turned_to_y(fbx_dir):
    """Joints stand along +Y whatever the file's up axis (the Maya character's head is
    above its feet by most of its height)."""
    c = read_fbx(fbx_dir / "maya_character_7500_binary.fbx")
    names = list(c.joint_names)
    head = c.positions[:, names.index("Character1_Head"), 1]
    foot = c.positions[:, names.index("Character1_LeftFoot"), 1]
    assert np.all(head - foot > 100)  # cm


def test_two_fbx_files_are_one_scene_each_wearing_its_own_mesh(fbx_dir):
    """Two FBX files make a two-character scene, each character with its own skinned
    mesh; a file's skeletons are listed by their root joint."""
    assert fbx_characters(fbx_dir / KENNEY) == ["LeftFootCtrl"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        s = load_scene([fbx_dir / KENNEY, fbx_dir / "maya_dq_weights_7500_ascii.fbx"])
    assert len(s.characters) == 2
    assert all(c.mesh is not None for c in s.characters)
    assert s.characters[0].mesh.n_vertices != s.characters[1].mesh.n_vertices


@pytest.mark.slow
def test_batch_indexes_a_folder_mixing_bvh_gltf_and_fbx(fbx_dir, motions_dir, tmp_path):
    """`snapshot batch` over BVH, glTF and FBX files: every clip is a row without error."""
    lib = tmp_path / "lib"
    lib.mkdir()
    shutil.copy(motions_dir / "walk_run" / "02_01.bvh", lib / "walk.bvh")
    shutil.copy(motions_dir / "gltf" / "CesiumMan.glb", lib / "cesium.glb")
    shutil.copy(fbx_dir / KENNEY, lib / "kenney.fbx")
    shutil.copy(fbx_dir / "maya_dq_weights_7500_ascii.fbx", lib / "maya.fbx")
    out = tmp_path / "out"
    args = ["--no-baselines", "--size", "160x180", "-q"]
    r = subprocess.run(
        [SNAPSHOT, "batch", str(lib), "-o", str(out), *args],
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    with open(out / "index.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {row["path"] for row in rows} == {"walk.bvh", "cesium.glb", "kenney.fbx", "maya.fbx"}
    for row in rows:
        assert row["status"] == "ok" and not row["error"], row
    assert {row["kind"] for row in rows} == {"bvh", "gltf", "fbx"}
