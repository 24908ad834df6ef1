"""Anatomy of a skeleton: joint names → side, body role, bone radius; the reference stature.

One table for every part of the suite that must know what a joint *is*: the body mesh
(capsule radii by role), contact detection (bones as capsules), the facing direction
(hips and upper arms), the default camera and, next, retargeting a body onto a
skeleton. Roles are read from joint names, case-insensitively, after removing a
``namespace:`` prefix (``mixamorig:LeftUpLeg``) and the side marker. The patterns cover
CMU cgspeed names (``Hips``, ``LeftUpLeg``, ``LeftLeg``, ``LeftFoot``, ``Spine1``,
``LeftShoulder`` = clavicle, ``LeftArm``...), Daz/Poser names (``hip``, ``abdomen``,
``chest``, ``lCollar``, ``lShldr``, ``lThigh``, ``lShin``...), Bandai names
(``UpperLeg_L``, ``LowerArm_R``...), the older CMU/assimp and 3ds Max names
(``LeftCollar``, ``LeftShoulder`` = upper arm, ``LeftElbow``, ``LeftHip`` = thigh...)
and the synthetic humanoid, and the conventions of tools whose files are not among the
shared clips (tests/test_anatomy.py): a side marker after a tool's prefix (``Bip01 L
Thigh``, ``CC_Base_L_Thigh``, ``J_Bip_L_UpperLeg``, ``Character1_LeftArm``) or glued to
the end (Kinect's ``HipLeft``), separators inside words (``upper_arm.L``), Unreal's
``calf_l``/``ball_l`` and OptiTrack's ``LUArm``/``LFArm``. A skeleton with no pelvis by
name (Kinect) gets it where the two legs meet. Unknown names get :data:`DEFAULT_ROLE`.

Lengths that scale with the person are given as fractions of the stature (the way
anthropometric tables are written, e.g. Drillis & Contini's segment lengths), so a
body or a tolerance for a character of height ``H`` is ``fraction × H``; quantities
that are defined for a typical adult (contact distances, rest speeds, the unit fitted
to a file whose unit is unknown) use :data:`REFERENCE_STATURE_M`.
"""

from __future__ import annotations

import functools
import re
from typing import Any

import numpy as np

__all__ = [
    "REFERENCE_STATURE_M",
    "stature_of",
    "ROLE_RADII",
    "DEFAULT_ROLE",
    "HIDDEN_ROLES",
    "TORSO_ROLES",
    "per_stature",
    "joint_sides",
    "joint_roles",
    "bone_role",
    "left_right_pairs",
    "LIMB_ROLES",
    "REQUIRED_LANDMARKS",
    "body_landmarks",
    "mirror_permutation",
]

#: Stature (m) of the reference adult: tolerances given "for a 1.70 m person" scale by
#: ``stature / REFERENCE_STATURE_M``, and a file whose unit cannot be recognised is
#: scaled so its people are this tall (the mean adult stature, both sexes).
REFERENCE_STATURE_M = 1.70


def stature_of(character) -> float:
    """A character's stature (m), or :data:`REFERENCE_STATURE_M` for one without a
    measurable height (no positions, a degenerate skeleton).

    Parameters
    ----------
    character : Character
        Anything with a ``height`` attribute (metres).

    Returns
    -------
    float
        Positive and finite.
    """
    h = float(character.height)
    return h if np.isfinite(h) and h > 0 else REFERENCE_STATURE_M


#: Stature (m) of the figure on which the body's radii below were measured.
_MEASURED_ON_M = 1.75


def per_stature(*metres: float) -> tuple[float, ...]:
    """Lengths measured on the 1.75 m reference figure, as fractions of its stature."""
    return tuple(m / _MEASURED_ON_M for m in metres)


def _radii(lateral: float, depth: float) -> tuple[float, float]:
    """A bone's ``(lateral, depth)`` radii (m, on the reference figure) per stature."""
    return lateral / _MEASURED_ON_M, depth / _MEASURED_ON_M


#: Bone radii as fractions of the stature, by the role of the bone's parent joint:
#: ``(lateral, depth)`` semi-axes of the cross-section. Lateral ≠ depth only on the
#: torso (hips are wider than deep). Roughly the anthropometric girths of an adult
#: (thigh circumference ~0.50 m → radius ~0.08 m; forearm ~0.25 m → ~0.04 m) slimmed a
#: little so limbs stay readable when they cross the torso.
ROLE_RADII: dict[str, tuple[float, float]] = {
    "pelvis": _radii(0.085, 0.085),  # pelvis → hip joint: CMU LHipJoint, Daz buttock
    "spine": _radii(0.125, 0.095),  # lower back / abdomen
    "chest": _radii(0.140, 0.100),  # thorax up to the shoulders
    "neck": _radii(0.050, 0.050),
    "head": _radii(0.085, 0.100),  # drawn as an ellipsoid by the body mesh
    "clavicle": _radii(0.050, 0.050),
    "upperarm": _radii(0.046, 0.046),
    "forearm": _radii(0.038, 0.038),
    "hand": _radii(0.030, 0.030),  # palm bones (hand → knuckles)
    "finger": _radii(0.010, 0.010),
    "thigh": _radii(0.072, 0.072),
    "shin": _radii(0.050, 0.050),
    "foot": _radii(0.042, 0.042),
    "toe": _radii(0.032, 0.032),
    "other": _radii(0.040, 0.040),
}
#: Role given to joint names no pattern recognises.
DEFAULT_ROLE = "other"
#: Roles whose bones are not part of the body surface: a floor-level root's bone up to
#: the hips (Bandai ``joint_Root``), eyes and jaw bones inside the head (Daz ``leftEye``).
HIDDEN_ROLES = ("hidden",)
#: Torso roles: elliptical cross-sections, oriented by the measured left-right axis.
TORSO_ROLES = ("spine", "chest")

# Patterns on the lower-cased joint name with its side marker removed, first match wins.
_ROLE_PATTERNS = (
    ("hidden", r"root|eye|jaw|tongue|teeth|tooth|facial|nose|ear$"),
    # before the fingers: Reallusion names its toes like fingers (PinkyToe1, IndexToe1)
    ("toe", r"toe"),
    ("hand", r"fingerbase|handbase|palm|metacarp|carpal"),
    ("finger", r"thumb|index|middle|mid\d|ring|pinky|little|finger|digit"),
    ("head", r"head"),
    ("neck", r"neck"),
    ("hand", r"hand|wrist"),
    ("forearm", r"forearm|lowerarm|lowarm|elbow|^farm$"),
    ("upperarm", r"upperarm|uparm|shldr|^uarm$|^arm|arm$"),
    ("clavicle", r"collar|clavicle|shoulder"),
    ("pelvis", r"hipjoint|buttock|pelvis"),
    ("thigh", r"upleg|upperleg|thigh"),
    ("shin", r"lowerleg|lowleg|shin|knee|calf|^leg|leg$"),
    ("foot", r"foot|ankle|heel"),
    ("toe", r"toe|ball$"),
    ("chest", r"chest|thorax|upperback|ribcage|spine[1-9]"),
    ("spine", r"spine|abdomen|lowerback|waist|torso|belly|^ab$|^abs$"),
    ("pelvis", r"hips?$"),
)
_SIDE_PATTERNS = (
    # (side, regex on the original name); the match is stripped from the name
    ("L", re.compile(r"^left[_ .]?", re.I)),
    ("R", re.compile(r"^right[_ .]?", re.I)),
    ("L", re.compile(r"[_ .]l(eft)?$", re.I)),
    ("R", re.compile(r"[_ .]r(ight)?$", re.I)),
    ("L", re.compile(r"^[lL](?=[A-Z_])")),  # lCollar, LHipJoint, LThumb (not LowerBack)
    ("R", re.compile(r"^[rR](?=[A-Z_])")),
    ("L", re.compile(r"^l(?=(hand|foot|arm|leg|hip|thigh|shin|shldr|collar)$)", re.I)),
    ("R", re.compile(r"^r(?=(hand|foot|arm|leg|hip|thigh|shin|shldr|collar)$)", re.I)),
    # after a tool's prefix: Bip01 L Thigh, CC_Base_L_Thigh, J_Bip_L_UpperLeg, Character1_LeftArm
    ("L", re.compile(r"(?<=[_ .:-])[lL](?=[_ .-])")),
    ("R", re.compile(r"(?<=[_ .:-])[rR](?=[_ .-])")),
    ("L", re.compile(r"(?<=[_ .:-])[lL]eft(?=[A-Z0-9_ .-])")),
    ("R", re.compile(r"(?<=[_ .:-])[rR]ight(?=[A-Z0-9_ .-])")),
    # glued to the end of a word: Kinect's HipLeft, ShoulderRight
    ("L", re.compile(r"(?<=[a-z])Left$")),
    ("R", re.compile(r"(?<=[a-z])Right$")),
)


def _split_side(name: str) -> tuple[str, str]:
    """(side ``'L'``/``'R'``/``''``, base name lower-cased without the side marker).

    Separators are kept in the base (:func:`joint_roles` drops them before matching)."""
    base = re.sub(r"_end$", "", str(name).rsplit(":", 1)[-1], flags=re.I)
    for side, pat in _SIDE_PATTERNS:
        m = pat.search(base)
        if m:
            rest = (base[: m.start()] + base[m.end() :]).strip("_ .")
            return side, rest.lower()
    return "", base.lower()


#: Skeletons whose names are read again and again (every scene of a library on one rig,
#: every body and renderer of a scene): the readings are kept, by value, for this many.
_MEMO_SIZE = 64


def _rig_key(names, parents=None) -> tuple:
    """A hashable key of a skeleton's names (and parents): its values."""
    key = tuple(str(n) for n in names)
    if parents is None:
        return key
    return key, tuple(int(p) for p in np.asarray(parents).ravel())


def joint_sides(names) -> list[str]:
    """Side of each joint from its name: ``'L'``, ``'R'`` or ``''`` (centre)."""
    return list(_joint_sides(_rig_key(names)))


@functools.lru_cache(maxsize=_MEMO_SIZE)
def _joint_sides(names: tuple) -> tuple:
    return tuple(_split_side(n)[0] for n in names)


def joint_roles(names, parents) -> list[str]:
    """Body role of each joint, read from its name (see :func:`_joint_roles`; kept per
    skeleton, a new list each call)."""
    key = _rig_key(names, parents)
    return list(_joint_roles_memo(key))


@functools.lru_cache(maxsize=_MEMO_SIZE)
def _joint_roles_memo(key: tuple) -> tuple:
    return tuple(_joint_roles(list(key[0]), np.array(key[1], dtype=int)))


def _joint_roles(names, parents) -> list[str]:
    """Body role of each joint, read from its name (case-insensitive).

    Parameters
    ----------
    names : sequence of str, length J
    parents : array of int, shape (J,)
        Parent index of each joint, -1 for roots.

    Returns
    -------
    list of str
        Keys of :data:`ROLE_RADII` or ``"hidden"``. Context resolves the ambiguous
        names: ``Shoulder`` is the upper arm when its parent is a collar (older CMU,
        assimp) and the clavicle otherwise (CMU cgspeed, Bandai); a sided ``Hip``
        (``LeftHip``) is the thigh while ``hip``/``Hips`` is the pelvis; a ``Root``
        joint is the pelvis unless it has a child that is (Bandai's floor-level root);
        end sites take the role of their parent.
    """
    parents = np.asarray(parents)
    roles: list[str] = []
    sides: list[str] = []
    for j, name in enumerate(names):
        side, base = _split_side(name)
        sides.append(side)
        base = re.sub(r"[_ .:-]", "", base)  # upper_arm, Bip01 Spine1, CC_Base_Thigh
        role = DEFAULT_ROLE
        for r, pat in _ROLE_PATTERNS:
            if re.search(pat, base):
                role = r
                break
        p = int(parents[j])
        if role == "pelvis" and side and re.fullmatch(r"hips?", base):
            role = "thigh"  # LeftHip, RightHip (older CMU / assimp)
        if role == "clavicle" and "shoulder" in base and p >= 0 and roles[p] == "clavicle":
            role = "upperarm"  # LeftCollar → LeftShoulder → LeftElbow
        if re.search(r"_end$", name, re.I) and p >= 0:
            role = roles[p]
        roles.append(role)
    # a root called "Root" is the pelvis unless one of its children is (only the
    # hierarchy's root: CC_Base's JawRoot is a jaw)
    for j, name in enumerate(names):
        if roles[j] == "hidden" and "root" in name.lower() and parents[j] < 0:
            kids = [k for k in range(len(names)) if parents[k] == j]
            if not any(roles[k] == "pelvis" for k in kids):
                roles[j] = "pelvis"
    if "pelvis" not in roles:
        # No pelvis by name (Kinect's SpineBase): it is where the two legs meet.
        meet = _meeting_joint(
            parents,
            *(
                [j for j, (r, s) in enumerate(zip(roles, sides)) if r == "thigh" and s == side]
                for side in "LR"
            ),
        )
        if meet is not None:
            roles[meet] = "pelvis"
    return roles


def _ancestors(parents, j: int) -> list[int]:
    """``j``, its parent, ..., the root."""
    out = []
    while j >= 0:
        out.append(j)
        j = int(parents[j])
    return out


def _meeting_joint(parents, left, right) -> int | None:
    """The nearest common ancestor of the first joints of ``left`` and ``right`` (None if
    either is empty or they share none)."""
    if not left or not right:
        return None
    up_left = _ancestors(parents, left[0])[1:]
    shared = [j for j in _ancestors(parents, right[0])[1:] if j in up_left]
    return shared[0] if shared else None


def bone_role(parent_role: str, child_role: str) -> str:
    """Role that sizes the bone from a joint of ``parent_role`` to one of ``child_role``.

    A bone takes its parent joint's role, except where the parent joint starts two
    kinds of bone: the pelvis's bone up the spine is torso (``spine``), not a hip
    connector, and the spine's bones to the shoulders and neck are ``chest``.
    """
    if parent_role == "pelvis" and child_role in ("spine", "chest", "neck"):
        return "spine"
    if parent_role == "spine" and child_role in ("clavicle", "upperarm", "neck"):
        return "chest"
    return parent_role


def left_right_pairs(names, parents) -> dict[str, tuple[int, int] | None]:
    """The left/right hip and shoulder joints that give a character's left-right axis.

    Parameters
    ----------
    names : sequence of str, length J
    parents : array of int, shape (J,)

    Returns
    -------
    dict
        ``hip``: the first ``(left, right)`` pair of thigh joints (``LeftUpLeg``,
        ``lThigh``, ``UpperLeg_L``, ``LeftHip``); ``shoulder``: the first pair of upper
        arms, or of clavicles where no upper arm is named. None where a side is missing.
        A skeleton with neither gets the first two mirrored sibling pairs
        (``leg_joint_L_1``/``leg_joint_R_1``) from a different parent each.
    """
    roles, sides = joint_roles(names, parents), joint_sides(names)

    def pair(*wanted):
        for role in wanted:
            left = [j for j, (r, s) in enumerate(zip(roles, sides)) if r == role and s == "L"]
            right = [j for j, (r, s) in enumerate(zip(roles, sides)) if r == role and s == "R"]
            if left and right:
                return left[0], right[0]
        return None

    out = {"hip": pair("thigh"), "shoulder": pair("upperarm", "clavicle")}
    if out["hip"] is None and out["shoulder"] is None:
        # No limb role by name (CesiumMan's leg_joint_L_1): the first two mirrored pairs
        # of siblings (same parent, same name but for the side) still give the left-right
        # axis, and the first one down the hierarchy is the hips or shoulders.
        mirrored = _mirrored_siblings(names, parents)
        out["hip"] = mirrored[0] if mirrored else None
        rest = [m for m in mirrored[1:] if parents[m[0]] != parents[mirrored[0][0]]]
        out["shoulder"] = rest[0] if rest else None
    return out


def _mirrored_siblings(names, parents) -> list[tuple[int, int]]:
    """(left, right) joints with the same parent and the same name but for the side
    marker, in the order of their left joint."""
    split = [_split_side(n) for n in names]
    out = []
    for j, (side, base) in enumerate(split):
        if side != "L":
            continue
        match = [
            k
            for k, (s, b) in enumerate(split)
            if s == "R" and b == base and parents[k] == parents[j]
        ]
        if match:
            out.append((j, match[0]))
    return out


#: Limb joints looked up per side by :func:`body_landmarks`: landmark name → role.
LIMB_ROLES = {
    "clavicle": "clavicle",
    "shoulder": "upperarm",
    "elbow": "forearm",
    "wrist": "hand",
    "hip": "thigh",
    "knee": "shin",
    "ankle": "foot",
    "toe": "toe",
}
#: Landmarks a skeleton must have to carry a human body (retargeting).
REQUIRED_LANDMARKS = (
    "pelvis",
    "head",
    *(f"{n}_{s}" for s in "LR" for n in ("shoulder", "elbow", "wrist", "hip", "knee", "ankle")),
)


def body_landmarks(names, parents) -> dict[str, Any]:
    """The joints a human body is fitted to, found by role and side (see
    :func:`_body_landmarks`; kept per skeleton, a new dict each call)."""
    return dict(_body_landmarks_memo(_rig_key(names, parents)))


@functools.lru_cache(maxsize=_MEMO_SIZE)
def _body_landmarks_memo(key: tuple) -> dict[str, Any]:
    return _body_landmarks(list(key[0]), np.array(key[1], dtype=int))


def _body_landmarks(names, parents) -> dict[str, Any]:
    """The joints a human body is fitted to, found by role and side.

    Parameters
    ----------
    names : sequence of str, length J
    parents : array of int, shape (J,)

    Returns
    -------
    dict
        Joint index (or None when the skeleton has none) for ``pelvis`` (the first
        unsided pelvis joint: ``Hips``, ``hip``), ``neck`` (the first neck joint on the
        way from the head down to the pelvis: the base of the neck), ``head`` (the first
        head joint that is not an end site), ``spine`` (a tuple: the joints from the
        pelvis up to ``neck``, or to ``head`` when there is no neck, both ends
        included) and, for side ``s`` in ``L``/``R``, ``<limb>_s`` for every limb of
        :data:`LIMB_ROLES` (``hip_L`` is the left thigh joint, ``wrist_R`` the first
        right hand joint...). A limb joint is searched among the descendants of the one
        before it (the knee below the hip...), so a stray joint of the same role
        elsewhere is not taken.
    """
    parents = np.asarray(parents)
    roles, sides = joint_roles(names, parents), joint_sides(names)
    end = [bool(re.search(r"_end$", str(n), re.I)) for n in names]
    n = len(names)

    def ancestors(j):
        return _ancestors(parents, j)

    kids: list[list[int]] = [[] for _ in range(n)]
    for c in range(n):
        if parents[c] >= 0:
            kids[int(parents[c])].append(c)

    def descendants(j):
        stack, count = list(kids[j]), 0
        while stack:
            count += 1
            stack.extend(kids[stack.pop()])
        return count

    def first(role, side="", below=None):
        """The joint of ``role`` nearest ``below`` (or the root) in the hierarchy; of
        joints as near, the one with the most joints below it (CC_Base's ToeBase with its
        toes, not the ToeBaseShareBone helper beside it): whatever order the children
        come in (CC_Base lists a foot's children in another order on each side)."""
        found = [
            j
            for j in range(n)
            if roles[j] == role
            and sides[j] == side
            and not end[j]
            and (below is None or below in ancestors(j))
        ]
        if not found:
            return None
        return min(found, key=lambda j: (len(ancestors(j)), -descendants(j), j))

    # values: int | None, but "spine" is a tuple (keys are built from names: no TypedDict)
    out: dict[str, Any] = {"pelvis": first("pelvis"), "head": first("head")}
    neck = None
    if out["head"] is not None:
        for j in ancestors(out["head"])[1:]:
            if roles[j] == "neck":
                neck = j  # keeps the lowest neck joint on the way down
    out["neck"] = neck
    top = neck if neck is not None else out["head"]
    spine = ()
    if out["pelvis"] is not None and top is not None and out["pelvis"] in ancestors(top):
        chain = ancestors(top)
        spine = tuple(reversed(chain[: chain.index(out["pelvis"]) + 1]))
    out["spine"] = spine
    for side in "LR":
        prev = None
        for limb in ("clavicle", "shoulder", "elbow", "wrist"):
            j = first(LIMB_ROLES[limb], side, prev)
            out[f"{limb}_{side}"] = j
            prev = j if j is not None else prev
        prev = None
        for limb in ("hip", "knee", "ankle", "toe"):
            j = first(LIMB_ROLES[limb], side, prev)
            if j is None and limb == "toe" and out[f"ankle_{side}"] is not None:
                # a second foot joint below the ankle is the ball of the foot (SMPL's and
                # Kinect's "foot" below their "ankle")
                ankle = out[f"ankle_{side}"]
                j = next(
                    (
                        k
                        for k in range(n)
                        if parents[k] == ankle and not end[k] and roles[k] == "foot"
                    ),
                    None,
                )
            out[f"{limb}_{side}"] = j
            prev = j if j is not None else prev
    return out


def mirror_permutation(names) -> np.ndarray:
    """Each joint's mirror twin: the index of the joint with the same name on the other
    side (``LeftHand`` ↔ ``RightHand``), itself for a centre joint or one without a twin.

    Parameters
    ----------
    names : sequence of str, length J

    Returns
    -------
    ndarray of int, shape (J,)
        A permutation (an involution): ``positions[..., perm, :]`` swaps left and right.
    """
    # An end site keeps its own key: _split_side drops "_end" (LeftToe and LeftToe_End).
    split = [(*_split_side(n), str(n).lower().endswith("_end")) for n in names]
    where = {(s, b, e): j for j, (s, b, e) in enumerate(split)}
    other = {"L": "R", "R": "L"}
    return np.array(
        [where.get((other[s], b, e), j) if s in other else j for j, (s, b, e) in enumerate(split)],
        dtype=int,
    )
