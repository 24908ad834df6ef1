"""Forward kinematics, units and scenes: analytic chains, independent references, real data."""

from __future__ import annotations

import itertools
import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from snapcore import load_scene
from snapcore.errors import SceneError, SchemaError
from snapcore.motion.bvh import BVHDocument, parse_bvh, write_bvh
from snapcore.motion.scene import KNOWN_UNITS, character_from_bvh

ORDERS = ["".join(p) for p in itertools.permutations("XYZ")]


def chain_document(order: str, motion: np.ndarray) -> BVHDocument:
    """A 3-joint chain (root with 6 channels, two 3-channel joints, one end site)."""
    rot = tuple(f"{a}rotation" for a in order)
    return BVHDocument(
        names=("root", "a", "b", "b_End"),
        parents=np.array([-1, 0, 1, 2]),
        offsets=np.array([[0.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.5, 0.0, 0.0], [0.0, 0.0, 0.25]]),
        channels=(("Xposition", "Yposition", "Zposition") + rot, rot, rot, ()),
        end_site=np.array([False, False, False, True]),
        frame_time=1 / 30,
        motion=motion,
        path="chain.bvh",
    )


@pytest.mark.parametrize("order", ORDERS)
def test_fk_matches_scipy_reference_for_every_channel_order(order):
    """FK of a 3-joint chain equals positions composed with SciPy's intrinsic Euler rotations."""
    rng = np.random.default_rng(7)
    f = 20
    motion = np.concatenate([rng.normal(size=(f, 3)), rng.uniform(-180, 180, size=(f, 9))], axis=1)
    doc = chain_document(order, motion)
    c = character_from_bvh(doc, scale=1.0)
    # Independent reference: SciPy with upper-case (intrinsic) axes is BVH's convention;
    # compose one frame at a time with plain matrix products.
    for i in range(f):
        r0 = Rotation.from_euler(order, motion[i, 3:6], degrees=True).as_matrix()
        r1 = Rotation.from_euler(order, motion[i, 6:9], degrees=True).as_matrix()
        r2 = Rotation.from_euler(order, motion[i, 9:12], degrees=True).as_matrix()
        p0 = motion[i, :3]
        p1 = p0 + r0 @ doc.offsets[1]
        p2 = p1 + r0 @ r1 @ doc.offsets[2]
        p3 = p2 + r0 @ r1 @ r2 @ doc.offsets[3]
        np.testing.assert_allclose(c.positions[i], [p0, p1, p2, p3], atol=1e-9)
        np.testing.assert_allclose(c.rotations[i, 2], r0 @ r1 @ r2, atol=1e-9)
        np.testing.assert_allclose(c.local_rotations[i, 1], r1, atol=1e-9)


@pytest.mark.parametrize("order", ["ZXY", "YZX"])
def test_character_is_the_frame_major_kinematics_to_the_bit(order):
    """The component-major path (trigonometry skipped on still channels) gives the
    numbers of Euler conversion with trigonometry everywhere and frame-major matrices,
    bit for bit: channels held at +0 or -0, a channel still but in one frame, moving
    ones, and a 1-channel joint (padded axes)."""
    from snapcore.motion.kinematics import euler_to_quat, forward_kinematics, quat_to_matrix

    rng = np.random.default_rng(3)
    f = 50
    motion = np.concatenate([rng.normal(size=(f, 3)), rng.uniform(-180, 180, size=(f, 9))], axis=1)
    motion[:, 6] = -0.0  # joint a: first axis held at -0, second at +0
    motion[:, 7] = 0.0
    motion[:, 9] = -0.0  # joint b (one channel): still ...
    motion[17, 9] = 40.0  # ... but in one frame
    doc = chain_document(order, motion)
    chans = list(doc.channels)
    chans[2] = (f"{order[1]}rotation",)
    doc = BVHDocument(
        doc.names,
        doc.parents,
        doc.offsets,
        tuple(chans),
        doc.end_site,
        doc.frame_time,
        motion[:, :10],
    )
    c = character_from_bvh(doc, scale=0.5)

    # the reference: every angle through np.cos and np.sin, frame-major arrays
    order_b = order[1] + "".join(a for a in "XYZ" if a != order[1])  # padded at angle 0
    angles_b = np.zeros((f, 3))
    angles_b[:, 0] = motion[:, 9]
    quat = np.zeros((f, 4, 4))
    quat[..., 0] = 1.0
    quat[:, 0] = euler_to_quat(order, np.deg2rad(motion[:, 3:6]))
    quat[:, 1] = euler_to_quat(order, np.deg2rad(motion[:, 6:9]))
    quat[:, 2] = euler_to_quat(order_b, np.deg2rad(angles_b))
    trans = np.broadcast_to(doc.offsets, (f, 4, 3)).copy()
    trans[:, 0] = motion[:, :3]
    positions, quat_world = forward_kinematics(doc.parents, quat, trans)

    def same(x, y):
        return np.array_equal(np.asarray(x).view(np.int64), np.asarray(y).view(np.int64))

    assert same(c.local_quaternions, quat)
    assert same(c.positions, positions * 0.5)
    assert same(c.rotations, quat_to_matrix(quat_world))
    assert same(c.local_rotations, quat_to_matrix(quat))


def test_fk_hand_computed_right_angles():
    """Quarter turns give positions computable by hand."""
    # ZXY order; root turns 90° about Z: the chain's +Y offset points to -X.
    motion = np.array(
        [
            [1.0, 2.0, 3.0, 90.0, 0, 0, 0, 0, 0, 0, 0, 0],
            # joint a turns 90° about Y: b's +X offset (in a's frame) points to -Z.
            [0.0, 0.0, 0.0, 0, 0, 0, 0, 0, 90.0, 0, 0, 0],
        ]
    )
    c = character_from_bvh(chain_document("ZXY", motion), scale=1.0)
    np.testing.assert_allclose(c.positions[0, 1], [0.0, 2.0, 3.0], atol=1e-12)  # (1,2,3) + (-1,0,0)
    np.testing.assert_allclose(
        c.positions[0, 2], [0.0, 2.5, 3.0], atol=1e-12
    )  # + R_z(90)(0.5,0,0) = (0,0.5,0)
    np.testing.assert_allclose(c.positions[1, 2], [0.0, 1.0, -0.5], atol=1e-12)
    np.testing.assert_allclose(
        c.positions[1, 3], [0.25, 1.0, -0.5], atol=1e-12
    )  # R_y(90)(0,0,.25) = (.25,0,0)


def test_six_channel_joint_positions_replace_offset():
    """A non-root joint with position channels uses them instead of its offset."""
    doc = chain_document("ZXY", np.zeros((1, 12)))
    chans = list(doc.channels)
    chans[1] = ("Xposition", "Yposition", "Zposition") + chans[1]
    motion = np.zeros((1, 15))
    motion[0, 6:9] = [
        0.0,
        7.0,
        0.0,
    ]  # joint a's position channels: (0, 7, 0), offset says (0, 1, 0)
    doc = BVHDocument(
        doc.names, doc.parents, doc.offsets, tuple(chans), doc.end_site, doc.frame_time, motion
    )
    c = character_from_bvh(doc, scale=1.0)
    np.testing.assert_allclose(c.positions[0, 1], [0.0, 7.0, 0.0])


def test_every_shared_file_loads_with_adult_height_and_rigid_bones(all_bvh):
    """Every shared BVH loads; CMU statures are 1.4–2.0 m; bone lengths constant to 1e-6 relative."""
    cmu = 0
    for path in all_bvh:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene(path)
        c = scene.characters[0]
        assert scene.n_frames > 1 and np.isfinite(c.positions).all(), path
        # MANIFEST.tsv: CMU data comes from mocap.cs.cmu.edu (filenames NN_NN*).
        if path.name[:2].isdigit():
            cmu += 1
            assert 1.4 <= c.height <= 2.0, f"{path.name}: stature {c.height:.2f} m"
        parents = c.parents
        child = np.flatnonzero(parents >= 0)
        length = np.linalg.norm(c.positions[:, child] - c.positions[:, parents[child]], axis=2)
        rest = np.linalg.norm(c.skeleton.offsets[child], axis=1)
        # Joints with position channels (Bandai, root) may move; all others are rigid bones.
        rigid = np.array(
            [not any(ch.endswith("position") for ch in c.source.channels[j]) for j in child]
        )
        ref = np.maximum(rest[rigid], 1e-9)
        rel = np.abs(length[:, rigid] - rest[rigid]) / ref
        rel[:, rest[rigid] < 1e-9] = 0.0
        assert rel.max() < 1e-6, f"{path.name}: bone length drift {rel.max():.2e}"
    assert cmu >= 10


def test_known_units_are_recognised(motions_dir):
    """Units snap to what the data README says: CMU cgspeed ~0.0564 m, Daz/Bandai cm."""
    cases = {
        "walk_run/02_01.bvh": "cmu",
        "soccer/10_01.bvh": "cm",
        "walk_run/dataset-2_run_normal_001.bvh": "cm",
        "boxing_jump/Boxing_Toes.bvh": "cm",
    }
    for rel, unit in cases.items():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene(motions_dir / rel)
        assert scene.characters[0].scale == KNOWN_UNITS[unit], rel


def test_salsa_pair_shares_one_scale_and_world_frame(motions_dir):
    """Two files captured together get one scale; partners' hands touch (MANIFEST: 5-8 cm)."""
    with pytest.warns(UserWarning, match="no standard unit"):
        scene = load_scene(
            [
                motions_dir / "two_person/60_01_scaled.bvh",
                motions_dir / "two_person/61_01_scaled.bvh",
            ],
            fps=60,
        )
    a, b = scene.characters
    assert a.scale == b.scale
    assert scene.fps == 60 and scene.n_frames == a.n_frames == b.n_frames

    # Hand and finger joints (Daz names: hands, then their descendants in file order).
    def hand_region(c):
        out = [c.skeleton.index("lHand"), c.skeleton.index("rHand")]
        for j, p in enumerate(c.parents):
            if p in out:
                out.append(j)
        return out

    ha, hb = hand_region(a), hand_region(b)
    d = np.linalg.norm(a.positions[:, ha][:, :, None] - b.positions[:, hb][:, None], axis=3)
    assert d.min() < 0.02  # fingers interlock: a shared world frame and a shared scale
    assert np.sum(d.min(axis=(1, 2)) < 0.05) >= 60  # and hold hands for at least a second
    assert 1.5 < a.height < 1.9 and 1.5 < b.height < 1.9


def test_tpose_lead_in_is_cut_and_numbering_kept(motions_dir):
    """An added T-pose frame is dropped and frame_offset keeps the source numbering."""
    path = motions_dir / "walk_run/02_03.bvh"  # MANIFEST: frame 0 = added T-pose
    full = load_scene(path, drop_tpose=False)
    cut = load_scene(path)
    assert cut.frame_offset == 1 and cut.n_frames == full.n_frames - 1
    np.testing.assert_array_equal(cut.characters[0].positions[0], full.characters[0].positions[1])
    assert int(cut.source_frame(0)) == 1
    # 02_01 is re-exported without a T-pose (MANIFEST): nothing is cut.
    assert load_scene(motions_dir / "walk_run/02_01.bvh").frame_offset == 0


def _with_lead_in(doc, frames: int, rest: bool):
    """``doc`` with ``frames`` copies of a first frame put in front: the rest pose (all
    rotations zero, as exporters add it) or the clip's own first frame (someone standing
    still before moving)."""
    from dataclasses import replace

    first = doc.motion[:1].copy()
    if rest:
        first[:, 3:] = 0.0  # root position kept, every rotation zero
    return replace(doc, motion=np.vstack([np.repeat(first, frames, axis=0), doc.motion]))


@pytest.mark.parametrize("held", [1, 12])
def test_a_held_tpose_is_cut_but_stillness_is_not(tmp_path, held):
    """Leading rest-pose frames, one or held for a while, followed by the snap into the
    motion are cut; the same number of frames of the clip's own first pose are kept."""
    from snapcore.motion.synth import humanoid_document

    doc = humanoid_document("punch", fps=30.0)
    write_bvh(_with_lead_in(doc, held, rest=True), tmp_path / "tpose.bvh")
    write_bvh(_with_lead_in(doc, held, rest=False), tmp_path / "still.bvh")
    tpose, still = load_scene(tmp_path / "tpose.bvh"), load_scene(tmp_path / "still.bvh")
    assert tpose.frame_offset == held and tpose.n_frames == doc.n_frames
    assert still.frame_offset == 0 and still.n_frames == doc.n_frames + held


def _write_chain(tmp_path, name="c.bvh", frames=5):
    motion = np.zeros((frames, 12))
    motion[:, 1] = 1.0
    motion[:, 0] = np.arange(frames) * 0.1
    write_bvh(chain_document("ZXY", motion), tmp_path / name)
    return tmp_path / name


def test_manifest_overrides(tmp_path):
    """A TOML manifest sets per-character offset, yaw, fps, scale and the ground."""
    _write_chain(tmp_path, "a.bvh")
    _write_chain(tmp_path, "b.bvh")
    (tmp_path / "s.toml").write_text(
        'name = "pair"\nground = 0.5\nfps = 60\n'
        '[[characters]]\nfile = "a.bvh"\nname = "left"\nscale = 2.0\n'
        '[[characters]]\nfile = "b.bvh"\nname = "right"\nscale = 2.0\nyaw = 90\noffset = [0, 0, 5]\n',
        encoding="utf-8",
    )
    scene = load_scene(tmp_path / "s.toml")
    assert scene.name == "pair" and scene.ground == 0.5 and scene.fps == 60
    left, right = scene.characters
    assert (left.name, right.name) == ("left", "right")
    # Root of frame 1 in file units: (0.1, 1, 0); scale 2 → (0.2, 2, 0).
    np.testing.assert_allclose(left.positions[1, 0], [0.2, 2.0, 0.0], atol=1e-12)
    # Yaw 90° about +Y maps +X to -Z, then offset (0, 0, 5).
    np.testing.assert_allclose(right.positions[1, 0], [0.0, 2.0, 5.0 - 0.2], atol=1e-12)


def test_json_manifest_equivalent(tmp_path):
    """JSON manifests are read like TOML ones."""
    _write_chain(tmp_path, "a.bvh")
    (tmp_path / "s.json").write_text(json.dumps({"characters": [{"file": "a.bvh", "scale": 1.0}]}))
    assert load_scene(tmp_path / "s.json").characters[0].scale == 1.0


@pytest.mark.parametrize(
    "body, fragment",
    [
        ('[[characters]]\nfile = "a.bvh"\noffset = [1, 2]\n', "characters[0].offset"),
        ('[[characters]]\nfile = "a.bvh"\nfps = -3\n', "characters[0].fps"),
        ('[[characters]]\nfile = "a.bvh"\ncolour = "red"\n', "colour"),
        ("characters = []\n", "characters"),
        ('[[characters]]\nfile = "a.bvh"\n[[props]]\nname = "ball"\ntype = "sphere"\n', "props[0]"),
    ],
)
def test_manifest_schema_errors_name_the_field(tmp_path, body, fragment):
    """A manifest that breaks the schema names the file and the field."""
    _write_chain(tmp_path, "a.bvh")
    (tmp_path / "s.toml").write_text(body, encoding="utf-8")
    with pytest.raises(SchemaError) as info:
        load_scene(tmp_path / "s.toml")
    assert "s.toml" in str(info.value) and fragment in str(info.value)


def test_manifest_missing_file_and_bad_toml(tmp_path):
    """A manifest naming a missing file, or not TOML at all, is a one-line error."""
    (tmp_path / "s.toml").write_text('[[characters]]\nfile = "missing.bvh"\n', encoding="utf-8")
    with pytest.raises(SceneError, match="missing.bvh: no such file"):
        load_scene(tmp_path / "s.toml")
    (tmp_path / "t.toml").write_text("characters = [\n", encoding="utf-8")
    with pytest.raises(SchemaError, match="not valid TOML"):
        load_scene(tmp_path / "t.toml")


def test_different_frame_rates_are_refused(tmp_path):
    """Characters with different fps need an explicit fps."""
    a = _write_chain(tmp_path, "a.bvh")
    doc = parse_bvh(a.read_text())
    write_bvh(
        BVHDocument(
            doc.names, doc.parents, doc.offsets, doc.channels, doc.end_site, 1 / 60, doc.motion
        ),
        tmp_path / "b.bvh",
    )
    with pytest.raises(SceneError, match="different frame rates"):
        load_scene([a, tmp_path / "b.bvh"], scale=1.0)
    assert load_scene([a, tmp_path / "b.bvh"], scale=1.0, fps=30).fps == 30


def test_one_frame_motion_loads(tmp_path):
    """A one-frame motion is a valid (static) scene."""
    p = _write_chain(tmp_path, frames=1)
    scene = load_scene(p, scale=1.0)
    assert scene.n_frames == 1 and scene.duration == 0.0


def test_info_json(motions_dir):
    """`snapshot info --json` reports frames, fps, duration, height and bounds in metres."""
    r = subprocess.run(
        [
            sys.executable,
            "-m",
            "snapcore.cli.main",
            "info",
            "--json",
            str(motions_dir / "walk_run/02_01.bvh"),
        ],
        capture_output=True,
        text=True,
        timeout=60,
    )
    assert r.returncode == 0, r.stderr
    s = json.loads(r.stdout)
    # MANIFEST: 343 frames at 120 fps, 31 joints (+ end sites).
    assert s["n_frames"] == 343 and s["fps"] == 120
    assert abs(s["duration_s"] - 342 / 120) < 1e-9
    c = s["characters"][0]
    assert c["n_joints"] - c["n_end_sites"] == 31
    assert 1.4 < c["height_m"] < 2.0
    lo, hi = np.array(s["bounds_m"]["min"]), np.array(s["bounds_m"]["max"])
    assert 1.2 < hi[1] - lo[1] < 2.0  # a walking adult's vertical extent


def test_transformed_scene_moves_props_with_it(tmp_path):
    """Scene.transformed rotates, scales and translates props like the characters."""
    p = _write_chain(tmp_path)
    scene = load_scene(p, scale=1.0)
    scene.props = [
        {"name": "ball", "type": "sphere", "center": [1.0, 0.0, 0.0], "radius": 0.1},
        {
            "name": "bar",
            "type": "capsule",
            "a": [0.0, 1.0, 0.0],
            "b": [0.0, 1.0, 2.0],
            "radius": 0.05,
        },
    ]
    moved = scene.transformed(yaw_deg=90, scale=2.0, offset=(0.0, 0.0, 1.0))
    ball, bar = moved.props
    # Yaw 90° about +Y maps +X to -Z and +Z to +X; then ×2; then +1 in z.
    np.testing.assert_allclose(ball["center"], [0.0, 0.0, -1.0], atol=1e-12)
    assert ball["radius"] == pytest.approx(0.2)
    np.testing.assert_allclose(bar["b"], [4.0, 2.0, 1.0], atol=1e-12)
    assert scene.props[0]["center"] == [1.0, 0.0, 0.0]  # the original is untouched


def test_local_quaternions_are_the_local_rotations(motions_dir):
    """The quaternions FK keeps are the local rotation matrices, after loading, a yaw
    (roots turned), a rescale and a slice; and matrix_to_quat inverts quat_to_matrix
    up to the sign of q."""
    from snapcore.motion.kinematics import matrix_to_quat, quat_to_matrix

    c = load_scene(motions_dir / "walk_run" / "02_01.bvh").characters[0]
    variants = {
        "loaded": c,
        "yawed": c.transformed(yaw_deg=37.0, offset=(1.0, 0.0, -2.0)),
        "rescaled": c.rescaled(c.scale * 2.0),
        "sliced": c.frames(10, 50),
    }
    for label, v in variants.items():
        assert v.local_quaternions is not None, label
        assert v.local_quaternions.shape == v.local_rotations.shape[:2] + (4,), label
        np.testing.assert_allclose(
            quat_to_matrix(v.local_quaternions), v.local_rotations, atol=1e-12, err_msg=label
        )
    q = matrix_to_quat(c.local_rotations)
    same = np.abs(np.einsum("fjk,fjk->fj", q, c.local_quaternions))  # |q . q'| = 1 if equal
    np.testing.assert_allclose(same, 1.0, atol=1e-12)


def test_scene_frames_keep_source_numbering(motions_dir):
    """Scene.frames crops every character alike and keeps source frame numbers."""
    scene = load_scene(motions_dir / "walk_run" / "02_01.bvh")
    part = scene.frames(10, 60)
    assert part.n_frames == 50
    assert part.source_frame(0) == scene.source_frame(10)
    np.testing.assert_array_equal(
        part.characters[0].positions, scene.characters[0].positions[10:60]
    )
    assert scene.frames(0, 10**6).n_frames == scene.n_frames  # clipped like a slice
    with pytest.raises(SceneError, match="empty"):
        scene.frames(5, 5)


@pytest.mark.filterwarnings("ignore:characters have different frame counts")
def test_files_in_different_units_are_flagged(motions_dir):
    """A CMU walk (~0.056 m per unit) loaded with a salsa dancer (~1.3 m per unit) would
    share one scale and come out 3 m and 0.13 m tall: a warning says so and names both.
    Characters in the same unit (the salsa pair) load without it."""
    walk, salsa = (
        motions_dir / "walk_run" / "02_01.bvh",
        motions_dir / "two_person" / "61_01_scaled.bvh",
    )
    with pytest.warns(UserWarning, match=r"'02_01' and '61_01_scaled' differ 2\dx in size"):
        load_scene([walk, salsa], fps=60)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        load_scene([motions_dir / "two_person" / "60_01_scaled.bvh", salsa], fps=60)
    assert not [w for w in caught if "different units" in str(w.message)]


def test_manifest_frame_range_past_the_end_warns(tmp_path):
    """frames = [1, 50] on a 5-frame motion keeps [1, 5) and says so (no silent clamp)."""
    _write_chain(tmp_path, "a.bvh")
    (tmp_path / "s.toml").write_text(
        'frames = [1, 50]\nscale = 1.0\n[[characters]]\nfile = "a.bvh"\n', encoding="utf-8"
    )
    with pytest.warns(UserWarning, match=r"frames \[1, 50\) runs past the motion's 5 frames"):
        scene = load_scene(tmp_path / "s.toml")
    assert scene.n_frames == 4 and scene.frame_offset == 1


def test_a_frame_that_was_cut_says_why(motions_dir, tmp_path):
    """Asking for a source frame the scene does not keep names the frames it keeps and why
    earlier ones were cut: the salsa files' added T-pose, or a manifest's frames range."""
    pair = [motions_dir / "two_person" / f for f in ("60_01_scaled.bvh", "61_01_scaled.bvh")]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(pair, fps=60)
    first = scene.frame_offset
    assert first > 0 and scene.internal_frame(first) == 0
    with pytest.raises(SceneError, match=rf"keeps source frames {first}\.\..*added T-pose"):
        scene.internal_frame(0)
    last = first + scene.n_frames - 1
    with pytest.raises(SceneError, match=rf"keeps source frames {first}\.\.{last}$"):
        scene.internal_frame(last + 1)  # after the end: nothing was cut there
    _write_chain(tmp_path, "a.bvh")
    (tmp_path / "s.toml").write_text(
        'frames = [2, 5]\nscale = 1.0\n[[characters]]\nfile = "a.bvh"\n', encoding="utf-8"
    )
    with pytest.raises(SceneError, match="manifest's frames range"):
        load_scene(tmp_path / "s.toml").internal_frame(1)


def _two_root_file(tmp_path, *, prop: bool = False):
    """Two people in one BVH file, one ROOT each (the second 1.5 m along +X), as some
    two-person captures are exported; ``prop`` adds a third ROOT, a one-joint ball."""
    import re

    from snapcore.motion.bvh import format_bvh
    from snapcore.motion.synth import humanoid_document

    a = format_bvh(humanoid_document("punch", seconds=1.0))
    b = format_bvh(humanoid_document("kick", seconds=1.0, facing_deg=180))
    head_a, motion_a = a.split("MOTION\n")
    head_b, motion_b = b.split("MOTION\n")
    head_b = re.sub(r"(ROOT|JOINT) (\S+)", r"\1 B_\2", head_b.replace("HIERARCHY\n", ""))
    rows_a, rows_b = motion_a.strip().split("\n"), motion_b.strip().split("\n")
    rows = []
    for ra, rb in zip(rows_a[2:], rows_b[2:]):
        vb = rb.split()
        vb[0] = f"{float(vb[0]) + 1.5:.6f}"
        rows.append(" ".join([ra, *vb, *(["0.4 0.11 0.3 0 0 0"] if prop else [])]))
    ball = (
        "ROOT Ball\n{\n  OFFSET 0 0 0\n  CHANNELS 6 Xposition Yposition Zposition "
        "Zrotation Xrotation Yrotation\n  End Site\n  {\n    OFFSET 0 0.11 0\n  }\n}\n"
    )
    text = (
        head_a + head_b + (ball if prop else "") + "MOTION\n" + "\n".join(rows_a[:2] + rows) + "\n"
    )
    path = tmp_path / "pair.bvh"
    path.write_text(text)
    return path, a


@pytest.mark.parametrize("prop", [False, True])
def test_one_character_per_root(tmp_path, prop):
    """Each ROOT of a BVH file is a character of its own (named after the file and its
    root), moving exactly as it would alone; a prop root (one joint) does not change the
    unit inferred from the people."""
    path, alone = _two_root_file(tmp_path, prop=prop)
    scene = load_scene(path)
    names = [c.name for c in scene.characters]
    assert names == ["pair_Hips", "pair_B_Hips", *(["pair_Ball"] if prop else [])]
    assert scene.meta["unit"] == "m"
    (tmp_path / "alone.bvh").write_text(alone)
    np.testing.assert_allclose(
        scene.characters[0].positions, load_scene(tmp_path / "alone.bvh").characters[0].positions
    )
    assert scene.characters[1].positions[:, 0, 0].min() > 1.0  # the second person, 1.5 m away


def test_both_people_of_a_two_root_file_wear_a_body(tmp_path):
    """The human body is fitted to each person (it used to dress only the first tree)."""
    from snapcore.render.bodies import scene_body

    path, _ = _two_root_file(tmp_path)
    body = scene_body(load_scene(path))
    assert [type(b).__name__ for b in body.characters] == ["HumanBody", "HumanBody"]


#: Y up → Z up (x, y, z) → (x, -z, y): how a Z-up tool would have written the same take.
_TO_Z_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]])


def _z_up_document(doc: BVHDocument, turn=_TO_Z_UP, *, lying: bool = False) -> BVHDocument:
    """``doc`` as a tool whose world is ``turn`` · Y-up writes it: every offset turned,
    every joint's rotation conjugated (R' = T R Tᵀ, so the pose is the same), the root
    path turned. ``lying``: only the root turned instead (R' = T R), a Y-up file of the
    same person lying down. Euler channels are rewritten in each joint's own order."""
    from dataclasses import replace

    out = doc.motion.copy()
    starts = doc.channel_start()
    for j, chans in enumerate(doc.channels):
        rot = [c for c in chans if c.endswith("rotation")]
        if not rot or (lying and doc.parents[j] >= 0):
            continue
        cols = [starts[j] + chans.index(c) for c in rot]
        order = "".join(c[0] for c in rot)
        r = Rotation.from_euler(order, doc.motion[:, cols], degrees=True).as_matrix()
        r = turn @ r if lying else turn @ r @ turn.T
        out[:, cols] = Rotation.from_matrix(r).as_euler(order, degrees=True)
        pos = [
            starts[j] + chans.index(c)
            for c in ("Xposition", "Yposition", "Zposition")
            if c in chans
        ]
        if len(pos) == 3:
            out[:, pos] = doc.motion[:, pos] @ turn.T
    return replace(doc, offsets=doc.offsets if lying else doc.offsets @ turn.T, motion=out)


def test_a_z_up_file_is_stood_up(tmp_path):
    """A BVH written Z up (its skeleton stands along +Z at rest and in the motion) is read
    as the same take Y up, with a warning; the same person lying along the floor in a
    Y-up file is left lying."""
    from snapcore.motion.synth import humanoid_document

    doc = humanoid_document("walk", seconds=1.0)
    write_bvh(doc, tmp_path / "y.bvh")
    write_bvh(_z_up_document(doc), tmp_path / "z.bvh")
    want = load_scene(tmp_path / "y.bvh").characters[0]
    with pytest.warns(UserWarning, match="Z up"):
        got = load_scene(tmp_path / "z.bvh").characters[0]
    np.testing.assert_allclose(got.positions, want.positions, atol=1e-5)
    # joint frames are relative to each file's own rest pose: the Z-up one's is turned
    np.testing.assert_allclose(got.rotations @ _TO_Z_UP, want.rotations, atol=1e-5)
    write_bvh(
        _z_up_document(humanoid_document("idle", seconds=1.0), lying=True), tmp_path / "lying.bvh"
    )
    with warnings.catch_warnings():
        warnings.simplefilter("error", UserWarning)
        c = load_scene(tmp_path / "lying.bvh").characters[0]
    assert np.ptp(c.positions[..., 1]) < 1.0  # still lying along the floor
