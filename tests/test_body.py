"""Body meshes: roles from joint names, sizes, attachment to the skeleton, posing."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

from snapcore import load_scene
from snapcore.motion import synth
from snapcore.motion.anatomy import ROLE_RADII, joint_roles, joint_sides
from snapcore.motion.scene import Character, Scene, Skeleton
from snapcore.render.mannequin import (
    CHARACTER_COLORS,
    CharacterBody,
    SceneBody,
    posed_mesh,
    scene_body,
    scene_trimesh,
)


@pytest.fixture(scope="module")
def walk():
    return synth.synth_scene("walk", fps=30)


@pytest.fixture(scope="module")
def push():
    return synth.synth_scene("push", fps=30)


def _load(path, **kw):
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # fitted units warn
        return load_scene(path, **kw)


def _parents(names, parent_names):
    idx = {n: i for i, n in enumerate(names)}
    return np.array([idx[p] if p else -1 for p in parent_names])


def test_roles_cmu_cgspeed_names():
    """CMU cgspeed: LeftShoulder is the clavicle, LeftArm the upper arm, LeftLeg the shin."""
    names = [
        "Hips",
        "LHipJoint",
        "LeftUpLeg",
        "LeftLeg",
        "LeftFoot",
        "LeftToeBase",
        "LowerBack",
        "Spine",
        "Spine1",
        "Neck1",
        "Head",
        "LeftShoulder",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "LeftFingerBase",
        "LeftHandIndex1",
        "LThumb",
    ]
    par = [
        None,
        "Hips",
        "LHipJoint",
        "LeftUpLeg",
        "LeftLeg",
        "LeftFoot",
        "Hips",
        "LowerBack",
        "Spine",
        "Spine1",
        "Neck1",
        "Spine1",
        "LeftShoulder",
        "LeftArm",
        "LeftForeArm",
        "LeftHand",
        "LeftFingerBase",
        "LeftHand",
    ]
    expect = [
        "pelvis",
        "pelvis",
        "thigh",
        "shin",
        "foot",
        "toe",
        "spine",
        "spine",
        "chest",
        "neck",
        "head",
        "clavicle",
        "upperarm",
        "forearm",
        "hand",
        "hand",
        "finger",
        "finger",
    ]
    assert joint_roles(names, _parents(names, par)) == expect
    sides = joint_sides(names)
    assert sides[2] == "L" and sides[1] == "L" and sides[17] == "L" and sides[0] == ""
    assert joint_sides(["LowerBack", "lowerneck"]) == ["", ""]  # "l" + lowercase is no side


def test_roles_daz_and_bandai_names():
    """Daz (hip, abdomen, lCollar, lShldr, rThigh, rShin) and Bandai (UpperLeg_L...)."""
    daz = [
        "hip",
        "abdomen",
        "chest",
        "neck",
        "head",
        "leftEye",
        "lCollar",
        "lShldr",
        "lForeArm",
        "lHand",
        "lIndex1",
        "rButtock",
        "rThigh",
        "rShin",
        "rFoot",
    ]
    dpar = [
        None,
        "hip",
        "abdomen",
        "chest",
        "neck",
        "head",
        "chest",
        "lCollar",
        "lShldr",
        "lForeArm",
        "lHand",
        "hip",
        "rButtock",
        "rThigh",
        "rShin",
    ]
    assert joint_roles(daz, _parents(daz, dpar)) == [
        "pelvis",
        "spine",
        "chest",
        "neck",
        "head",
        "hidden",
        "clavicle",
        "upperarm",
        "forearm",
        "hand",
        "finger",
        "pelvis",
        "thigh",
        "shin",
        "foot",
    ]
    assert joint_sides(daz)[6:10] == ["L"] * 4 and joint_sides(daz)[11:] == ["R"] * 4
    ban = [
        "joint_Root",
        "Hips",
        "Spine",
        "Chest",
        "Neck",
        "Head",
        "Shoulder_L",
        "UpperArm_L",
        "LowerArm_L",
        "Hand_L",
        "UpperLeg_R",
        "LowerLeg_R",
        "Foot_R",
        "Toes_R",
    ]
    bpar = [
        None,
        "joint_Root",
        "Hips",
        "Spine",
        "Chest",
        "Neck",
        "Chest",
        "Shoulder_L",
        "UpperArm_L",
        "LowerArm_L",
        "Hips",
        "UpperLeg_R",
        "LowerLeg_R",
        "Foot_R",
    ]
    assert joint_roles(ban, _parents(ban, bpar)) == [
        "hidden",
        "pelvis",
        "spine",
        "chest",
        "neck",
        "head",
        "clavicle",
        "upperarm",
        "forearm",
        "hand",
        "thigh",
        "shin",
        "foot",
        "toe",
    ]
    assert joint_sides(ban)[6] == "L" and joint_sides(ban)[10] == "R"


def test_roles_older_cmu_names_and_unknown():
    """LeftCollar → LeftShoulder (= upper arm) → LeftElbow; LeftHip is the thigh; unknown
    names get the default role."""
    names = [
        "Hips",
        "Chest",
        "LeftCollar",
        "LeftShoulder",
        "LeftElbow",
        "LeftWrist",
        "LeftHip",
        "LeftKnee",
        "LeftAnkle",
        "Tail",
    ]
    par = [
        None,
        "Hips",
        "Chest",
        "LeftCollar",
        "LeftShoulder",
        "LeftElbow",
        "Hips",
        "LeftHip",
        "LeftKnee",
        "Hips",
    ]
    assert joint_roles(names, _parents(names, par)) == [
        "pelvis",
        "chest",
        "clavicle",
        "upperarm",
        "forearm",
        "hand",
        "thigh",
        "shin",
        "foot",
        "other",
    ]


def test_radius_table_torso_thicker_than_limbs_than_fingers():
    """The documented table orders girths like a person's."""
    r = {k: min(v) for k, v in ROLE_RADII.items()}
    assert r["chest"] > r["thigh"] > r["upperarm"] > r["forearm"] > r["hand"] > r["finger"]
    assert r["spine"] > r["neck"] and r["thigh"] > r["shin"]


def test_face_counts_like_the_papers_models(walk, push):
    """A few thousand faces per character (the paper's models: 3,191-6,412)."""
    for scene in (walk, push):
        body = SceneBody(scene)
        for b in body.characters:
            assert 3000 <= b.n_faces <= 6500
        assert body.n_faces == sum(b.n_faces for b in body.characters)


def test_every_real_skeleton_gets_a_plausible_body(all_bvh):
    """Every real clip: 3-6.5k faces, and the body spans the character's stature."""
    for path in all_bvh:
        scene = _load(path)
        body = scene_body(scene)
        c = scene.characters[0]
        assert 3000 <= body.characters[0].n_faces <= 6500, path.name
        # upright frame: the median height extent of the body vs stature (head top
        # above the head joint, feet below the ankles)
        f = scene.n_frames // 2
        v = body.characters[0].vertices(f)
        joints = c.positions[f]
        assert np.ptp(v[:, 1]) > np.ptp(joints[:, 1]), path.name


def _segment_distance(x, a, b):
    """Distance of points x (N, 3) from the segment a-b (independent geometry)."""
    ab = b - a
    t = np.clip(((x - a) @ ab) / max(ab @ ab, 1e-12), 0, 1)
    return np.linalg.norm(x - (a + t[:, None] * ab), axis=1)


@pytest.mark.parametrize(
    "clip",
    [
        "walk_run/02_01.bvh",
        "two_person/60_01_scaled.bvh",
        "walk_run/dataset-2_run_normal_001.bvh",
        "boxing_jump/Boxing_Toes.bvh",
    ],
)
def test_bones_stay_attached_to_their_joints(motions_dir, clip):
    """Every bone capsule, posed at any frame, lies within its radius of the segment
    between its two joints as forward kinematics places them, and reaches both ends."""
    scene = _load(motions_dir / clip)
    b = SceneBody(scene).characters[0]
    c = scene.characters[0]
    frames = np.linspace(0, scene.n_frames - 1, 7).round().astype(int)
    for f in frames:
        v = b.vertices(int(f))
        for k, piece in enumerate(b.pieces):
            if piece["kind"] != "bone":
                continue
            pv = v[b.piece == k]
            a, e = c.positions[f, piece["joint"]], c.positions[f, piece["child"]]
            d = _segment_distance(pv, a, e)
            r = max(piece["radii"])
            assert d.max() <= r * 1.001 + 1e-6, (clip, f, c.joint_names[piece["child"]])
            # both ends covered: the nearest vertex to each joint is within the radius
            for end in (a, e):
                assert np.linalg.norm(pv - end, axis=1).min() <= r * 1.001 + 1e-6


def test_posing_is_the_rigid_transform_of_each_joint(walk):
    """x = R[f, j] @ x_local + p[f, j], checked vertex by vertex with a plain loop."""
    b = SceneBody(walk).characters[0]
    c = walk.characters[0]
    f = 17
    v = b.vertices(f)
    rng = np.random.default_rng(0)
    for i in rng.choice(b.n_vertices, 50, replace=False):
        j = b.joint[i]
        expect = c.rotations[f, j] @ b.local_vertices[i] + c.positions[f, j]
        np.testing.assert_allclose(v[i], expect, atol=1e-12)
    # batched frames equal single frames
    batch = b.vertices(np.array([3, 17]))
    np.testing.assert_allclose(batch[1], v)
    np.testing.assert_allclose(b.normals(np.array([3, 17]))[1], b.normals(f))


def test_pieces_are_closed_and_outward(walk):
    """Each piece is a watertight solid with outward faces (positive volume), so culling
    back faces is safe; normals agree with face orientation."""
    import trimesh

    b = SceneBody(walk).characters[0]
    v = b.vertices(0)
    fpiece = b.piece[b.faces[:, 0]]
    for k in range(len(b.pieces)):
        m = trimesh.Trimesh(v, b.faces[fpiece == k], process=True)
        assert m.is_watertight, b.pieces[k]
        assert m.volume > 0, b.pieces[k]
    m = posed_mesh(walk, 0).trimesh()
    vn = b.normals(0)[b.faces].mean(axis=1)
    assert np.mean(np.einsum("ij,ij->i", vn, m.face_normals) > 0) > 0.99


def test_two_characters_get_distinct_colours(push):
    """The two people of a scene are told apart by colour; faces know their character."""
    m = posed_mesh(push, 10)
    assert m.vertices.shape == (m.vertex_colors.shape[0], 3)
    assert m.faces.max() < len(m.vertices)
    cols = [set(map(tuple, m.face_colors[m.face_character == i, :3])) for i in (0, 1)]
    assert cols[0] and cols[1] and not (cols[0] & cols[1])
    base = np.round(np.asarray(CHARACTER_COLORS[:2]) * 255)
    for i in (0, 1):  # the centre pieces carry the base colour exactly
        assert tuple(base[i].astype(np.uint8)) in cols[i]
    tm = scene_trimesh(push, 10)
    assert len(tm.faces) == len(m.faces) and tm.visual.face_colors.shape == (len(m.faces), 4)
    assert scene_body(push) is scene_body(push)  # built once per scene
    from snapcore.render.mannequin import TESSELLATION_FINE

    fine = scene_body(push, TESSELLATION_FINE)  # once per scene and tessellation
    assert fine is scene_body(push, TESSELLATION_FINE) and fine is not scene_body(push)
    assert fine.n_vertices > scene_body(push).n_vertices


def test_body_scales_with_stature(walk):
    """Twice the skeleton → twice the body (radii scale with stature)."""
    big = walk.transformed(scale=2.0)
    a, b = SceneBody(walk).pose(5).vertices, SceneBody(big).pose(5).vertices
    np.testing.assert_allclose(b, 2.0 * a, atol=1e-9)


def test_unknown_skeleton_gets_default_radius():
    """A chain of unknown names gets capsules of the default radius."""
    names = ("a", "b", "c", "d")
    parents = np.array([-1, 0, 1, 2])
    offsets = np.array([[0, 0, 0], [0, 0.5, 0], [0, 0.5, 0], [0, 0.7, 0]], float)
    sk = Skeleton(names, parents, offsets, np.array([False, False, False, True]))
    F = 3
    pos = np.cumsum(np.broadcast_to(offsets, (F, 4, 3)), axis=1) + [0, 0.1, 0]
    rot = np.broadcast_to(np.eye(3), (F, 4, 3, 3)).copy()
    ch = Character("blob", sk, pos, rot, rot.copy(), fps=30.0)
    scene = Scene([ch], fps=30.0)
    b = SceneBody(scene).characters[0]
    assert [p["kind"] for p in b.pieces] == ["bone"] * 3
    # radii are fractions of stature: an unnamed bone is 0.040 m on a 1.75 m figure
    assert all(abs(p["radii"][0] - 0.040 / 1.75 * ch.height) < 1e-12 for p in b.pieces)


def test_frame_out_of_range_is_an_error(walk):
    from snapcore.errors import SceneError

    with pytest.raises(SceneError, match="outside"):
        SceneBody(walk).pose(walk.n_frames)


def _facet_depth(body) -> float:
    """Deepest face centre below the ideal round capsule (m), over round bones."""
    sk = body.character.skeleton
    centre = body.local_vertices[body.faces].mean(axis=1)  # (M, 3), carrying joint's frame
    piece = body.piece[body.faces[:, 0]]
    worst = 0.0
    for i, pc in enumerate(body.pieces):
        if pc["kind"] != "bone" or pc["radii"][0] != pc["radii"][1]:
            continue  # elliptical torso pieces: not a round capsule
        c = centre[piece == i]
        off = np.asarray(sk.offsets[pc["child"]], float)
        t = np.clip(c @ off / (off @ off), 0.0, 1.0)
        axis_dist = np.linalg.norm(c - t[:, None] * off, axis=1)
        worst = max(worst, float((pc["radii"][0] - axis_dist).max()))
    return worst


def test_fine_tessellation_hugs_the_capsules(walk):
    """Reliefs carve the body's depth, so facets would show as ridges: the fine
    tessellation keeps every face within 1.5 mm of the round capsule it stands for, at
    least three times closer than the default one."""
    from snapcore.render.mannequin import TESSELLATION, TESSELLATION_FINE, CharacterBody

    ch = walk.characters[0]
    fine = _facet_depth(CharacterBody(ch, tessellation=TESSELLATION_FINE))
    default = _facet_depth(CharacterBody(ch, tessellation=TESSELLATION))
    assert 0 < fine < 1.5e-3
    assert fine < default / 3


def test_helper_joints_draw_no_blobs(walk):
    """Reallusion CC_Base rigs carry helper joints: breast (``L_RibsTwist`` →
    ``L_Breast`` in front of the chest) and twist bones beside the limbs. The
    mannequin draws no piece for them: the body is the same as without them (it drew
    chest-sized blobs)."""
    ch = walk.characters[0]
    sk = ch.skeleton
    names, parents = list(sk.names), list(sk.parents)
    offsets = [np.asarray(o, float) for o in sk.offsets]
    extra = []  # (name, parent name, offset in the parent's frame)
    for side, x in (("L", 1.0), ("R", -1.0)):
        extra += [
            (f"CC_Base_{side}_RibsTwist", "Spine1", (0.06 * x, 0.10, 0.06)),
            (f"CC_Base_{side}_Breast", f"CC_Base_{side}_RibsTwist", (0.0, -0.03, 0.07)),
            (
                f"CC_Base_{side}_UpperarmTwist01",
                "LeftArm" if side == "L" else "RightArm",
                (0.14 * x, 0.0, 0.0),
            ),
        ]
    pos, rot = ch.positions, ch.rotations
    new_pos, new_rot = [pos], [rot]
    for name, parent, off in extra:
        p = names.index(parent)
        names.append(name)
        parents.append(p)
        offsets.append(np.asarray(off))
        r = (new_rot[0] if p < rot.shape[1] else np.concatenate(new_rot, axis=1))[:, p]
        q = np.concatenate(new_pos, axis=1)[:, p]
        new_pos.append((q + r @ np.asarray(off))[:, None])
        new_rot.append(r[:, None])
    rich = Character(
        "cc",
        Skeleton(tuple(names), np.array(parents), np.array(offsets), np.zeros(len(names), bool)),
        np.concatenate(new_pos, axis=1),
        np.concatenate(new_rot, axis=1),
        np.concatenate(new_rot, axis=1).copy(),
        fps=ch.fps,
    )
    plain, helped = CharacterBody(ch), CharacterBody(rich)
    assert [(p["kind"], p["joint"], p["child"]) for p in helped.pieces] == [
        (p["kind"], p["joint"], p["child"]) for p in plain.pieces
    ]
    np.testing.assert_allclose(helped.vertices(5), plain.vertices(5), atol=1e-9)


def test_the_mannequin_cache_and_the_scene_body_cache_do_not_collide():
    """A scene drawn as a mannequin (``mannequin.scene_body``, as the viewpoint-entropy baseline
    does) can then be drawn with its scene body: the two caches kept on the scene are
    separate (they shared one dict, and the second lookup failed on the first's keys)."""
    from snapcore.motion.synth import synth_scene
    from snapcore.render import bodies, mannequin

    scene = synth_scene("kick")
    capsules = mannequin.scene_body(scene)
    dressed = bodies.scene_body(scene)
    assert mannequin.scene_body(scene) is capsules
    assert bodies.scene_body(scene) is dressed
    assert dressed is not capsules
