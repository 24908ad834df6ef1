"""Interaction events (snapcore.select.contacts): the seed-and-propagate rule, geometry, and
real data checked against independent measurements (steps from heel heights, the
distance between partners' hands)."""

from __future__ import annotations

import math
import re
import warnings

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.errors import SceneError
from snapcore.motion import synth
from snapcore.motion.scene import Scene
from snapcore.select.capsules import body_near, bone_radii, segment_distance
from snapcore.select.contacts import (
    DEFAULT_TOLERANCES,
    GROUND,
    ContactParams,
    detect_interactions,
    merge_adjacent,
    prop_distance,
    scan_interactions,
)

HAND = re.compile(r"(hand|thumb|index|mid|ring|pinky)", re.I)
SALSA_PAIRS = [
    ("two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"),
    ("two_person/60_12_scaled.bvh", "two_person/61_12_scaled.bvh"),
]
# Joints of each foot across the naming schemes of walk_run/ (CMU MotionBuilder, CMU
# 3ds Max, Bandai); the first listed of each side present is the heel (ankle) joint.
FOOT = {
    "L": (
        "LeftFoot",
        "LeftAnkle",
        "Foot_L",
        "LeftToeBase",
        "LeftToeBase_End",
        "LeftToe",
        "LeftToe_End",
        "Toes_L",
        "Toes_L_End",
    ),
    "R": (
        "RightFoot",
        "RightAnkle",
        "Foot_R",
        "RightToeBase",
        "RightToeBase_End",
        "RightToe",
        "RightToe_End",
        "Toes_R",
        "Toes_R_End",
    ),
}
HEEL = {"L": ("LeftFoot", "LeftAnkle", "Foot_L"), "R": ("RightFoot", "RightAnkle", "Foot_R")}


def _load(paths, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return load_scene(paths, **kw)


# --------------------------------------------------------------------------- geometry


def test_segment_distance_known_answers():
    """Perpendicular foot inside the segment, clamped ends, zero-length segment."""
    a, b = np.array([0.0, 0, 0]), np.array([2.0, 0, 0])
    pts = np.array([[1.0, 3, 0], [-1.0, 0, 0], [5.0, 4, 0], [0.5, 0, 0]])
    np.testing.assert_allclose(segment_distance(pts, a, b), [3.0, 1.0, 5.0, 0.0])
    np.testing.assert_allclose(segment_distance(np.array([3.0, 4, 0]), a, a), 5.0)


def test_prop_distances():
    """Sphere, box (axis-aligned, full edge lengths) and capsule distances; 0 inside."""
    p = np.array([[0.0, 0, 2], [0.0, 0, 0.5], [3.0, 0, 0]])
    sphere = {"name": "ball", "type": "sphere", "center": [0, 0, 0], "radius": 1.0}
    np.testing.assert_allclose(prop_distance(p, sphere), [1.0, 0.0, 2.0])
    box = {"name": "table", "type": "box", "center": [0, 0, 0], "size": [2, 2, 2]}
    np.testing.assert_allclose(prop_distance(p, box), [1.0, 0.0, 2.0])
    corner = np.array([2.0, 2.0, 1.0])  # 1 m beyond the box in x and y: sqrt(2)
    assert prop_distance(corner, box) == pytest.approx(math.sqrt(2))
    capsule = {"name": "bar", "type": "capsule", "a": [0, 0, -1], "b": [0, 0, 1], "radius": 0.5}
    np.testing.assert_allclose(prop_distance(p, capsule), [0.5, 0.0, 2.5])
    with pytest.raises(SceneError, match="cone"):
        prop_distance(p, {"name": "x", "type": "cone"})
    with pytest.raises(SceneError, match="radius"):
        prop_distance(p, {"name": "x", "type": "sphere", "center": [0, 0, 0]})


def test_tolerances_are_checked():
    """Tolerances must be positive; durations become at least two frames."""
    with pytest.raises(ValueError, match="ground_distance"):
        ContactParams(ground_distance=-0.1)
    assert DEFAULT_TOLERANCES.min_frames(120) == 12
    assert DEFAULT_TOLERANCES.min_frames(30) == 3
    assert DEFAULT_TOLERANCES.min_frames(10) == 2


# --------------------------------------------------------------------------- the rule


def _disp(x):
    return lambda j, s, g: np.linalg.norm(x[g, j] - x[s, j], axis=-1)


def test_scan_rule_by_hand():
    """A joint that moves, rests (frames 5-14), then slides slowly: the interaction
    starts where it comes to rest, ends when it has slid more than the tolerance, and
    the slide continues as back-to-back pieces that merge into one contact."""
    n = 30
    x = np.zeros((n, 1, 3))
    x[:6, 0, 0] = 0.1 * np.arange(6)  # moving: 0.1 per frame, arrives at 0.5 at frame 5
    x[6:15, 0, 0] = 0.5  # resting
    x[15:, 0, 0] = 0.5 + 0.015 * np.arange(1, n - 14)  # sliding 1.5 cm per frame
    near = np.ones((n, 1), bool)
    js, ss, es = scan_interactions(near, _disp(x), min_frames=3, tolerance=0.04)
    # 5..16: 0.545 at frame 17 is 4.5 cm from the start (0.5), beyond the tolerance.
    # Then 3 frames move 3 cm <= 4 cm: a new piece every 3 frames (17-19, 20-22, ...).
    # The last piece (26-28) ends at 29; a new one would need 3 frames, 2 are left.
    assert list(zip(ss, es)) == [(5, 16), (17, 19), (20, 22), (23, 25), (26, 28)]
    mj, ms, me, first = merge_adjacent(js, ss, es)
    assert list(zip(ms, me)) == [(5, 28)] and list(first) == [0]
    # Leaving the object (not near) ends an interaction and a new one needs a new seed.
    near[10] = False
    js, ss, es = scan_interactions(near, _disp(x), min_frames=3, tolerance=0.04)
    assert (ss[0], es[0]) == (5, 9) and ss[1] == 11
    # Too short a rest is no interaction.
    near[:] = False
    near[6:8] = True
    assert scan_interactions(near, _disp(x), min_frames=3, tolerance=0.04)[0].size == 0


def _loop_scan(near, x, m, tol):
    out = []
    for j in range(near.shape[1]):
        f = 0
        while f <= near.shape[0] - m:
            ok = near[f : f + m, j].all() and all(
                np.linalg.norm(x[f + k, j] - x[f, j]) <= tol for k in range(m)
            )
            if not ok:
                f += 1
                continue
            g = f + m
            while g < near.shape[0] and near[g, j] and np.linalg.norm(x[g, j] - x[f, j]) <= tol:
                g += 1
            out.append((j, f, g - 1))
            f = g
    return out


def test_scan_equals_a_frame_by_frame_loop_on_random_series():
    """The vectorised scan (seeds for all frames, propagation in rounds) equals the
    obvious loop on random walks with random gaps."""
    rng = np.random.default_rng(7)
    for trial in range(20):
        n, nj, m = 200, 5, int(rng.integers(2, 9))
        x = np.cumsum(rng.normal(scale=rng.uniform(0.002, 0.03), size=(n, nj, 3)), axis=0)
        near = rng.random((n, nj)) > rng.uniform(0.0, 0.2)
        got = list(zip(*scan_interactions(near, _disp(x), min_frames=m, tolerance=0.05)))
        assert [tuple(map(int, g)) for g in got] == _loop_scan(near, x, m, 0.05), trial


def test_body_broad_phase_equals_testing_every_bone(motions_dir):
    """The space-time bounding-box hierarchy finds exactly what testing every bone of
    the partner at every frame finds (near flags and nearest bone)."""
    scene = _load([motions_dir / p for p in SALSA_PAIRS[1]], fps=60)
    a, b = scene.characters
    frames = slice(300, 900)
    x, links, radii = a.positions[frames], b.skeleton.links, bone_radii(b)
    y = b.positions[frames]
    d = segment_distance(x[:, :, None], y[:, None, links[:, 0]], y[:, None, links[:, 1]]) - radii
    want_near = d.min(axis=2) <= 0.03
    want_bone = np.where(want_near, d.argmin(axis=2), -1)
    sub = b.frames(300, 900)
    assert want_near.sum() > 100  # the pair does touch in this stretch
    for block in (1, 3, 6, 7):
        near, bone = body_near(x, sub, 0.03, block=block)
        np.testing.assert_array_equal(near, want_near)
        np.testing.assert_array_equal(bone, want_bone)


# --------------------------------------------------------------------------- real data


def _foot_contacts(scene, inter, side):
    c = scene.characters[0]
    foot = [j for j, n in enumerate(c.joint_names) if n in FOOT[side]]
    on = np.zeros(scene.n_frames, bool)
    for e in inter.events:
        if e.object == GROUND and e.joint in foot:
            on[e.start : e.end + 1] = True
    edges = np.flatnonzero(np.diff(np.r_[0, on.astype(int), 0]))
    return list(zip(edges[::2], edges[1::2] - 1)), foot


def _steps_from_heel_minima(scene, side, foot):
    """Independent step count: prominent minima (>= 2 cm) of the heel's height, the
    clip ends included (padding with the highest value); consecutive minima count as
    one step unless the foot's lowest point rose >= 3 cm between them (a heel that
    lifts and lowers while the toes stay planted is not a new step)."""
    from scipy.signal import find_peaks

    c = scene.characters[0]
    heel = next(j for j, n in enumerate(c.joint_names) if n in HEEL[side])
    h = c.positions[:, heel, 1]
    low = c.positions[:, foot, 1].min(axis=1)
    padded = np.r_[h.max(), h, h.max()]
    minima, _ = find_peaks(-padded, prominence=0.02, distance=max(1, int(0.2 * scene.fps)))
    steps = []
    for k in minima - 1:
        if steps:
            a = steps[-1]
            if low[a : k + 1].max() - max(low[a], low[k]) < 0.03:
                continue
        steps.append(k)
    return steps


def test_foot_contacts_match_steps_and_lie_on_the_floor(motions_dir):
    """walk_run/: per foot, the number of ground contacts equals an independent step
    count from heel-height minima within +-1, and every contact is where the foot is
    on the floor: its lowest joint within 10 cm of ``scene.ground`` (fitted by the
    loader) on the median frame of the contact, and its slowest joint moving at under
    0.5 m/s on the median frame (a foot in swing moves at 2-5 m/s)."""
    files = sorted((motions_dir / "walk_run").glob("*.bvh"))
    assert len(files) == 4
    for path in files:
        scene = _load(path)
        inter = detect_interactions(scene)
        c = scene.characters[0]
        for side in "LR":
            contacts, foot = _foot_contacts(scene, inter, side)
            steps = _steps_from_heel_minima(scene, side, foot)
            assert len(contacts) >= 2, (path.name, side)
            assert abs(len(contacts) - len(steps)) <= 1, (path.name, side, contacts, steps)
            low = c.positions[:, foot, 1].min(axis=1) - scene.ground
            speed = np.linalg.norm(np.gradient(c.positions[:, foot], axis=0), axis=-1)
            speed = speed.min(axis=1) * scene.fps
            for s, e in contacts:
                assert np.median(low[s : e + 1]) <= 0.10, (path.name, side, s, e)
                assert np.median(speed[s : e + 1]) <= 0.5, (path.name, side, s, e)


@pytest.mark.parametrize("pair", SALSA_PAIRS)
def test_salsa_hand_contacts_where_hands_touch(motions_dir, pair):
    """Partners' hands: wherever the nearest hand joints of the two stay within 3 cm
    for at least 0.2 s (measured here, joint to joint), a hand-on-hand interaction is
    detected on >= 80 % of those frames; and every detected hand-on-hand interaction
    happens with the hands within 10 cm (joint centres; hands have thickness)."""
    scene = _load([motions_dir / p for p in pair], fps=60)
    a, b = scene.characters
    ha = [j for j, n in enumerate(a.joint_names) if HAND.search(n)]
    hb = [j for j, n in enumerate(b.joint_names) if HAND.search(n)]
    dist = np.linalg.norm(a.positions[:, ha, None] - b.positions[:, None, hb], axis=-1)
    dist = dist.min(axis=(1, 2))  # (F,) nearest pair of hand joints
    close = dist < 0.03
    edges = np.flatnonzero(np.diff(np.r_[0, close.astype(int), 0]))
    held = np.zeros(scene.n_frames, bool)
    for s, e in zip(edges[::2], edges[1::2]):
        if e - s >= 0.2 * scene.fps:
            held[s:e] = True
    assert held.sum() > 50
    inter = detect_interactions(scene)
    touching = np.zeros(scene.n_frames, bool)
    for e in inter.events:
        if e.object == GROUND:
            continue
        who = scene.characters[e.character]
        assert e.object != who.name  # nobody touches themself
        if HAND.search(who.joint_names[e.joint]) and e.part and HAND.search(e.part):
            touching[e.start : e.end + 1] = True
    assert (touching & held).sum() >= 0.8 * held.sum()
    assert dist[touching].max() <= 0.10


def test_contacts_do_not_depend_on_the_frame_rate(motions_dir):
    """The same walk at 120 fps and every other frame at 60 fps: the same foot contacts,
    starting and ending within two 60-fps frames of each other."""
    scene = _load(motions_dir / "walk_run" / "02_01.bvh")
    half = scene.characters[0].frames(0, scene.n_frames)
    for name in ("positions", "rotations", "local_rotations", "local_quaternions"):
        setattr(half, name, getattr(half, name)[::2])
    half.fps = scene.fps / 2
    scene60 = Scene([half], fps=half.fps, ground=scene.ground)
    for side in "LR":
        full, _ = _foot_contacts(scene, detect_interactions(scene), side)
        sub, _ = _foot_contacts(scene60, detect_interactions(scene60), side)
        assert len(full) == len(sub)
        for (s1, e1), (s2, e2) in zip(full, sub):
            assert abs(s1 / 120 - s2 / 60) <= 2 / 60 and abs(e1 / 120 - e2 / 60) <= 2 / 60


def test_contacts_do_not_depend_on_units_or_placement(motions_dir):
    """Rescaled (cm), rotated and moved: the same events (tolerances follow stature)."""
    scene = _load([motions_dir / p for p in SALSA_PAIRS[1]], fps=60)
    base = [
        (e.character, e.joint, e.object, e.start, e.end) for e in detect_interactions(scene).events
    ]
    moved = scene.transformed(yaw_deg=63.0, offset=(1.5, -0.2, 4.0), scale=100.0)
    got = [
        (e.character, e.joint, e.object, e.start, e.end) for e in detect_interactions(moved).events
    ]
    assert got == base


def test_records_are_in_source_numbering(motions_dir):
    """02_03 starts with an added T-pose (frame_offset 1): records add the offset."""
    scene = _load(motions_dir / "walk_run" / "02_03.bvh")
    assert scene.frame_offset == 1
    inter = detect_interactions(scene)
    recs = inter.records(scene)
    assert len(recs) == len(inter.events) > 0
    for r, e in zip(recs, inter.events):
        assert (r["start"], r["end"]) == (e.start + 1, e.end + 1)
        assert r["character"] == "02_03" and r["object"] == GROUND


# --------------------------------------------------------------------------- synthetic


def test_synthetic_push_touches_the_chest():
    """synth 'push': the pusher's hands are on the other's chest from PUSH_CONTACT_S to
    PUSH_CONTACT_END_S; detected hand contacts start and end within 0.15 s of those
    and touch a spine/chest bone."""
    scene = synth.synth_scene("push", fps=60)
    pusher = scene.characters[0].name
    inter = detect_interactions(scene)
    hands = [
        e
        for e in inter.events
        if e.object != GROUND
        and scene.characters[e.character].name == pusher
        and "Hand" in scene.characters[e.character].joint_names[e.joint]
    ]
    assert hands
    for e in hands:
        assert abs(e.start / 60 - synth.PUSH_CONTACT_S) <= 0.15
        assert abs(e.end / 60 - synth.PUSH_CONTACT_END_S) <= 0.15
        assert e.part in ("Spine", "Spine1", "Neck")


def test_synthetic_walk_contacts_start_at_heel_strikes():
    """synth 'walk': a ground contact of each heel starts within 0.1 s of every
    documented heel strike inside the clip."""
    scene = synth.synth_scene("walk", fps=60)
    truth = synth.events("walk")
    c = scene.characters[0]
    inter = detect_interactions(scene)
    for side, key in (("Left", "left_heel_strikes"), ("Right", "right_heel_strikes")):
        j = c.joint_names.index(f"{side}Foot")
        onsets = np.array([e.start for e in inter.events if e.joint == j and e.start > 0]) / 60
        for t in truth[key]:
            if 0.15 < t < scene.duration - 0.15:
                assert np.min(np.abs(onsets - t)) <= 0.1, (side, t, onsets)


def test_props_from_the_manifest():
    """A prop the hand rests on gives events named after the prop; a prop far away none."""
    scene = synth.synth_scene("idle", fps=30)
    c = scene.characters[0]
    hand = c.joint_names.index("RightHand")
    at = c.positions[:, hand].mean(axis=0)
    scene.props = [
        {
            "name": "table",
            "type": "box",
            "center": (at - [0, 0.06, 0]).tolist(),
            "size": [0.6, 0.1, 0.6],
        },
        {"name": "moon", "type": "sphere", "center": [0.0, 50.0, 0.0], "radius": 1.0},
    ]
    inter = detect_interactions(scene)
    on_table = [e for e in inter.events if e.object == "table"]
    assert any(c.joint_names[e.joint] == "RightHand" for e in on_table)
    assert not [e for e in inter.events if e.object == "moon"]
    assert inter.objects == [GROUND, "table", "moon"]
