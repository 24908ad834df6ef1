"""The shoulder of a hanging arm, seen from the front, rounds over: no peak (issue 40).

Measured on the outline a person sees: the body's silhouette from the chest's front
(:func:`snapcore.render.buffers.render_depth`), in the chest's frame (so a trunk leaning
forward is not read as a shoulder), from 6 cm (x the body's size) out from the neck's
base, over the top of the shoulder and down the arm's outer side to 6 cm below the
shoulder joint. A shoulder slopes down from the neck and rounds over the deltoid; the
rig's A-pose skinning carried the top of the shoulder out over a hanging arm, so the
outline climbed outwards to a corner 15-19 cm out (the "boxy peaks" of CMU 01_01
frame 197, pictures in docs/body_issue40.md).
"""

from __future__ import annotations

import warnings

import numpy as np
import pytest

#: Arms-down frames: both upper arms within this of the trunk's down direction, degrees.
ARMS_DOWN_DEG = 20.0
#: The outline's highest point above its start by the neck, metres on the rig (divided
#: by the body's size): the median over a clip's arms-down frames and both sides, and
#: the most in any. Set from the reference pictures of CMU 01_01 frame 197 (boxy before:
#: 1.8 cm; rounded after: 0.8 cm) and the clips' medians before (1.5-2.4 cm on CMU, 3ds
#: Max, Daz, CC_Base and the salsa follower) and after (0.5-1.1 cm; the most 2.9 cm,
#: 3ds Max 131_01's left).
MEDIAN_RISE_M = 0.013
MAX_RISE_M = 0.03
#: (clip, extra frames) per rig family.
FAMILIES = {
    "CMU": ("boxing_jump/01_01.bvh", (197,)),
    "3ds Max": ("walk_run/131_01.bvh", ()),
    "Daz": ("soccer/10_01.bvh", ()),
    "Daz salsa": ("two_person/61_01_scaled.bvh", ()),
    "CC_Base": ("cc_base/002_01.bvh", ()),
}
#: Bandai's shoulder joints sit high on the neck (the shoulder 8.7 cm under the head
#: joint on the rig's scale, against the rig's 19.5 cm and 10-14 cm elsewhere): its body's
#: shoulders rise to the ears, a shrug of the arm joint's placement, not of the skin
#: (open; the outline there climbs to the head, 10 cm).
BANDAI = pytest.param(
    "Bandai",
    marks=pytest.mark.xfail(strict=True, reason="Bandai's shoulder joints: shoulders to the ears"),
)


def _chest_view(r, pos):
    """(front, up) of the chest on one pose (J, 3): up from the pelvis to the neck base,
    front square to it and to the shoulder line."""
    lm = r.landmarks
    up = r._point(pos[None], r.neck_base)[0] - pos[lm["pelvis"]]
    up /= np.linalg.norm(up)
    front = np.cross(pos[lm["shoulder_L"]] - pos[lm["shoulder_R"]], up)
    return front / np.linalg.norm(front), up


def shoulder_rise(vertices, faces, r, pos) -> dict[str, float]:
    """Per side (``L``, ``R``): the front outline's highest point above its start 6 cm
    (x ``r.k``) out from the neck base, metres / ``r.k`` (see the module notes)."""
    import contourpy

    from snapcore.render.buffers import render_depth

    front, up = _chest_view(r, pos)
    d = render_depth(vertices, faces, front, resolution=800, up=up)
    s, (h, w) = d.pixel_size, d.mask.shape

    def pixel(x):  # world point → (column, row)
        q = x - d.origin
        return np.array([(q @ d.right) / s + w / 2 - 0.5, -(q @ d.up) / s + h / 2 - 0.5])

    lines = contourpy.contour_generator(z=d.mask.astype(float)).lines(0.5)
    lm, k = r.landmarks, r.k
    neck = pixel(r._point(pos[None], r.neck_base)[0])
    out = {}
    for side in "LR":
        joint = pixel(pos[lm[f"shoulder_{side}"]])
        sgn = np.sign(joint[0] - neck[0])
        start = neck[0] + sgn * 0.06 * k / s
        best = np.zeros((0, 2))
        for ln in lines:
            sel = (
                (sgn * (ln[:, 0] - start) >= 0)
                & (ln[:, 1] <= joint[1] + 0.06 * k / s)
                & (ln[:, 1] >= joint[1] - 0.15 * k / s)
            )
            idx = np.flatnonzero(sel)
            for run in np.split(idx, np.flatnonzero(np.diff(idx) != 1) + 1):
                if len(run) > len(best):
                    best = ln[run]
        assert len(best) > 10, f"no shoulder outline on side {side}"
        x, y = sgn * (best[:, 0] - neck[0]) * s, -(best[:, 1] - joint[1]) * s
        first = np.argmin(x)  # the end by the neck
        out[side] = float((y.max() - y[first]) / k)
    return out


def _arms_down(r, positions) -> np.ndarray:
    lm = r.landmarks
    up = r._point(positions, r.neck_base) - positions[:, lm["pelvis"]]
    up /= np.linalg.norm(up, axis=-1, keepdims=True)
    worst = np.zeros(len(positions))
    for s in "LR":
        arm = positions[:, lm[f"elbow_{s}"]] - positions[:, lm[f"shoulder_{s}"]]
        arm /= np.linalg.norm(arm, axis=-1, keepdims=True)
        e = np.degrees(np.arccos(np.clip(-np.sum(arm * up, axis=-1), -1, 1)))
        worst = np.maximum(worst, e)
    return np.flatnonzero(worst < ARMS_DOWN_DEG)


@pytest.mark.slow
@pytest.mark.parametrize("family", [*FAMILIES, BANDAI])
def test_hanging_arms_shoulders_have_no_peak(motions_dir, family):
    """On three arms-down frames of each rig family (and CMU 01_01 frame 197), the
    front outline of each shoulder rises at most 3 cm above its start by the neck, and
    by at most 1.3 cm in the median (before: medians of 1.5-2.4 cm, up to 4.1 cm, at a
    corner 15-19 cm out from the neck; after: medians 0.5-1.1 cm, up to 2.9 cm)."""
    from snapcore.motion.load import load_scene
    from snapcore.render.human import HumanBody

    clip, extra = FAMILIES.get(family, ("dance/dataset-1_dance-short_normal_001.bvh", ()))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        ch = load_scene(motions_dir / clip).characters[0]
    body = HumanBody(ch)
    r = body.retarget
    down = _arms_down(r, ch.positions)
    assert len(down) >= 3, f"{clip}: {len(down)} arms-down frames"
    frames = list(extra) + list(down[np.linspace(0, len(down) - 1, 3).round().astype(int)])
    upper = body.faces[body.asset.vertices[body.faces].min(axis=1)[:, 1] > 0.25]  # no legs
    rises = []
    for f in frames:
        v = body.skin(ch.positions[[f]], ch.rotations[[f]])[0]
        got = shoulder_rise(v, upper, r, ch.positions[f])
        print(f"{clip} frame {f}: " + ", ".join(f"{s} {x * 100:.1f} cm" for s, x in got.items()))
        rises += list(got.values())
    assert np.median(rises) <= MEDIAN_RISE_M, f"{clip}: median rise {np.median(rises) * 100:.1f} cm"
    assert max(rises) <= MAX_RISE_M, (
        f"{clip}: a shoulder {max(rises) * 100:.1f} cm above the neck's side"
    )


def test_shoulder_weights_move_only_the_shoulders_share():
    """The split changes only the clavicle and upper-arm weights near the shoulders'
    upper side: every row still sums to 1, other bones' weights are the rig's, and
    vertices 16 cm or more from both shoulder joints keep all their weights; above the
    joint the clavicle now holds most of it (the rig gave the arm 60-80% there)."""
    from dataclasses import replace

    from scipy import sparse

    from snapcore.render.human_asset import human_asset
    from snapcore.render.shoulders import REACH_M, shoulder_weights

    a = human_asset()
    w = a.weights.toarray()
    # the asset carries the split already: splitting it again must leave far rows and
    # other bones alone, and keep every row's sum
    assert np.allclose(w.sum(axis=1), 1.0)
    again = shoulder_weights(replace(a, weights=sparse.csr_matrix(w))).toarray()
    far = np.ones(len(w), bool)
    for side in ("Left", "Right"):
        j = a.heads[a.bone(f"{side}Arm")]
        far &= np.linalg.norm(a.vertices - j, axis=1) >= REACH_M[1]
        top = np.argmin(np.linalg.norm(a.vertices - (j + [0.0, 0.06, 0.0]), axis=1))
        assert w[top, a.bone(f"{side}Shoulder")] > w[top, a.bone(f"{side}Arm")], side
    np.testing.assert_allclose(again[far], w[far], atol=1e-12)
    others = [i for i, b in enumerate(a.bone_names) if not b.endswith(("Shoulder", "Arm"))]
    np.testing.assert_allclose(again[:, others], w[:, others], atol=1e-12)
    np.testing.assert_allclose(again.sum(axis=1), 1.0, atol=1e-12)


def test_the_shoulder_drop_follows_the_arms_elevation():
    """No drop with the arm at the rig's elevation or above it; the full drop (x the
    size) down the trunk with the arm hanging along it; half of it half-way."""
    from snapcore.render.shoulders import DROP_M, shoulder_drops

    up = np.array([[0.0, 1.0, 0.0]] * 4)
    sh = np.zeros((4, 2, 3))
    rig = 40.0
    angles = np.radians([rig, 120.0, 0.0, rig / 2])  # from the trunk's down direction
    el = np.stack([np.sin(angles), -np.cos(angles), np.zeros(4)], axis=-1)[:, None].repeat(2, 1)
    d = shoulder_drops(sh, el, up, rig, 2.0)
    np.testing.assert_allclose(d[0], 0.0, atol=1e-12)
    np.testing.assert_allclose(d[1], 0.0, atol=1e-12)
    np.testing.assert_allclose(d[2], [[0.0, -2 * DROP_M, 0.0]] * 2, atol=1e-12)
    np.testing.assert_allclose(d[3], [[0.0, -DROP_M, 0.0]] * 2, atol=1e-12)
