"""The human body's posture on every rig family (issue 40): upright where the skeleton
is, the head where it looks, both feet's toes on the floor."""

from __future__ import annotations

import numpy as np
import pytest
from test_human import _contact_frames, _midline_vertices, _quiet_load

#: The same walk on two rigs: the body's chest and head pitch agree within this, degrees.
SAME_WALK_DEG = 5.0
#: Median chest and head pitch (relative to the skeleton's trunk line) within this of
#: the rig's upright rest pose, degrees (before: CC_Base's head 27° up, Daz's 30°).
PITCH_TOL_DEG = 10.0
#: Toes on standing frames: the lowest toe point's median height above the floor, and
#: the difference between the left and the right foot's, metres.
TOE_FLOOR_M = 0.025
TOE_SIDES_M = 0.02


def _pitch_points(asset):
    """Rest vertices (sternum, spine at the chest; nose tip, back of the head at its
    height): the chest's and the face's forward directions."""
    v = asset.vertices
    cf, cb = _midline_vertices(asset, asset.heads[asset.bone("Spine1")][1] + 0.06)
    head = np.flatnonzero((np.abs(v[:, 0]) < 0.01) & (v[:, 1] > asset.heads[asset.bone("Head")][1]))
    nose = head[np.argmax(v[head, 2])]
    _, back = _midline_vertices(asset, v[nose, 1])
    return np.array([cf, cb, nose, back])


def _pitch(forward, up):
    """Degrees the direction ``forward`` (..., 3) rises above the plane square to ``up``."""
    f = forward / np.linalg.norm(forward, axis=-1, keepdims=True)
    u = up / np.linalg.norm(up, axis=-1, keepdims=True)
    return np.degrees(np.arcsin(np.clip(np.sum(f * u, axis=-1), -1, 1)))


def _pitches(body, frames, world=False):
    """(chest, head) pitch per frame, degrees, less the rig's rest: the skinned
    sternum - spine and nose - back of the head against the skeleton's trunk line
    (pelvis → top of its spine chain), or the world's up with ``world``."""
    from snapcore.motion.anatomy import body_landmarks

    a, ch = body.asset, body.character
    idx = _pitch_points(a)
    pts, w = a.vertices[idx], a.weights[idx]
    r = body.retarget
    v = r.skin_points(pts, w, r.stretch_weights(pts, w), ch.positions[frames], ch.rotations[frames])
    lm = body_landmarks(ch.skeleton.names, np.asarray(ch.skeleton.parents))
    p = ch.positions[frames]
    up = np.array([0.0, 1.0, 0.0]) if world else p[:, lm["spine"][-1]] - p[:, lm["pelvis"]]
    rest_up = a.heads[a.bone("Neck")] - a.heads[a.bone("Hips")]
    rv = a.vertices[idx]
    chest = _pitch(v[:, 0] - v[:, 1], up) - _pitch(rv[0] - rv[1], rest_up)
    head = _pitch(v[:, 2] - v[:, 3], up) - _pitch(rv[2] - rv[3], rest_up)
    return chest, head


def test_the_same_walk_on_two_rigs_has_the_same_posture(motions_dir):
    """CMU 02_01 on cgspeed names and on Reallusion's CC_Base rig: the body's chest and
    face pitch (world, median over the walk) agree within 5° (before: CC_Base's chest
    8° further back and its head 27° up, looking at the sky)."""
    from snapcore.render.human import HumanBody

    got = {}
    for name in ("walk_run/02_01.bvh", "cc_base/002_01.bvh"):
        ch = _quiet_load(motions_dir / name).characters[0]
        frames = np.arange(0, ch.n_frames, max(1, ch.n_frames // 100))
        got[name] = [float(np.median(x)) for x in _pitches(HumanBody(ch), frames, world=True)]
    (c1, h1), (c2, h2) = got.values()
    assert abs(c1 - c2) <= SAME_WALK_DEG, f"chest {c1:.1f}° vs {c2:.1f}°"
    assert abs(h1 - h2) <= SAME_WALK_DEG, f"head {h1:.1f}° vs {h2:.1f}°"


@pytest.mark.slow
def test_chest_and_head_are_upright_where_the_skeleton_is(all_bvh):
    """On every shared clip (CMU cgspeed and 3ds Max names, Daz, Bandai, CC_Base), the
    body's chest and face pitch against the skeleton's trunk line stay, at the
    median over the clip, within 10° of the rig's upright rest (before: heads 10-30°
    up on CMU, Daz and CC_Base, a dancer's chest 15° back)."""
    from snapcore.render.human import HumanBody

    rows = []
    for path in all_bvh:
        ch = _quiet_load(path).characters[0]
        frames = np.arange(0, ch.n_frames, max(1, ch.n_frames // 150))
        chest, head = _pitches(HumanBody(ch), frames)
        rows.append((path.name, float(np.median(chest)), float(np.median(head))))
    report = "\n".join(f"{n}: chest {c:+.1f}°, head {h:+.1f}°" for n, c, h in rows)
    print("\nmedian pitch against the trunk line, less the rig's rest:\n" + report)
    assert max(max(abs(c), abs(h)) for _, c, h in rows) <= PITCH_TOL_DEG, report


@pytest.mark.slow
def test_both_feet_rest_their_toes_on_the_floor(all_bvh):
    """On every shared clip, on the frames where a foot stands (by its joints), the
    lowest point of its toes (vertices mostly on the toe bone) is within 2.5 cm of the
    floor at the median, and the left and right feet within 2 cm of each other
    (before: CC_Base's right toes 8 cm up, folded onto the instep, its left 3.3 cm)."""
    from snapcore.motion.anatomy import body_landmarks
    from snapcore.render.human import HumanBody

    rows = []
    for path in all_bvh:
        scene = _quiet_load(path)
        ch = scene.characters[0]
        body = HumanBody(ch, ground=scene.ground)
        a, r = body.asset, body.retarget
        lm = body_landmarks(ch.skeleton.names, np.asarray(ch.skeleton.parents))
        heights = []
        for s, side in (("L", "Left"), ("R", "Right")):
            toe = np.flatnonzero(np.asarray(a.weights[:, a.bone(f"{side}ToeBase")].todense()) > 0.5)
            frames = _contact_frames(ch, s, lm)
            frames = frames[:: max(1, len(frames) // 100)]
            pts, w = a.vertices[toe], a.weights[toe]
            v = r.skin_points(
                pts, w, r.stretch_weights(pts, w), ch.positions[frames], ch.rotations[frames]
            )
            heights.append(float(np.median(v[..., 1].min(axis=1) - scene.ground)))
        rows.append((path.name, *heights))
    report = "\n".join(
        f"{n}: left {lh * 100:.1f} cm, right {rh * 100:.1f} cm" for n, lh, rh in rows
    )
    print("\nlowest toe point above the floor, standing (median):\n" + report)
    assert all(max(lh, rh) <= TOE_FLOOR_M for _, lh, rh in rows), report
    assert all(abs(lh - rh) <= TOE_SIDES_M for _, lh, rh in rows), report
