"""Joint roles from the naming conventions of tools whose files are not in ../shared.

The shared clips cover CMU, Daz, 3ds Max, Bandai and one assimp export. Files from other
tools name the same joints differently: a side marker in the middle (``Bip01 L Thigh``,
``CC_Base_L_Thigh``, ``J_Bip_L_UpperLeg``) or glued to the end (Kinect's ``HipLeft``),
a tool prefix (``Character1_LeftArm``), separators inside words (``upper_arm.L``) or
abbreviations (OptiTrack's ``LUArm``). Each convention below is written from the tool's
published joint list, applied to the procedural humanoid, and must give a body.
"""

from __future__ import annotations

import re
import warnings

import numpy as np
import pytest

from snapcore.motion.anatomy import REQUIRED_LANDMARKS, body_landmarks, left_right_pairs
from snapcore.motion.bvh import format_bvh
from snapcore.motion.load import load_scene
from snapcore.motion.scene import Scene
from snapcore.motion.synth import humanoid_document

#: The humanoid's joints (CMU-style names) by landmark: what each convention must name.
SYNTH_LANDMARKS = {"pelvis": "Hips", "neck": "Neck", "head": "Head"} | {
    f"{limb}_{s[0]}": f"{s}{joint}"
    for s in ("Left", "Right")
    for limb, joint in (
        ("clavicle", "Shoulder"),
        ("shoulder", "Arm"),
        ("elbow", "ForeArm"),
        ("wrist", "Hand"),
        ("hip", "UpLeg"),
        ("knee", "Leg"),
        ("ankle", "Foot"),
        ("toe", "ToeBase"),
    )
}

# Convention name for each humanoid joint: centre joints, then sided ones as a template in
# {L} (the side as the tool writes it) and the tool's words for each side.
_CENTRE = ("Hips", "Spine", "Spine1", "Neck", "Head")
_SIDED = ("Shoulder", "Arm", "ForeArm", "Hand", "UpLeg", "Leg", "Foot", "ToeBase")
CONVENTIONS = {
    "unreal": (
        ("pelvis", "spine_01", "spine_03", "neck_01", "head"),
        (
            "clavicle_{L}",
            "upperarm_{L}",
            "lowerarm_{L}",
            "hand_{L}",
            "thigh_{L}",
            "calf_{L}",
            "foot_{L}",
            "ball_{L}",
        ),
        ("l", "r"),
    ),
    "xsens_mvn": (
        ("Pelvis", "L5", "T8", "Neck", "Head"),
        (
            "{L}Shoulder",
            "{L}UpperArm",
            "{L}ForeArm",
            "{L}Hand",
            "{L}UpperLeg",
            "{L}LowerLeg",
            "{L}Foot",
            "{L}Toe",
        ),
        ("Left", "Right"),
    ),
    "optitrack_motive": (
        ("Hip", "Ab", "Chest", "Neck", "Head"),
        (
            "{L}Shoulder",
            "{L}UArm",
            "{L}FArm",
            "{L}Hand",
            "{L}Thigh",
            "{L}Shin",
            "{L}Foot",
            "{L}Toe",
        ),
        ("L", "R"),
    ),
    # Kinect v2 names joints, not bones, and has no pelvis joint: SpineBase is the root
    "kinect": (
        ("SpineBase", "SpineMid", "SpineShoulder", "Neck", "Head"),
        (
            "Clavicle{L}",
            "Shoulder{L}",
            "Elbow{L}",
            "Wrist{L}",
            "Hip{L}",
            "Knee{L}",
            "Ankle{L}",
            "Foot{L}",
        ),
        ("Left", "Right"),
    ),
    "smpl": (
        ("pelvis", "spine1", "spine3", "neck", "head"),
        (
            "{L}_collar",
            "{L}_shoulder",
            "{L}_elbow",
            "{L}_wrist",
            "{L}_hip",
            "{L}_knee",
            "{L}_ankle",
            "{L}_foot",
        ),
        ("left", "right"),
    ),
    "blender_metarig": (
        ("hips", "spine", "chest", "neck", "head"),
        (
            "shoulder.{L}",
            "upper_arm.{L}",
            "forearm.{L}",
            "hand.{L}",
            "thigh.{L}",
            "shin.{L}",
            "foot.{L}",
            "toe.{L}",
        ),
        ("L", "R"),
    ),
    "3dsmax_biped": (
        ("Bip01_Pelvis", "Bip01_Spine", "Bip01_Spine1", "Bip01_Neck", "Bip01_Head"),
        (
            "Bip01_{L}_Clavicle",
            "Bip01_{L}_UpperArm",
            "Bip01_{L}_Forearm",
            "Bip01_{L}_Hand",
            "Bip01_{L}_Thigh",
            "Bip01_{L}_Calf",
            "Bip01_{L}_Foot",
            "Bip01_{L}_Toe0",
        ),
        ("L", "R"),
    ),
    "character_creator": (
        ("CC_Base_Hip", "CC_Base_Waist", "CC_Base_Spine02", "CC_Base_NeckTwist01", "CC_Base_Head"),
        (
            "CC_Base_{L}_Clavicle",
            "CC_Base_{L}_Upperarm",
            "CC_Base_{L}_Forearm",
            "CC_Base_{L}_Hand",
            "CC_Base_{L}_Thigh",
            "CC_Base_{L}_Calf",
            "CC_Base_{L}_Foot",
            "CC_Base_{L}_ToeBase",
        ),
        ("L", "R"),
    ),
    "vrm": (
        ("J_Bip_C_Hips", "J_Bip_C_Spine", "J_Bip_C_Chest", "J_Bip_C_Neck", "J_Bip_C_Head"),
        (
            "J_Bip_{L}_Shoulder",
            "J_Bip_{L}_UpperArm",
            "J_Bip_{L}_LowerArm",
            "J_Bip_{L}_Hand",
            "J_Bip_{L}_UpperLeg",
            "J_Bip_{L}_LowerLeg",
            "J_Bip_{L}_Foot",
            "J_Bip_{L}_ToeBase",
        ),
        ("L", "R"),
    ),
}


def _cmu_with_prefix(prefix: str):
    """CMU/HumanIK names behind a tool's prefix."""
    return (
        tuple(prefix + n for n in _CENTRE),
        tuple(prefix + "{L}" + n for n in _SIDED),
        ("Left", "Right"),
    )


# MotionBuilder / HumanIK with the character's name as a prefix
CONVENTIONS["motionbuilder"] = _cmu_with_prefix("Character1_")
# Mixamo after a converter replaced the namespace colon
CONVENTIONS["mixamo_underscore"] = _cmu_with_prefix("mixamorig_")
# the Biped as 3ds Max writes it into BVH files, spaces and all
CONVENTIONS["3dsmax_biped_spaces"] = (
    *(tuple(n.replace("_", " ") for n in names) for names in CONVENTIONS["3dsmax_biped"][:2]),
    CONVENTIONS["3dsmax_biped"][2],
)


def _renaming(convention: str) -> dict[str, str]:
    centre, sided, words = CONVENTIONS[convention]
    out = dict(zip(_CENTRE, centre))
    for side, word in zip(("Left", "Right"), words):
        out |= {side + j: t.format(L=word) for j, t in zip(_SIDED, sided)}
    return out


def _renamed_clip(tmp_path, convention: str, motion: str = "walk", seconds: float = 1.0):
    """The procedural humanoid written as BVH with the convention's joint names."""
    text = format_bvh(humanoid_document(motion, seconds=seconds))
    mapping = _renaming(convention)
    text = re.sub(
        r"^(\s*(?:ROOT|JOINT) )(\S+)", lambda m: m.group(1) + mapping[m.group(2)], text, flags=re.M
    )
    path = tmp_path / f"{convention}.bvh"
    path.write_text(text)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the synthetic file's unit is metres: not under test
        return load_scene(path).characters[0], mapping


@pytest.mark.parametrize("convention", sorted(CONVENTIONS))
def test_landmarks_are_found_in_every_naming(tmp_path, convention):
    """Every landmark is the joint the convention gives that body part, and the left-right
    pairs are the thighs and upper arms."""
    ch, mapping = _renamed_clip(tmp_path, convention)
    names = ch.skeleton.names
    lm = body_landmarks(names, ch.skeleton.parents)
    got = {k: names[lm[k]] if lm[k] is not None else None for k in SYNTH_LANDMARKS}
    want = {k: mapping[v] for k, v in SYNTH_LANDMARKS.items()}
    if convention == "kinect":
        want["pelvis"] = mapping["Hips"]  # no pelvis by name: the thighs' common parent
    assert got == want
    assert not [k for k in REQUIRED_LANDMARKS if lm[k] is None]
    pairs = left_right_pairs(names, ch.skeleton.parents)
    assert [names[j] for k in ("hip", "shoulder") for j in pairs[k]] == [
        mapping[n] for n in ("LeftUpLeg", "RightUpLeg", "LeftArm", "RightArm")
    ]


@pytest.mark.parametrize("convention", ["kinect", "optitrack_motive", "3dsmax_biped_spaces"])
def test_the_human_body_fits_other_namings(tmp_path, convention):
    """The human body is retargeted (no mannequin fallback) and keeps its joints within
    3 cm of the skeleton's, as on the shared clips."""
    from snapcore.render.human import HumanBody

    ch, _ = _renamed_clip(tmp_path, convention)
    _, got, want = HumanBody(ch).landmarks()
    assert np.linalg.norm(got - want, axis=-1).max() <= 0.03


def test_mirrored_siblings_give_the_left_right_axis_when_no_limb_is_named():
    """Joints named only by side and number (CesiumMan: ``leg_joint_L_1``) still give a
    facing: the first mirrored sibling pair is the hips, the next under another parent
    the shoulders. Named limbs take precedence over it."""
    names = ("torso_1", "leg_joint_R_1", "leg_joint_L_1", "torso_2", "limb_R", "limb_L", "leg_R_2")
    parents = np.array([-1, 0, 0, 0, 3, 3, 1])
    assert left_right_pairs(names, parents) == {"hip": (2, 1), "shoulder": (5, 4)}
    named = ("Hips", "RightUpLeg", "LeftUpLeg", "Spine", "limb_R", "limb_L", "RightLeg")
    assert left_right_pairs(named, parents)["hip"] == (2, 1)
    assert left_right_pairs(named, parents)["shoulder"] is None


def test_cesium_man_faces_the_way_he_walks(motions_dir):
    """CesiumMan's left leg is at +X in his first frame and he walks along +Z in place (glTF
    characters face +Z): his facing is +Z in every frame."""
    from snapcore.motion.facing import character_facing

    c = load_scene(motions_dir / "gltf" / "CesiumMan.glb").characters[0]
    f = character_facing(c.positions, c.joint_names, c.parents)
    assert np.all(f @ [0.0, 0.0, 1.0] > 0.9)


@pytest.mark.parametrize("motion", ["jump", "kick"])
def test_the_story_pick_does_not_depend_on_the_naming(tmp_path, motion):
    """The story selector reads contacts from joint roles: the same motion under every
    naming gives the same pick (and its contacts) as under CMU names."""
    from snapcore.select.pose_methods import select_pose

    def pick(ch):
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sel = select_pose(Scene([ch], fps=ch.fps), method="story")
        return sel.index

    want = pick(_renamed_clip(tmp_path, "motionbuilder", motion, seconds=None)[0])
    got = {
        c: pick(_renamed_clip(tmp_path, c, motion, seconds=None)[0]) for c in sorted(CONVENTIONS)
    }
    assert got == dict.fromkeys(got, want)


def test_roles_and_sides_are_a_cached_property_of_the_skeleton():
    """Skeleton.roles/.sides are joint_roles/joint_sides of its names, computed once per
    skeleton and shared by the characters that share it (a scaled copy keeps its own)."""
    from snapcore.motion.anatomy import joint_roles, joint_sides
    from snapcore.motion.synth import synth_scene

    c = synth_scene("walk").characters[0]
    sk = c.skeleton
    assert list(sk.roles) == joint_roles(sk.names, sk.parents)
    assert list(sk.sides) == joint_sides(sk.names)
    assert {"foot", "hand", "pelvis"} <= set(sk.roles) and {"L", "R"} <= set(sk.sides)
    assert sk.roles is sk.roles and sk.sides is sk.sides  # computed once
    assert c.frames(0, 10).skeleton.roles is sk.roles  # a cut shares the skeleton
    assert c.rescaled(2.0).skeleton.roles == sk.roles  # a new skeleton, the same names


def test_toes_named_like_fingers_are_toes_whatever_the_order_of_children():
    """Reallusion's foot: a ToeBaseShareBone helper beside ToeBase and its toes named
    like fingers (PinkyToe1, IndexToe1). The toes take the toe role, and the toe
    landmark is ToeBase (the joint with the toes below it) with the foot's children
    in either order; a JawRoot under the head is no pelvis."""
    from snapcore.motion.anatomy import joint_roles

    for share_first in (True, False):
        names = ["RL_BoneRoot", "CC_Base_Hip", "CC_Base_L_Thigh", "CC_Base_L_Calf"]
        names += ["CC_Base_L_Foot"]
        kids = ["CC_Base_L_ToeBaseShareBone", "CC_Base_L_ToeBase"]
        names += kids if share_first else kids[::-1]
        toe_base = names.index("CC_Base_L_ToeBase")
        names += ["CC_Base_L_PinkyToe1", "CC_Base_L_IndexToe1", "CC_Base_L_BigToe1"]
        names += ["CC_Base_Waist", "CC_Base_Head", "CC_Base_JawRoot"]
        parents = [-1, 0, 1, 2, 3, 4, 4, toe_base, toe_base, toe_base, 1, 10, 11]
        roles = joint_roles(names, parents)
        assert roles[7:10] == ["toe"] * 3, roles
        assert roles[names.index("CC_Base_JawRoot")] != "pelvis"
        assert body_landmarks(names, parents)["toe_L"] == toe_base


def test_joint_readings_are_kept_per_skeleton_and_handed_out_as_copies(monkeypatch):
    """A library reads one rig's names for every scene and body: the readings are made
    once per skeleton (by value: a new list of the same names hits), and each call
    gets its own copy, so a caller that edits one changes no later answer."""
    import snapcore.motion.anatomy as anatomy

    doc = humanoid_document("walk", seconds=0.5)
    names, parents = list(doc.names), np.asarray(doc.parents)
    calls = []
    real = anatomy._joint_roles
    monkeypatch.setattr(anatomy, "_joint_roles", lambda n, p: calls.append(1) or real(n, p))
    anatomy._joint_roles_memo.cache_clear()
    anatomy._body_landmarks_memo.cache_clear()
    roles = anatomy.joint_roles(names, parents)
    again = anatomy.joint_roles([str(n) for n in names], parents.copy())
    assert again == roles and again is not roles
    again[0] = "edited"
    assert anatomy.joint_roles(names, parents) == roles
    lm = body_landmarks(names, parents)
    lm["pelvis"] = -5
    assert body_landmarks(names, parents)["pelvis"] == names.index("Hips")
    assert len(calls) == 1  # body_landmarks read the kept roles too
    sides = anatomy.joint_sides(names)
    sides.clear()
    assert anatomy.joint_sides(names)[names.index("LeftUpLeg")] == "L"
