"""Tests of the procedural humanoid (snapcore.motion.synth): file format, units, and the
analytic ground truth the other modules test against (contacts, events, planes)."""

from __future__ import annotations

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.motion import synth
from snapcore.motion.bvh import format_bvh, parse_bvh
from snapcore.schema import read_document

FPS = 30.0
FOOT = ("Foot", "ToeBase", "ToeBase_End")


@pytest.fixture(scope="module")
def scenes():
    return {name: synth.synth_scene(name) for name in synth.SCENES}


def _foot_low(c, side):
    """Lowest height (m) of the foot's joints per frame, (F,)."""
    idx = [c.skeleton.index(side + j) for j in FOOT]
    return c.positions[:, idx, 1].min(axis=1)


def _hspeed(c, name):
    """Horizontal speed (m/s) of joint ``name`` per frame (central differences), (F,)."""
    p = c.positions[:, c.skeleton.index(name)][:, [0, 2]]
    return np.linalg.norm(np.gradient(p, axis=0), axis=1) * c.fps


def _frame(t, fps=FPS):
    return int(round(t * fps))


@pytest.mark.parametrize("motion", synth.MOTIONS)
def test_round_trip_is_exact(motion):
    """format_bvh → parse_bvh reproduces every name, offset, channel and value."""
    doc = synth.humanoid_document(motion, fps=FPS, seed=3)
    text = format_bvh(doc)
    back = parse_bvh(text)
    assert back.names == doc.names
    assert np.array_equal(back.parents, doc.parents)
    assert np.array_equal(back.offsets, doc.offsets)
    assert back.channels == doc.channels
    assert np.array_equal(back.end_site, doc.end_site)
    assert back.frame_time == doc.frame_time
    assert np.array_equal(back.motion, doc.motion)
    assert format_bvh(back) == text
    assert doc.channels[0] == (
        "Xposition",
        "Yposition",
        "Zposition",
        "Zrotation",
        "Xrotation",
        "Yrotation",
    )
    assert set(doc.channels[1:]) <= {("Zrotation", "Xrotation", "Yrotation"), ()}


def test_document_shape_and_names():
    """Default length, CMU-like joint names, end sites on head, hands and toes."""
    doc = synth.humanoid_document("walk", seconds=2.0, fps=25.0)
    assert doc.n_frames == 51  # 2 s at 25 fps, first and last frame included
    for name in (
        "Hips",
        "Spine",
        "Spine1",
        "Neck",
        "Head",
        "LeftShoulder",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "RightHand",
        "LeftUpLeg",
        "LeftLeg",
        "LeftFoot",
        "LeftToeBase",
        "RightToeBase",
        "Head_End",
        "LeftHand_End",
        "RightToeBase_End",
    ):
        assert name in doc.names
    assert doc.end_site.sum() == 5
    with pytest.raises(ValueError, match="unknown motion"):
        synth.humanoid_document("moonwalk")
    with pytest.raises(ValueError, match="unknown scene"):
        synth.synth_scene("dance")


def test_write_demo_loads_in_metres(tmp_path):
    """Every demo manifest validates, loads with the unit snapped to metres, stature
    1.65-1.85 m (thigh + shank 0.86 m / 0.491), ground at 0 and no frame cut."""
    paths = synth.write_demo(tmp_path)
    assert [p.stem for p in paths] == list(synth.DEMO_SCENES)
    for p in paths:
        read_document(p, "scene")  # raises SchemaError if invalid
        scene = load_scene(p)
        assert scene.frame_offset == 0
        assert scene.ground == 0.0
        expected = synth.synth_scene(p.stem)
        assert scene.n_frames == expected.n_frames
        assert len(scene.characters) == (2 if p.stem == "push" else 1)
        for c, e in zip(scene.characters, expected.characters):
            assert c.meta["unit"] == "m"
            assert 1.65 <= c.height <= 1.85
            np.testing.assert_allclose(c.positions, e.positions, atol=1e-9)
    # Deterministic: writing again gives identical bytes.
    again = synth.write_demo(tmp_path / "again")
    for a, b in zip(paths, again):
        assert a.read_bytes() == b.read_bytes()
    for bvh in tmp_path.glob("*.bvh"):
        assert bvh.read_bytes() == (tmp_path / "again" / bvh.name).read_bytes()


def test_bvh_files_load_without_manifest(tmp_path):
    """Loading the BVH files directly also snaps to metres (inference from stature),
    infers the floor at 0 and cuts no lead-in frame (the clips start at rest)."""
    synth.write_demo(tmp_path)
    groups = [[tmp_path / "push_pusher.bvh", tmp_path / "push_pushed.bvh"]]
    groups += [[tmp_path / f"{n}.bvh"] for n in synth.DEMO_SCENES if n != "push"]
    for files in groups:
        scene = load_scene(files)
        assert scene.meta["unit"] == "m"
        assert abs(scene.ground) < 0.01
        assert scene.frame_offset == 0


def test_bone_lengths_constant(scenes):
    """Every link keeps its rest length in every frame of every scene."""
    for scene in scenes.values():
        for c in scene.characters:
            links = c.skeleton.links
            rest = np.linalg.norm(c.skeleton.offsets[links[:, 1]], axis=1)
            length = np.linalg.norm(
                c.positions[:, links[:, 1]] - c.positions[:, links[:, 0]], axis=2
            )
            np.testing.assert_allclose(length, np.broadcast_to(rest, length.shape), atol=1e-5)


def test_nothing_below_ground_and_smooth(scenes):
    """No joint sinks below the floor; no joint moves faster than 15 m/s (no Euler flips
    or glitches) and no rotation channel jumps more than 40 degrees between frames."""
    for name, scene in scenes.items():
        for c in scene.characters:
            assert c.positions[..., 1].min() > -0.003, name
            speed = np.linalg.norm(np.diff(c.positions, axis=0), axis=2) * c.fps
            assert speed.max() < 15.0, name
            rot = c.source.motion[:, 3:]
            assert np.abs(np.diff(rot, axis=0)).max() < 40.0, name


def test_walk_feet_plant_and_root_advances(scenes):
    """Each foot has ground-contact phases (lowest point < 2 cm, ball speed < 0.1 m/s)
    covering a good part of the clip, does not slide within a phase, and the root
    travels forward along +Z (the facing) at a walking speed."""
    c = scenes["walk"].characters[0]
    for side in ("Left", "Right"):
        contact = (_foot_low(c, side) < 0.02) & (_hspeed(c, side + "ToeBase") < 0.1)
        assert 0.3 < contact.mean() < 0.8, side
        # Split into runs of consecutive contact frames; the ball stays put in each.
        ball = c.positions[:, c.skeleton.index(side + "ToeBase")][:, [0, 2]]
        edges = np.flatnonzero(np.diff(contact.astype(int)))
        runs = np.split(np.arange(c.n_frames), edges + 1)
        runs = [r for r in runs if contact[r[0]]]
        assert len(runs) >= 2, side
        for r in runs:
            drift = np.linalg.norm(ball[r] - ball[r[0]], axis=1).max()
            assert drift < 0.02, (side, r[0], drift)
    root = c.positions[:, 0]
    travel = root[-1] - root[0]
    speed = travel[2] / scenes["walk"].duration
    assert 0.8 < speed < 1.6
    assert abs(travel[0]) < 0.1


def test_walk_heel_strikes_are_where_documented(scenes):
    """At each documented heel strike the foot has just arrived: its ball moved fast
    0.2 s before and is at rest (< 0.1 m/s) 0.1 s after."""
    c = scenes["walk"].characters[0]
    strikes = synth.walk_heel_strikes(scenes["walk"].duration)
    assert len(strikes["left"]) >= 2 and len(strikes["right"]) >= 2
    np.testing.assert_allclose(np.diff(strikes["left"]), synth.WALK_STRIDE_S)
    for side in ("Left", "Right"):
        speed = _hspeed(c, side + "ToeBase")
        for t in strikes[side.lower()]:
            if t - 0.2 >= 0:
                assert speed[_frame(t - 0.2)] > 0.5, (side, t)
            if t + 0.1 <= scenes["walk"].duration:
                assert speed[_frame(t + 0.1)] < 0.1, (side, t)


def test_jump_leaves_ground_at_documented_times(scenes):
    """The root rises >= 0.2 m; both feet are on the ground until take-off, both are
    off it (> 5 cm) from 0.1 s after take-off until shortly before landing, and
    back on it after landing."""
    scene = scenes["jump"]
    c = scene.characters[0]
    low = np.minimum(_foot_low(c, "Left"), _foot_low(c, "Right"))
    root_y = c.positions[:, 0, 1]
    assert root_y.max() - root_y[0] >= 0.2
    to, ld = _frame(synth.JUMP_TAKEOFF_S), _frame(synth.JUMP_LANDING_S)
    assert low[: to + 1].max() < 0.02
    assert low[to + 3 : ld - 2].min() > 0.05
    assert low.max() >= 0.2  # the feet themselves clear 20 cm at the apex
    assert low[ld:].max() < 0.02


def test_kick_extends_fast_at_impact(scenes):
    """The right toe is highest and farthest forward at KICK_IMPACT_S (± 2 frames),
    moving fast just before; the left foot stays planted throughout."""
    scene = scenes["kick"]
    c = scene.characters[0]
    toe = c.positions[:, c.skeleton.index("RightToeBase_End")]
    ti = _frame(synth.KICK_IMPACT_S)
    assert abs(int(np.argmax(toe[:, 1])) - ti) <= 2
    assert abs(int(np.argmax(toe[:, 2])) - ti) <= 2
    assert toe[ti, 1] > 0.8  # about hip height
    speed = np.linalg.norm(np.gradient(toe, axis=0), axis=1) * c.fps
    assert speed[ti - 4 : ti + 1].max() > 4.0
    left = c.positions[:, c.skeleton.index("LeftToeBase")]
    assert np.linalg.norm(left - left[0], axis=1).max() < 0.005
    assert _foot_low(c, "Right")[-1] < 0.02  # the kicking foot is back down


def test_punch_extends_and_returns(scenes):
    """The right wrist is farthest forward at PUNCH_IMPACT_S with the elbow nearly
    straight (< 30 degrees of flexion), and returns to the guard."""
    c = scenes["punch"].characters[0]
    wrist = c.positions[:, c.skeleton.index("RightHand")]
    elbow = c.positions[:, c.skeleton.index("RightForeArm")]
    shoulder = c.positions[:, c.skeleton.index("RightArm")]
    ti = _frame(synth.PUNCH_IMPACT_S)
    assert abs(int(np.argmax(wrist[:, 2])) - ti) <= 2
    upper, fore = elbow[ti] - shoulder[ti], wrist[ti] - elbow[ti]
    flexion = np.degrees(np.arccos(upper @ fore / np.linalg.norm(upper) / np.linalg.norm(fore)))
    assert flexion < 30.0
    assert np.degrees(np.arccos(fore[2] / np.linalg.norm(fore))) < 30  # pointing forward
    assert wrist[ti, 2] - wrist[0, 2] > 0.3
    assert np.linalg.norm(wrist[-1] - wrist[0]) < 0.05


def _chest_frame(c, i):
    """Spine1 position and the person's forward (horizontal) and left directions."""
    spine1 = c.positions[i, c.skeleton.index("Spine1")]
    fwd = c.rotations[i, 0] @ np.array([0.0, 0.0, 1.0])
    fwd[1] = 0.0
    fwd /= np.linalg.norm(fwd)
    left = np.cross([0.0, 1.0, 0.0], fwd)
    return spine1, fwd, left


@pytest.mark.parametrize("facing", [0.0, 70.0])
def test_push_contact(facing):
    """From PUSH_CONTACT_S to PUSH_CONTACT_END_S the pusher's wrists lie on the pushed
    person's chest front (CHEST_DEPTH_M ahead of Spine1, within 3 cm) inside the
    chest region; 1 s earlier they are far (> 20 cm) from it; the pushed person ends
    at least 0.2 m further back."""
    scene = synth.synth_scene("push", facing_deg=facing)
    a, b = scene.characters
    assert (a.name, b.name) == ("pusher", "pushed")
    hands = [a.skeleton.index("LeftHand"), a.skeleton.index("RightHand")]
    start, end = _frame(synth.PUSH_CONTACT_S), _frame(synth.PUSH_CONTACT_END_S)
    for i in range(start, end + 1):
        spine1, fwd, left = _chest_frame(b, i)
        for h in hands:
            rel = a.positions[i, h] - spine1
            assert abs(rel @ fwd - synth.CHEST_DEPTH_M) < 0.03, (i, rel @ fwd)
            assert abs(rel @ left) < 0.2 and -0.2 < rel[1] < 0.15
            assert np.linalg.norm(rel) < synth.CHEST_DEPTH_M + 0.2
    early = start - _frame(1.0)
    spine1, fwd, _ = _chest_frame(b, early)
    front = spine1 + synth.CHEST_DEPTH_M * fwd
    for h in hands:
        assert np.linalg.norm(a.positions[early, h] - front) > 0.2
    # Facing each other ~1 m apart at the start; B pushed back afterwards.
    ra, rb = a.positions[0, 0], b.positions[0, 0]
    assert abs(np.linalg.norm((rb - ra)[[0, 2]]) - synth.PUSH_DISTANCE_M) < 0.05
    _, fa, _ = _chest_frame(a, 0)
    _, fb, _ = _chest_frame(b, 0)
    assert fa @ fb < -0.99
    away = (b.positions[-1, 0] - b.positions[0, 0]) @ fa
    assert away > 0.2


@pytest.mark.parametrize("facing", [0.0, 35.0])
def test_jumping_jacks_in_frontal_plane(facing):
    """Hands and feet move in the frontal plane: their spread along the facing axis is
    tiny compared with their spread across it."""
    c = synth.synth_scene("jumping_jacks", facing_deg=facing).characters[0]
    fwd = np.array([np.sin(np.radians(facing)), 0.0, np.cos(np.radians(facing))])
    for name in ("LeftHand", "RightHand_End", "LeftToeBase", "RightFoot"):
        p = c.positions[:, c.skeleton.index(name)]
        along = p @ fwd
        across = p - along[:, None] * fwd
        assert along.std() < 0.01, name
        assert np.linalg.norm(across.std(axis=0)) > 0.1, name


@pytest.mark.parametrize("name", synth.SCENES)
def test_facing_rotates_everything(name, scenes):
    """facing_deg turns the whole scene about +Y through the origin (yaw_matrix
    convention), i.e. equals Scene.transformed(yaw_deg=...)."""
    turned = synth.synth_scene(name, facing_deg=40.0)
    expected = scenes[name].transformed(yaw_deg=40.0)
    for c, e in zip(turned.characters, expected.characters):
        np.testing.assert_allclose(c.positions, e.positions, atol=1e-4)


def test_seed_reproducible_and_varies():
    """Same seed → identical files; different seed → a different motion."""
    for motion in synth.MOTIONS:
        a = synth.humanoid_document(motion, seed=7)
        b = synth.humanoid_document(motion, seed=7)
        c = synth.humanoid_document(motion, seed=8)
        assert np.array_equal(a.motion, b.motion)
        assert not np.allclose(a.motion, c.motion, atol=1e-3), motion


def test_keyframe_curves_match_scipy_pchip():
    """The private PCHIP evaluator equals scipy.interpolate.PchipInterpolator (random
    keys, flat runs included) and holds the end values outside the keys."""
    from scipy.interpolate import PchipInterpolator

    from snapcore.motion.synth_rig import pchip as _keys

    rng = np.random.default_rng(1)
    for _ in range(50):
        k = int(rng.integers(2, 8))
        x = np.sort(rng.uniform(0, 3, k)) + np.arange(k) * 0.05
        y = rng.normal(size=k)
        y[rng.uniform(size=k) < 0.3] = 0.5  # repeated values: flat segments
        t = np.linspace(x[0] - 0.5, x[-1] + 0.5, 200)
        ref = PchipInterpolator(x, y)(np.clip(t, x[0], x[-1]))
        np.testing.assert_allclose(_keys(t, x, y), ref, atol=1e-12)


def test_walk_toe_offs_are_where_documented(scenes):
    """Each foot is on the ground (< 1 cm) 0.05 s before its documented toe-off and
    clear of it (> 2 cm) 0.1 s after."""
    c = scenes["walk"].characters[0]
    ev = synth.events("walk")
    for side in ("Left", "Right"):
        low = _foot_low(c, side)
        offs = ev[side.lower() + "_toe_offs"]
        assert len(offs) >= 2
        for t in offs:
            assert low[_frame(t - 0.05)] < 0.01, (side, t)
            if t + 0.1 <= scenes["walk"].duration:
                assert low[_frame(t + 0.1)] > 0.02, (side, t)


def test_jumping_jacks_hop_at_documented_times(scenes):
    """Each documented jack starts with a hop (both feet > 3 cm up 0.07 s later) that
    lands with the feet apart (ankles > 0.5 m apart mid-jack), then closes them again."""
    c = scenes["jumping_jacks"].characters[0]
    low = np.minimum(_foot_low(c, "Left"), _foot_low(c, "Right"))
    ankles = c.positions[:, [c.skeleton.index("LeftFoot"), c.skeleton.index("RightFoot")]]
    width = np.linalg.norm(ankles[:, 0] - ankles[:, 1], axis=1)
    starts = synth.events("jumping_jacks")["jack_starts"]
    assert len(starts) == 3
    assert low[: _frame(starts[0])].max() < 0.01  # standing still before the first
    for t in starts:
        assert low[_frame(t + 0.07)] > 0.03
        assert width[_frame(t + 0.3 * synth.JACKS_PERIOD_S)] > 0.5
        assert low[_frame(t + 0.3 * synth.JACKS_PERIOD_S)] < 0.01
        assert width[_frame(t + 0.9 * synth.JACKS_PERIOD_S)] < 0.25


def test_events_cover_every_scene():
    """events() answers for every scene, and matches the module constants."""
    assert synth.events("jump") == {
        "takeoff": synth.JUMP_TAKEOFF_S,
        "landing": synth.JUMP_LANDING_S,
    }
    assert synth.events("push") == {"contact": (synth.PUSH_CONTACT_S, synth.PUSH_CONTACT_END_S)}
    assert synth.events("kick") == {"impact": synth.KICK_IMPACT_S}
    assert synth.events("punch") == {"impact": synth.PUNCH_IMPACT_S}
    assert synth.events("idle") == {}
    assert synth.events("jump", seconds=1.0) == {}  # both after the end of a 1 s clip
    np.testing.assert_allclose(
        synth.events("walk")["left_heel_strikes"], synth.walk_heel_strikes()["left"]
    )
    with pytest.raises(ValueError):
        synth.events("dance")
