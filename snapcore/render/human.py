"""A human body on any humanoid skeleton: the MakeHuman mesh retargeted and skinned.

The body (:mod:`snapcore.render.human_asset`: 13,380 vertices, 26,756 triangles, a
31-bone CMU-style rig in an A-pose) is fitted to a motion-capture skeleton by joint
*roles* (:func:`snapcore.motion.anatomy.body_landmarks`), so CMU cgspeed, Daz/Poser,
3ds Max, Bandai and assimp skeletons all carry it without name tables.

Retargeting
-----------
Rig bones move in *groups* (a bone, or a rigid piece such as the hand with its fingers,
or foot and toe on a skeleton without toes). Each group has a head and, where the
skeleton has one, a tip on the skeleton: a joint, or a point along the spine's chain of
joints at the same fraction of its length as on the rig (the rig's spine has four
bones, a BVH spine two to four; :mod:`snapcore.render.rig_groups` builds them). Only
lengths are read from the skeleton's rest pose.

At frame ``f`` the group's frame is ``W = F_skeleton(f) F_rig^T``: the same recipe
(:mod:`snapcore.render.segments`: pelvis from the hip line, chest from the shoulder
line, limbs from their bone and bend plane, feet from ankle → toe, the head from the
eyes) applied to the skeleton's joint positions and to the rig's rest pose, so no rest
convention enters. Lengths: along the axis, the skeleton's head-tip distance over the
rig's; across it, ``k`` = the person's size over the rig's (the mean of the legs' and
the standing head height's ratios: :meth:`Retarget._size_ratio`); untracked groups
(head, hands) scale by ``k`` all round; a foot's depth follows the skeleton's standing
ankle height. A rig point ``x`` then moves to ``h(f) + W diag(k, s, k) A_g^T (x -
head_g)`` (``A_g`` = ``F_rig``): every bone head lands on its skeleton joint, feet are
planted on the floor where they stand (:meth:`Retarget._plant_shifts`), and
dual-quaternion skinning (:func:`snapcore.motion.skinning.dq_skin`) deforms the mesh
between them.

Where a skeleton's joints say a segment's line but not how it sits about it, the
rig's posture is kept in the clip's median pose and the skeleton's changes add on:
the torso keeps the rig's spine curve about its chord (:meth:`Retarget._spine_offsets`),
the head its nod and the clavicle its lift relative to the chest (:data:`TURNED`), the
ball of the foot its height above the floor (:meth:`Retarget._ball_drops`). Each had
followed one rig's joint placement onto another's: CC_Base's body arched back and
looked up, CMU's shoulders shrugged.

Skinning: linear blending took the chord of the arc between two bones, so an elbow
folded to 17° ended in an open stump, a knee at 16° pinched into a flap (the upper
arm kept 68% of its cross-section, thigh and shank 40-51%), and the top of a shoulder
whose arm hangs where the rig's was raised 45° came to a corner. Dual quaternions keep
the skin on the arc (93-156% there, ``tests/test_human_rigs.py``); the bones' stretch
and girth scale, which a rigid motion cannot carry, are blended linearly in the rest
pose first (Kavan et al. 2008), at about twice the cost of linear blending.
"""

from __future__ import annotations

from functools import cached_property

import numpy as np

from snapcore.errors import SceneError
from snapcore.motion.anatomy import REQUIRED_LANDMARKS, body_landmarks
from snapcore.motion.dq_kernel import dq_plan, dq_skin_planned
from snapcore.motion.kinematics import rest_positions
from snapcore.motion.load import infer_ground
from snapcore.render.human_asset import (
    LEFT_LIGHTEN,
    RIGHT_DARKEN,
    HumanAsset,
    body_colours,
    human_asset,
    surface_weights,
)
from snapcore.render.rig_groups import Point, eye_joints, rig_groups
from snapcore.render.segments import (
    axis_rotation,
    cross,
    frame_x,
    frame_z,
    hinge,
    mean_rotation,
    norm,
    rest_frame,
    swing_matrices,
    unit,
)
from snapcore.render.shoulders import rig_elevation, shoulder_drops, shoulder_masks
from snapcore.render.skinned import FrameBlocks
from snapcore.render.soles import SIDES, SoleFit

__all__ = [
    "RetargetError",
    "Retarget",
    "HumanBody",
    "swing_matrices",
    "motion_offsets",
    "LANDMARK_BONES",
    "landmark_weights",
    "LEFT_LIGHTEN",
    "RIGHT_DARKEN",
]

#: The rig bone whose head is each skeleton landmark (:func:`body_landmarks` names).
LANDMARK_BONES = {"pelvis": "Hips", "neck": "Neck", "head": "Head"} | {
    f"{limb}_{s}": f"{side}{bone}"
    for s, side in SIDES.items()
    for limb, bone in (
        ("hip", "UpLeg"),
        ("knee", "Leg"),
        ("ankle", "Foot"),
        ("shoulder", "Arm"),
        ("elbow", "ForeArm"),
        ("wrist", "Hand"),
    )
}
#: Precision of the vertices drawn (stills, videos, reliefs, viewpoint entropy): the GL
#: pipeline is float32 anyway.
DRAW_DTYPE = np.float32
#: Nearest rest vertices whose skin weights a landmark borrows.
LANDMARK_NEIGHBOURS = 8


def landmark_weights(asset: HumanAsset, points: np.ndarray, k: int = LANDMARK_NEIGHBOURS):
    """Skin weights for joints inside the body (:func:`surface_weights` of the
    ``k`` nearest rest vertices), so a joint moves as the surface around it does."""
    return surface_weights(asset, points, k)


class RetargetError(SceneError):
    """A skeleton the human body cannot be fitted to (a required joint is missing).

    Attributes
    ----------
    missing : list of str
        Landmarks not found (``hip_L``, ``head``...).
    unmapped : list of str
        The skeleton's joints whose role no name pattern recognised.
    """

    def __init__(self, character: str, missing, unmapped):
        self.missing = list(missing)
        self.unmapped = list(unmapped)
        names = ", ".join(self.unmapped) if self.unmapped else "none"
        super().__init__(
            f"character '{character}': no joint for {', '.join(self.missing)} "
            f"(joints with no known role: {names})"
        )


def motion_offsets(character, max_frames: int = 200) -> np.ndarray:
    """Each joint's offset from its parent in the parent's frame, as the motion has it.

    The median over (up to ``max_frames``) frames of ``R_parent^T (p_joint - p_parent)``:
    the header offset for most BVH files, but the position channels' value where every
    joint has them (Bandai: the header offsets are not the bones). Roots get their
    median position. Shape (J, 3), metres.
    """
    c = character
    f = np.unique(np.linspace(0, c.n_frames - 1, min(c.n_frames, max_frames)).round().astype(int))
    parents = np.asarray(c.skeleton.parents)
    pos, rot = c.positions[f], c.rotations[f]
    has = parents >= 0
    pp = np.maximum(parents, 0)
    rel = np.einsum("fjki,fjk->fji", rot[:, pp], pos - pos[:, pp])
    out = np.median(rel, axis=0)
    out[~has] = np.median(pos[:, ~has], axis=0)
    return out


#: Frames whose bone matrices are made at a time when skinning (bounds their memory;
#: the kernel itself works in smaller chunks).
SKIN_FRAMES = 256
#: Shoulder-drop masks kept (:meth:`Retarget._drop_weights`), the most recent first:
#: (asset, points, weights, moved points, their masks).
_DROPS: list[tuple] = []
_DROPS_KEPT = 4

#: Rig bones whose skin is blended linearly, not as dual quaternions: the pelvis and
#: hip pieces, whose short stretched bones meet the thigh at up to 120° (a dancer's
#: kick), where dual quaternions bulge the hip joint 3 cm out of place (CMU 05_06);
#: a vertex shared with other bones takes its weight's share of linear blending.
LINEAR_BONES = ("Hips", "LHipJoint", "RHipJoint")

#: Segments turned about one of their axes (0: x, the left; 2: z, the front) to sit as
#: the rig's relative to the chest in the clip's median pose (see Retarget._calibrate).
TURNED = {"eyes": 0, "clavicle": 2}


#: Joints of the skeleton whose positions the segment frames read, with the rig point
#: (bone head) that stands for each.
_FRAME_JOINTS = {
    f"{n}_{s}": f"{side}{b}"
    for s, side in SIDES.items()
    for n, b in (
        ("hip", "UpLeg"),
        ("knee", "Leg"),
        ("ankle", "Foot"),
        ("shoulder", "Arm"),
        ("elbow", "ForeArm"),
        ("wrist", "Hand"),
    )
}


class Retarget(SoleFit):
    """The fit of the human rig to one skeleton: per-bone transforms for any pose.

    Parameters
    ----------
    character : Character
        A humanoid skeleton.
    asset : HumanAsset, optional
        Default :func:`human_asset`.

    Raises
    ------
    RetargetError
        A required landmark (:data:`snapcore.motion.anatomy.REQUIRED_LANDMARKS`) is
        missing.
    """

    def __init__(self, character, asset: HumanAsset | None = None, *, ground: float | None = None):
        self.asset = asset = asset or human_asset()
        sk = character.skeleton
        names, parents = sk.names, np.asarray(sk.parents)
        lm = body_landmarks(names, parents)
        missing = [k for k in REQUIRED_LANDMARKS if lm[k] is None]
        if missing or len(lm["spine"]) < 2:
            unmapped = [n for n, r in zip(names, sk.roles) if r == "other"]
            raise RetargetError(character.name, missing or ["spine (pelvis → neck)"], unmapped)
        self.landmarks = lm
        self.offsets = motion_offsets(character)
        # only lengths are read from it (arc lengths along chains, bone lengths): the
        # same whatever pose the rest convention puts the skeleton in
        self.rest = rest = rest_positions(parents, self.offsets)
        self.eyes = eye_joints(names, parents, sk.sides, lm["head"])
        self.ground = float(infer_ground([character.positions]) if ground is None else ground)
        self.k = self._size_ratio(lm, rest, asset, character.positions)  # the girth scale
        sample = np.unique(
            np.linspace(0, character.n_frames - 1, min(character.n_frames, 200)).round().astype(int)
        )
        fit = rig_groups(
            lm, character.positions[sample], rest, self.offsets, sk, asset, k=self.k, eyes=self.eyes
        )
        self.groups, self.neck_base = fit.groups, fit.neck_base
        self._spine1, self._head_group, self._neck1 = fit.spine1, fit.head_group, fit.neck1
        # per rig bone, 1 where the skin is blended linearly (see LINEAR_BONES)
        self._linear_bones = np.array([float(b in LINEAR_BONES) for b in asset.bone_names])
        self._rig_elevation = rig_elevation(asset)
        self._spine_offsets(character.positions[sample])
        self._drop: dict[str, tuple[int, int, float]] = {}
        self._calibrate(character.positions[sample], character.rotations[sample])
        self.sole_scale = self._sole_scale(character.positions)
        self._ball_drops(character.positions)

    def _size_ratio(self, lm, rest, rig, positions) -> float:
        """The person's size over the rig's: the mean of two ratios, the legs' (thigh +
        shank, both legs' mean) and the standing head's (the head joint's 95th
        percentile height above the floor over the rig's head joint above its soles),
        the second kept within 10% of the first (a clip that never stands up).

        The legs alone misjudge a long-legged figure: CC_Base's legs are 52% of its
        stature, the rig's 48%, and a body scaled by them stood 2.03 m for a 1.87 m
        figure (8% too broad, the head too big); a head joint alone sits at a
        different height in the skull on every rig."""
        leg = self._leg_ratio(lm, rest, rig)
        head = np.percentile(positions[:, lm["head"], 1] - self.ground, 95.0)
        rig_head = rig.heads[rig.bone("Head")][1] - rig.vertices[:, 1].min()
        return float(0.5 * (leg + np.clip(head / rig_head, 0.9 * leg, 1.1 * leg)))

    @staticmethod
    def _leg_ratio(lm, rest, rig) -> float:
        """The skeleton's thigh + shank over the rig's (both legs' mean)."""
        rig_leg = (
            sum(
                np.linalg.norm(rig.tails[rig.bone(b)] - rig.heads[rig.bone(b)])
                for b in ("LeftUpLeg", "LeftLeg", "RightUpLeg", "RightLeg")
            )
            / 2
        )
        sk_leg = np.mean(
            [
                np.linalg.norm(rest[lm[f"knee_{s}"]] - rest[lm[f"hip_{s}"]])
                + np.linalg.norm(rest[lm[f"ankle_{s}"]] - rest[lm[f"knee_{s}"]])
                for s in "LR"
            ]
        )
        return float(sk_leg / rig_leg)

    def _chord(self, positions):
        """The torso's chord on poses (F, J, 3): the pelvis (F, 3) and the chord's
        frame (F, 3, 3): y from the pelvis to the neck base, x the mean of the hip and
        shoulder lines, z forward."""
        lm = self.landmarks
        pel = positions[:, lm["pelvis"]]
        lat = unit(positions[:, lm["hip_L"]] - positions[:, lm["hip_R"]]) + unit(
            positions[:, lm["shoulder_L"]] - positions[:, lm["shoulder_R"]]
        )
        return pel, frame_x(self._point(positions, self.neck_base) - pel, lat)

    def _spine_offsets(self, pos_sample):
        """Where the rig's spine curve puts its torso bone heads, off the skeleton's chain.

        Skeletons run their spine joints up the middle of the trunk in a nearly straight
        line (CC_Base, CMU), the rig's spine curves (its lumbar bone leans 26° back,
        its chest bone forward): aiming each rig bone along the skeleton's chain
        tipped the rig's pelvis 25-35° forward and its chest back, an arched back. The
        torso's inner points (the heads of LowerBack, Spine, Spine1) are moved, in the
        frame of the torso's chord (pelvis → neck base), by a constant offset: the rig's
        curve (scaled to the chord's length) less the skeleton's chain in its median
        pose over the clip. In that pose the torso is the rig's, upright where the
        chord is; away from it the chain's own bending adds on. Only the sagittal
        (up, forward) part is taken: the lateral one of both is nil.
        """
        g_all = self.groups
        self._off_head = np.zeros((len(g_all), 3))
        self._off_tip = np.zeros((len(g_all), 3))
        a = self.asset
        rig_pel = a.heads[a.bone("Hips")]
        rig_top = a.heads[a.bone("Neck")]
        rig_t = frame_x(rig_top - rig_pel, np.array([1.0, 0.0, 0.0]))
        pel, t = self._chord(pos_sample)
        top = self._point(pos_sample, self.neck_base)
        s = float(np.median(np.linalg.norm(top - pel, axis=-1))) / np.linalg.norm(rig_top - rig_pel)

        def offset(p: Point, rig_p):
            q = np.median(np.einsum("fji,fj->fi", t, self._point(pos_sample, p) - pel), axis=0)
            out = s * rig_t.T @ (rig_p - rig_pel) - q
            out[0] = 0.0
            return out

        torso = [i for i, g in enumerate(g_all) if g.recipe[0] == "torso"]
        for i in torso[1:]:
            self._off_head[i] = offset(g_all[i].head, g_all[i].rig_head)
        for i in torso[:-1]:
            self._off_tip[i] = offset(g_all[i].tip, g_all[i].rig_tip)

    def _ball_drops(self, positions):
        """How far below the skeleton's toe joint the rig's ball of the foot goes.

        Skeletons put the toe joint at their own height inside the foot: CC_Base's
        stands 6.8 cm above the floor, the rig's ball 2.8 cm (x k) above its sole, so a
        foot aimed at it stood on its heel with the toes 3-8 cm up (folded onto the
        instep in pictures). Standing (the 10th percentile of the toe joint's height
        above the floor, as the ankle's in :meth:`_sole_scale`), the ball is put the
        rig's height (x the foot's depth scale) above the floor: the toe point moves
        along the foot's down direction (the shank's, square to the foot) by the
        difference, within ±5 cm.
        """
        a = self.asset
        for s, side in SIDES.items():
            toe = self.landmarks[f"toe_{s}"]
            foot = next(i for i, g in enumerate(self.groups) if g.bones[0] == f"{side}Foot")
            toes = [i for i, g in enumerate(self.groups) if g.bones[0] == f"{side}ToeBase"]
            if toe is None or self.groups[foot].tip is None or not toes:
                continue
            w = a.weights[:, [a.bone(f"{side}Foot"), a.bone(f"{side}ToeBase")]]
            foot_v = np.asarray(w.sum(axis=1)).ravel() > 0.5
            rig = (a.heads[a.bone(f"{side}ToeBase")][1] - a.vertices[foot_v, 1].min()) * self.k
            rig *= self.sole_scale[foot]
            h = np.percentile(positions[:, toe, 1] - self.ground, 10.0)
            self._drop[s] = (foot, toes[0], float(np.clip(h - rig, -0.05, 0.05)))

    def _calibrate(self, pos_sample, rot_sample):
        g_all = self.groups
        names = self.asset.bone_names
        self.bone_group = np.empty(len(names), dtype=np.int64)
        for i, g in enumerate(g_all):
            for b in g.bones:
                self.bone_group[names.index(b)] = i
        self._head_a = np.array([g.head.a for g in g_all])
        self._head_b = np.array([g.head.b for g in g_all])
        self._head_t = np.array([g.head.alpha for g in g_all])
        tracked = [i for i, g in enumerate(g_all) if g.tip is not None]
        self._tracked = np.array(tracked, dtype=np.int64)
        self._tip_a = np.array([g_all[i].tip.a for i in tracked], dtype=np.int64)
        self._tip_b = np.array([g_all[i].tip.b for i in tracked], dtype=np.int64)
        self._tip_t = np.array([g_all[i].tip.alpha for i in tracked])
        self._ref = np.array([g.ref for g in g_all])
        self._at_tip = np.array([g.at_tip for g in g_all])
        self._rig_origin = np.array([g.rig_tip if g.at_tip else g.rig_head for g in g_all])
        self.rig_len = np.array([np.linalg.norm(g.rig_tip - g.rig_head) for g in g_all])
        # the rig's own segment frames, by the same recipes on its rest pose
        a = self.asset
        rig_pts = {k: a.heads[a.bone(b)][None] for k, b in _FRAME_JOINTS.items()}
        rig_d = np.array([g.rig_tip - g.rig_head for g in g_all])[None]
        if self.eyes is not None:
            rig_pts |= {
                "eye_L": a.eyes[0][None],
                "eye_R": a.eyes[1][None],
                "head": a.heads[a.bone("Head")][None],
            }
        self._calib, self._rig_arm, self._turn = {}, {}, {}
        self.frames_rig = self._frames(rig_pts, rig_d, None, {}, rig=True)[0]  # (G, 3, 3)
        # calibrated groups: the constant X of R_joint X, from the clip's frames
        sk_pts, sk_d, fingers = self._inputs(pos_sample)
        parent = self._frames(sk_pts, sk_d, rot_sample, fingers, calibrating=True)
        for i, g in enumerate(g_all):
            if g.recipe[0] == "calibrated":
                p = g.recipe[1]
                want = parent[:, p] @ (self.frames_rig[p].T @ self.frames_rig[i])  # (S, 3, 3)
                self._calib[i] = mean_rotation(np.swapaxes(rot_sample[:, g.ref], -1, -2) @ want)
            elif g.recipe[0] in TURNED:
                # Joints say a segment's line, not always where it sits about it: the
                # head → eyes direction depends on where a rig puts its head joint
                # (CC_Base's 9 cm below the eyes, at the skull's base; the rig's 3 cm:
                # the head looked 30° up), the clavicle's on where its inner joint is
                # (CMU's 7 cm below the shoulders: the rig's clavicle raised 22-36°, a
                # shrug that peaked the shoulders). That turn (the head's nod about the
                # eye line, the clavicle's lift about the front axis) is taken, relative
                # to the chest, as the rig's in the clip's median pose; per frame the
                # skeleton's own turn adds on.
                axis, c = TURNED[g.recipe[0]], self._spine1
                rel = np.swapaxes(parent[:, c], -1, -2) @ parent[:, i]  # (S, 3, 3)
                q = np.swapaxes(rel, -1, -2) @ (self.frames_rig[c].T @ self.frames_rig[i])
                u, v = [k for k in range(3) if k != axis][:: -1 if axis == 1 else 1]
                self._turn[i] = axis_rotation(
                    axis, float(np.median(np.arctan2(q[:, v, u], q[:, u, u])))
                )

    def _inputs(self, positions, heads_tips=None):
        """Skeleton points, group directions (tip - head) and finger directions for the
        segment frames of poses ``positions`` (F, J, 3); ``heads_tips``: their
        :meth:`_heads_tips` when the caller has them."""
        lm = self.landmarks
        pts = {k: positions[:, lm[k]] for k in _FRAME_JOINTS}
        if self.eyes is not None:
            pts |= {
                "eye_L": positions[:, self.eyes[0]],
                "eye_R": positions[:, self.eyes[1]],
                "head": positions[:, lm["head"]],
            }
        h, tip = self._heads_tips(positions) if heads_tips is None else heads_tips
        d = np.zeros(h.shape)
        d[:, self._tracked] = tip - h[:, self._tracked]
        fingers = {}
        for i, g in enumerate(self.groups):
            if len(g.recipe) > 2 and g.recipe[0] == "calibrated" and g.recipe[2]:
                fingers[i] = positions[:, list(g.recipe[2])].mean(axis=1) - positions[:, g.head.a]
        return pts, d, fingers

    def _heads_tips(self, positions):
        t = self._head_t[None, :, None]
        h = (1 - t) * positions[:, self._head_a] + t * positions[:, self._head_b]  # (F, G, 3)
        tt = self._tip_t[None, :, None]
        tip = (1 - tt) * positions[:, self._tip_a] + tt * positions[:, self._tip_b]
        # the rig's spine curve about the chord (see _spine_offsets)
        _, chord = self._chord(positions)
        h = h + self._off_head @ np.swapaxes(chord, -1, -2)  # chord @ offset per group
        tip = tip + self._off_tip[self._tracked] @ np.swapaxes(chord, -1, -2)
        lm = self.landmarks
        for s, (foot, toes, drop) in self._drop.items():  # the ball (_ball_drops)
            ankle = positions[:, lm[f"ankle_{s}"]]
            along = unit(positions[:, lm[f"toe_{s}"]] - ankle)
            shank = ankle - positions[:, lm[f"knee_{s}"]]
            down = unit(shank - along * np.sum(shank * along, axis=-1, keepdims=True))
            tip[:, np.flatnonzero(self._tracked == foot)[0]] += drop * down
            h[:, toes] += drop * down  # the toes start there
        return h, tip

    def _frames(self, pts, d, rotations, fingers, *, rig=False, calibrating=False):
        """Every group's segment frame (F, G, 3, 3) by its recipe (see
        :mod:`snapcore.render.segments`); ``rig``: the rig's rest pose (calibrated
        groups take an arbitrary frame about their axis, the one their X refers to)."""
        g_all = self.groups
        f = d.shape[0]
        out = np.zeros((f, len(g_all), 3, 3))
        lat_p = pts["hip_L"] - pts["hip_R"]
        lat_c = pts["shoulder_L"] - pts["shoulder_R"]
        front_p = cross(lat_p, d[:, 0])
        front_c = cross(lat_c, d[:, self._spine1])
        done = np.zeros(len(g_all), bool)
        # the torso first (the arms' stand-in hinge is carried by the chest), each
        # recipe's groups in one call (frame_x and frame_z work point by point)
        ulat_p, ulat_c = unit(lat_p), unit(lat_c)
        refs = {"neck": lat_c, "hipjoint": front_p, "clavicle": front_c}
        for frame, kinds in ((frame_x, ("torso", "neck")), (frame_z, ("hipjoint", "clavicle"))):
            idx = [i for i, g in enumerate(g_all) if g.recipe[0] in kinds]
            r = [  # a torso group's blend of the hip and shoulder lines (its recipe's u)
                refs[k[0]] if k[0] in refs else (1 - k[1]) * ulat_p + k[1] * ulat_c
                for k in (g_all[i].recipe for i in idx)
            ]
            if idx:
                out[:, idx], done[idx] = frame(d[:, idx], np.stack(r, axis=1)), True
        # the limbs' hinges, both arms and both legs in one call (hinge works point by
        # point): arms (L, R), then legs (L, R)
        sides = list(SIDES)
        upper = np.stack([pts[f"elbow_{s}"] - pts[f"shoulder_{s}"] for s in sides], axis=1)
        fore = np.stack([pts[f"wrist_{s}"] - pts[f"elbow_{s}"] for s in sides], axis=1)
        if rig:
            stand = cross(upper, fore)  # the rig's arm is bent (40°): its own plane
        else:
            # rig → skeleton, as the chest turns
            rel = (out[:, self._spine1] @ self.frames_rig[self._spine1].T)[:, None]
            a_up = (rel @ np.stack([self._rig_arm[s][0] for s in sides])[..., None])[..., 0]
            b = rel @ np.stack([self._rig_arm[s][1] for s in sides])[..., None]
            stand = (swing_matrices(a_up, upper) @ b)[..., 0]
        thigh = np.stack([pts[f"knee_{s}"] - pts[f"hip_{s}"] for s in sides], axis=1)
        shank = np.stack([pts[f"ankle_{s}"] - pts[f"knee_{s}"] for s in sides], axis=1)
        feet = [[g.bones[0] for g in g_all].index(f"{SIDES[s]}Foot") for s in sides]
        foot = [d[:, i] if i in self._tracked else front_p for i in feet]
        axes = hinge(
            np.concatenate([upper, thigh], axis=1),
            np.concatenate([fore, shank], axis=1),
            np.concatenate([stand, cross(np.stack(foot, axis=1), thigh)], axis=1),
        )
        hinges = {}
        for n, s in enumerate(sides):
            hinges["arm", s], hinges["leg", s] = axes[:, n], axes[:, 2 + n]
            if rig:
                self._rig_arm[s] = (unit(upper[0, n]), axes[0, n])
        # the limbs' frames in one call (frame_x works point by point: the same values)
        limb = [(i, g.recipe) for i, g in enumerate(g_all) if g.recipe[0] in ("arm", "leg")]
        if limb:
            idx = [i for i, _ in limb]
            dirs = d[:, [r[2] if len(r) > 2 else i for i, r in limb]]
            out[:, idx] = frame_x(dirs, np.stack([hinges[r[0], r[1]] for _, r in limb], 1))
            done[idx] = True
        for i, g in enumerate(g_all):
            kind = g.recipe[0]
            if kind == "eyes":
                out[:, i] = frame_z(
                    unit(pts["eye_L"] - pts["eye_R"]),
                    0.5 * (pts["eye_L"] + pts["eye_R"]) - pts["head"],
                )
                # the frame above has the eye line as y: turn it so x is the eye line
                out[:, i] = out[:, i][..., [1, 2, 0]]
            elif kind == "calibrated":
                if rig or calibrating:
                    out[:, i] = rest_frame(g.rig_tip - g.rig_head)
                    continue
                fr = rotations[:, g.ref] @ self._calib[i]
                target = d[:, i] if i in self._tracked else fingers.get(i)
                if target is not None:  # the axis onto the top of the head / the fingers
                    fr = swing_matrices(fr[..., 1], target) @ fr
                out[:, i] = fr
        if not (rig or calibrating):
            for i, turn in self._turn.items():  # the rig's turn about the line (_calibrate)
                out[:, i] = out[:, i] @ turn
        return out

    @staticmethod
    def _point(pos: np.ndarray, p: Point) -> np.ndarray:
        return (1.0 - p.alpha) * pos[:, p.a] + p.alpha * pos[:, p.b]

    # ---- posing
    def group_matrices(
        self, positions: np.ndarray, rotations: np.ndarray, *, stretch: bool = False
    ):
        """Each group's transform (rig rest space → world) for poses: (F, G, 3, 4).

        Parameters
        ----------
        positions : ndarray of shape (F, J, 3)
            World joint positions, metres.
        rotations : ndarray of shape (F, J, 3, 3)
            World joint rotations (read only for the segments whose twist positions
            cannot show: see :mod:`snapcore.render.segments`).
        stretch : bool
            Also return ``(k - s) · axis`` (F, G, 3), per group: what
            :meth:`skin_points` adds, times a point's distance beyond the bone's ends,
            so only the bone's own span stretches by ``s`` (see :meth:`stretch_weights`).
        """
        m, st, _ = self._posed(positions, rotations)
        if stretch:
            return m, st
        return m

    def _posed(self, positions, rotations):
        """:meth:`group_matrices`, stretch term and each matrix's rotation (F, G, 3, 3): a
        matrix is W A^T · A D A^T (D > 0), so W A^T is its polar factor (the skin's)."""
        m, st, rot = self._unplanted(positions, rotations)
        return self._planted(m, st, positions, rot), st, rot

    def _unplanted(self, positions, rotations):
        """Group matrices before foot planting (F, G, 3, 4), the stretch term (F, G, 3)
        of :meth:`group_matrices` and the matrices' rotations (F, G, 3, 3)."""
        h, tip = self._heads_tips(positions)
        pts, d, fingers = self._inputs(positions, (h, tip))
        fr = self._frames(pts, d, rotations, fingers)
        # segment frame on the skeleton, times the rig's inverse: rig axes → world axes
        # (the rig frames are also the axes the lengths scale along: W A = F_skeleton)
        w = fr
        f, g = h.shape[:2]
        length = np.full((f, g), self.k)
        if self._tracked.size:
            dist = norm(d[:, self._tracked])
            ok = dist > 1e-9
            length[:, self._tracked] = np.where(ok, dist / self.rig_len[self._tracked], self.k)
            if self._at_tip.any():  # anchored at the tip: rig length, placed from the tip
                at = self._at_tip[self._tracked]
                h = h.copy()
                h[:, self._tracked[at]] = tip[:, at]
                length[:, self._tracked[at]] = self.k
        scale = np.stack(
            [np.full((f, g), self.k), length, np.broadcast_to(self.k * self.sole_scale, (f, g))],
            axis=-1,
        )
        # W D A^T and W A^T, as sums over the three axes (NumPy's matmul of 3 x 3
        # stacks cost 3-5 times as much)
        a = self.frames_rig  # (G, 3, 3): A, its rows A^T's columns
        ws = w * scale[..., None, :]  # W D
        rot, lin = (sum(x[..., :, c, None] * a[:, None, :, c] for c in range(3)) for x in (w, ws))
        o = self._rig_origin
        trans = h - sum(lin[..., c] * o[:, c, None] for c in range(3))
        st = (self.k - length)[..., None] * w[..., 1]
        return np.concatenate([lin, trans[..., None]], axis=-1), st, rot

    def stretch_weights(self, points: np.ndarray, weights):
        """Sparse (P, B): skin weight × how far each point lies beyond its bone's span.

        A bone stretched by ``s`` along its axis would carry points below its head (or
        past its tail) out by ``s`` times their distance too — a neck twice the rig's
        length would push the skin of the shoulders 10 cm up its axis. Along the axis
        only the span [head, tail] stretches; beyond it, the distance ``c`` (negative
        below the head) scales by ``k`` like the girth: ``x' = M x + (k - s) c axis``.
        """
        from scipy import sparse

        w = sparse.csr_matrix(weights)
        rows = np.repeat(np.arange(w.shape[0]), np.diff(w.indptr))
        g = self.bone_group[w.indices]
        u = np.einsum(
            "ni,ni->n",
            self.frames_rig[g][:, :, 1],
            np.asarray(points, float)[rows] - self._rig_origin[g],
        )
        c = np.minimum(u, 0.0) + np.maximum(u - self.rig_len[g], 0.0)
        c[self._at_tip[g]] = 0.0  # anchored groups do not stretch
        return sparse.csr_matrix((w.data * c, w.indices, w.indptr), shape=w.shape)

    def skin_points(
        self, points, weights, stretch_w, positions, rotations, *, dtype=np.float64, plan=None
    ) -> np.ndarray:
        """Rig-space ``points`` (P, 3) skinned to poses (F, J, 3) / (F, J, 3, 3): (F, P, 3).

        Dual-quaternion skinning (:func:`dq_skin`) plus the stretch correction of
        :meth:`stretch_weights`, in one kernel (the stretch terms are its ``shifts``);
        frames in chunks to bound the memory of the bones' tables. ``plan``:
        :meth:`skin_plan` of the same points and weights (made here when None).
        """
        if plan is None:
            plan = self.skin_plan(points, weights, stretch_w, dtype=dtype)
        f = positions.shape[0]
        out = np.empty((f, len(points), 3), dtype=plan.dtype)
        dropped, drop_w = self._drop_weights(points, weights)
        for a in range(0, f, SKIN_FRAMES):
            b = min(f, a + SKIN_FRAMES)
            m, st, rot = self._posed(positions[a:b], rotations[a:b])
            g = self.bone_group
            dq_skin_planned(
                plan, m[:, g], self.asset.heads, st[:, g], out=out[a:b], rotations=rot[:, g]
            )
            if dropped.size:
                drops = self._shoulder_drops(positions[a:b])  # (chunk, 2, 3)
                out[a:b, dropped] += np.einsum("ps,fsi->fpi", drop_w, drops).astype(out.dtype)
        return out

    def _drop_weights(self, points, weights) -> tuple[np.ndarray, np.ndarray]:
        """The points the shoulder drop moves (D,) and their masks (D, 2): only they take
        it. Fixed by the rest points and weights, so kept for the last ones asked (a
        still poses one frame per call, where the masks cost as much as the skinning)."""
        # kept per process, not per body: the mesh's points and weights are the cached
        # asset's own arrays, the same objects for every body of every scene (held here,
        # so an entry's objects stay alive and their ids are not reused)
        for c in list(_DROPS):
            if c[0] is self.asset and c[1] is points and c[2] is weights:
                return c[3], c[4]
        w = shoulder_masks(self.asset, points, weights)  # (P, 2)
        keep = np.flatnonzero(np.any(w != 0, axis=1))
        _DROPS.insert(0, (self.asset, points, weights, keep, w[keep]))
        del _DROPS[_DROPS_KEPT:]
        return keep, w[keep]

    def _shoulder_drops(self, positions) -> np.ndarray:
        """The top of each shoulder's drop as the arm hangs (F, 2, 3): see
        :mod:`snapcore.render.shoulders`."""
        lm = self.landmarks
        up = self._point(positions, self.neck_base) - positions[:, lm["pelvis"]]
        shoulders, elbows = (
            positions[:, [lm[f"{j}_L"], lm[f"{j}_R"]]] for j in ("shoulder", "elbow")
        )
        return shoulder_drops(shoulders, elbows, up, self._rig_elevation, self.k)

    def skin_plan(self, points, weights, stretch_w, *, dtype=np.float64):
        """The :func:`~snapcore.motion.dq_kernel.dq_plan` of :meth:`skin_points`:
        ``points`` (P, 3) with ``weights`` (P, B) and ``stretch_w`` (P, B)."""
        linear = np.asarray(weights @ self._linear_bones).ravel()
        return dq_plan(points, weights, linear, shift_weights=stretch_w, dtype=dtype)


class HumanBody(FrameBlocks):
    """The human mesh on one character, posable at any frame (like ``CharacterBody``).

    Parameters
    ----------
    character : Character
    color : tuple of 3 floats
        Base RGB in 0-1; left limbs lighter, right limbs darker.
    detail : {"full", "reduced"}
        The mesh drawn (:func:`snapcore.render.human_asset.human_asset`): the reduced one
        is for videos.
    ground : float, optional
        The floor's height (metres; the scene's), where the soles stand; default
        inferred from the character's joints as scenes do.

    Raises
    ------
    RetargetError
        The skeleton lacks a required joint.
    """

    kind = "human"

    def __init__(
        self,
        character,
        *,
        color=(0.306, 0.475, 0.655),
        detail: str = "full",
        ground: float | None = None,
    ):
        self.character = character
        self.detail = detail
        self._plans: dict = {}
        self.asset = asset = human_asset(detail)
        self.retarget = Retarget(character, asset, ground=ground)
        self.faces = asset.faces
        self.vertex_rgb, self.face_colors = body_colours(asset, color)

    @property
    def n_vertices(self) -> int:
        return int(self.asset.vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    @cached_property
    def _stretch(self):
        return self.retarget.stretch_weights(self.asset.vertices, self.asset.weights)

    def _plan(self, dtype):
        """The skinning plan of the mesh in ``dtype`` (made once per dtype)."""
        key = np.dtype(dtype).name
        if key not in self._plans:
            a = self.asset
            self._plans[key] = self.retarget.skin_plan(
                a.vertices, a.weights, self._stretch, dtype=dtype
            )
        return self._plans[key]

    def skin(self, positions: np.ndarray, rotations: np.ndarray, *, dtype=np.float64) -> np.ndarray:
        """Skinned vertices for poses given as arrays: (F, J, 3), (F, J, 3, 3) → (F, V, 3).

        ``dtype=np.float32`` is what drawing uses (:meth:`vertices`): half the memory
        traffic, errors below 1e-6 m.
        """
        return self.retarget.skin_points(
            self.asset.vertices,
            self.asset.weights,
            self._stretch,
            positions,
            rotations,
            plan=self._plan(dtype),
        )

    def _pose(self, frames: np.ndarray) -> np.ndarray:
        c = self.character
        return self.skin(c.positions[frames], c.rotations[frames], dtype=DRAW_DTYPE)

    def landmarks(self, frames=None) -> tuple[list[str], np.ndarray, np.ndarray]:
        """The rig's joints after skinning, beside the skeleton's joints they stand for.

        Each landmark is its rig bone's head (:data:`LANDMARK_BONES`), skinned with the
        weights of the surface around it (:func:`landmark_weights`) — where the body
        puts the joint, not where the retargeting aims it.

        Returns
        -------
        names : list of str
            Landmark names (``pelvis``, ``knee_L``...).
        body : ndarray of shape (F, L, 3)
            Skinned landmark positions, metres.
        skeleton : ndarray of shape (F, L, 3)
            The skeleton's joints, metres; for ``neck``, the point of the skeleton's
            pelvis → head chain where the body's neck starts (:attr:`Retarget.neck_base`:
            skeletons' own "neck" joints sit anywhere from mid-chest to the neck).
        """
        c = self.character
        frames = np.arange(c.n_frames) if frames is None else np.asarray(frames)
        names = list(LANDMARK_BONES)
        a = self.asset
        pts = np.array([a.heads[a.bone(LANDMARK_BONES[n])] for n in names])
        w = landmark_weights(a, pts)
        body = self.retarget.skin_points(
            pts, w, self.retarget.stretch_weights(pts, w), c.positions[frames], c.rotations[frames]
        )
        pos = c.positions[frames]
        r = self.retarget
        skel = np.stack(
            [r._point(pos, r.neck_base) if n == "neck" else pos[:, r.landmarks[n]] for n in names],
            axis=1,
        )
        return names, body, skel
