"""Soles on the floor: a retargeted body's foot depth and per-frame foot planting.

A skeleton puts its ankle joint at its own height inside the foot and its floor
contact drifts by a few centimetres over a clip (marker noise, feet sliding into the
floor, a foot pitched on its heel or toes), so a body that follows the joints alone
sinks into the floor or floats above it. :class:`SoleFit` holds the two corrections
the human body's retargeting (:class:`snapcore.render.human.Retarget`) makes: the foot's
depth scaled to the skeleton's standing ankle height (:meth:`SoleFit._sole_scale`), and
per frame each foot moved up or down onto the floor where it stands
(:meth:`SoleFit._plant_shifts`), as game engines plant feet after a retarget.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from snapcore.motion.dq_kernel import dq_plan, dq_skin_planned

__all__ = ["SoleFit", "SIDES", "PLANT_MAX_M"]

#: Side letters of the skeleton landmarks and the rig's bone-name prefixes.
SIDES = {"L": "Left", "R": "Right"}
#: Percentile of the ankle's height over frames taken as its standing height, and the
#: range of the foot's depth scale that puts the sole there (see SoleFit._sole_scale).
SOLE_PERCENTILE = 10.0
SOLE_SCALE_RANGE = (0.75, 1.35)
#: Foot planting (SoleFit._plant_shifts), metres: the largest shift of a foot (a foot pointed
#: on its toes puts the mesh's longer toes 6-8 cm under the floor on CMU 01_01 and
#: 05_06); the sole's height above the floor up to which it is put on the floor, and
#: from which it is left.
PLANT_MAX_M = 0.08
PLANT_FULL_M = 0.02
PLANT_FADE_M = 0.05
#: A foot whose ankle is within PLANT_ANKLE_FULL_M of its standing height (and whose
#: sole is within PLANT_REACH_M of the floor) stands: its sole is put on the floor; the
#: correction fades out by PLANT_ANKLE_FADE_M above the standing height.
PLANT_ANKLE_FULL_M = 0.02
PLANT_ANKLE_FADE_M = 0.04
PLANT_REACH_M = 0.08


#: The rig's sole points per (asset, side), kept: the same for every body of a process.
_SOLES: dict[tuple[int, str], tuple] = {}


def _sole_points(asset, side: str) -> tuple:
    """The rig's sole on one side (``"Left"``/``"Right"``), from the asset alone: its
    foot bones, the ankle's and the sole's heights (metres), the sole points (the foot
    vertices within 1.5 cm of its lowest, on their convex hull), their weights (sparse,
    all bones), the bones that carry them and the foot's share of each point."""
    hit = _SOLES.get((id(asset), side))
    if hit is not None and hit[0] is asset:  # the entry holds the asset: ids not reused
        return hit[1]
    from scipy import sparse
    from scipy.spatial import ConvexHull

    a = asset
    w = a.weights.toarray() if hasattr(a.weights, "toarray") else np.asarray(a.weights)
    bones = [a.bone(f"{side}Foot"), a.bone(f"{side}ToeBase")]
    foot_v = w[:, bones].sum(axis=1) > 0.5
    sole_y = a.vertices[foot_v, 1].min()
    # the sole: foot vertices within 1.5 cm of its lowest, with their skin weights (for
    # the per-frame contact in _plant_shifts)
    sole = np.flatnonzero(foot_v & (a.vertices[:, 1] < sole_y + 0.015))
    # the lowest point of a (nearly rigidly) moved point set is on its hull: ~1/5 of
    # the sole's points, the planting's cost with it
    sole = sole[ConvexHull(a.vertices[sole]).vertices]
    # only the bones that carry the sole: the planting skins a few hundred points with
    # a handful of matrices, not the whole rig's
    ws = sparse.csr_matrix(w[sole])
    cols = np.unique(ws.indices)
    out = (bones, a.heads[bones[0]][1], sole_y, sole, ws, cols, w[sole][:, bones].sum(axis=1))
    _SOLES[(id(asset), side)] = (asset, out)
    return out


class SoleFit:
    """Mixin of :class:`snapcore.render.human.Retarget`: it provides ``asset``, ``k``,
    ``ground``, ``landmarks``, ``groups``, ``bone_group``, :meth:`stretch_weights` and
    ``_unplanted`` (the group matrices before planting)."""

    asset: Any
    k: float
    ground: float
    landmarks: dict[str, Any]
    groups: list
    bone_group: np.ndarray
    _linear_bones: np.ndarray
    _sole_plan_memo: tuple | None = None

    def stretch_weights(self, points: np.ndarray, weights) -> Any:
        raise NotImplementedError

    def _unplanted(self, positions, rotations) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        raise NotImplementedError

    def _sole_scale(self, positions) -> np.ndarray:
        """Per group, the scale of its depth axis (z: the foot's top → sole) that puts
        the soles on the floor: (G,), 1 except for feet and toes.

        Skeletons put the ankle joint at different heights inside the foot (CMU's lower
        than the rig's x k: the soles sank 1.5-3 cm; Bandai's higher: they floated 1-3
        cm). Standing, the ankle is its height above the floor: the 10th percentile
        over frames of the ankle's height above the ground (the heel down in stance;
        frames in the air or on the toes are higher). The foot's depth below the ankle
        is scaled from the rig's (x k) to it, within [0.75, 1.35] (a foot no flatter or
        deeper than that; the rest is left to the per-frame planting, :meth:`_plant_shifts`).
        """
        a = self.asset
        out = np.ones(len(self.groups))
        self._soles = {}
        self._sole_plan_memo = None  # made from _soles on first use
        self._ankle_stand: dict[str, float] = {}
        for s, side in SIDES.items():
            bones, ankle_rig, sole_y, sole, ws, cols, share = _sole_points(a, side)
            depth = (ankle_rig - sole_y) * self.k  # rig: ankle over sole
            h = np.percentile(
                positions[:, self.landmarks[f"ankle_{s}"], 1] - self.ground, SOLE_PERCENTILE
            )
            scale = float(np.clip(h / depth, *SOLE_SCALE_RANGE)) if depth > 0 else 1.0
            groups = [
                i
                for i, g in enumerate(self.groups)
                if g.bones[0] in (f"{side}Foot", f"{side}ToeBase")
            ]
            out[groups] = scale
            self._ankle_stand[s] = self.ground + h
            self._soles[s] = (
                a.vertices[sole],
                ws[:, cols],
                self.stretch_weights(a.vertices[sole], ws)[:, cols],
                self.bone_group[cols],
                share,  # the foot's share of each point
                np.array(groups),
                self.asset.heads[cols],
                np.asarray(ws @ self._linear_bones).ravel(),
            )
        return out

    def _plant_shifts(
        self, m: np.ndarray, st: np.ndarray, positions: np.ndarray, rot: np.ndarray
    ) -> np.ndarray:
        """Foot planting, as game engines do after a retarget: how far to move each foot
        up or down (F, 2; left, right; metres) to put it on the floor where it is in
        contact, from the unplanted group matrices ``m`` (F, G, 3, 4), their stretch
        term ``st`` (F, G, 3), their rotations ``rot`` (F, G, 3, 3) and the poses
        ``positions`` (F, J, 3).

        A skeleton's own foot height varies in stance by 2-5 cm (marker noise, feet
        sliding into the floor, a foot pitched on its heel or toes), so no fixed foot
        keeps the soles on the floor. Per frame and foot, ``r`` = the lowest sole
        point's height above the floor. A sole below the floor is lifted onto it (by at
        most :data:`PLANT_MAX_M`). Above it, the foot is lowered onto the floor with a
        weight that is the larger of two cues of standing, both read from the pose:

        - the sole is low: weight 1 up to :data:`PLANT_FULL_M`, fading out by
          :data:`PLANT_FADE_M` (a foot lifting off rises from the floor, no jump);
        - the ankle is at its standing height (``positions``; the 10th percentile of
          the clip's ankle heights, see :meth:`_sole_scale`): weight 1 within
          :data:`PLANT_ANKLE_FULL_M` of it, fading out by :data:`PLANT_ANKLE_FADE_M`,
          for soles within :data:`PLANT_REACH_M` of the floor. A foot resting on its
          heel with the toes up, or a skeleton whose stance is a little higher in one
          step than another, keeps its ankle there while its sole hovers 1-4 cm up
          (measured on CMU and Bandai clips); a swinging foot's ankle is higher.

        The foot and toe groups move by the same vertical shift; the skin at the ankle
        blends it into the shank.
        """
        lm = self.landmarks
        out = np.zeros((m.shape[0], len(self._soles)))
        # the sole points as the skin will place them (blend and stretch): a point's
        # rigid move with one bone misses the shank's share at the heel; both feet in
        # one call (each its own bones: block-diagonal weights)
        plan, owners, centres, split = self._sole_plan()
        heights = dq_skin_planned(
            plan, m[:, owners], centres, st[:, owners], rotations=rot[:, owners]
        )[..., 1]
        for i, s in enumerate(self._soles):
            foot_share = self._soles[s][4]
            y = heights[:, split[i] : split[i + 1]]
            low_point = y.argmin(axis=1)
            r = y[np.arange(len(y)), low_point] - self.ground
            low = np.clip((PLANT_FADE_M - r) / (PLANT_FADE_M - PLANT_FULL_M), 0.0, 1.0)
            dh = positions[:, lm[f"ankle_{s}"], 1] - self._ankle_stand[s]
            standing = np.clip(
                (PLANT_ANKLE_FADE_M - dh) / (PLANT_ANKLE_FADE_M - PLANT_ANKLE_FULL_M), 0.0, 1.0
            ) * (r < PLANT_REACH_M)
            fade = np.maximum(low, standing)
            # the lowest point moves by its foot share of the shift
            shift = np.where(r < 0, -r, -r * fade) / foot_share[low_point]
            out[:, i] = np.clip(shift, -PLANT_MAX_M, PLANT_MAX_M)
        return out

    def _sole_plan(self) -> tuple[Any, np.ndarray, np.ndarray, np.ndarray]:
        """The skinning plan of both soles' points (made once), their bones' groups
        (B,), centres (B, 3) and where each foot's points start and end (feet + 1,)."""
        if self._sole_plan_memo is None:
            from scipy import sparse

            parts = list(self._soles.values())
            plan = dq_plan(
                np.concatenate([p[0] for p in parts]),
                sparse.block_diag([p[1] for p in parts], format="csr"),
                np.concatenate([p[7] for p in parts]),
                shift_weights=sparse.block_diag([p[2] for p in parts], format="csr"),
            )
            self._sole_plan_memo = (
                plan,
                np.concatenate([p[3] for p in parts]),
                np.concatenate([p[6] for p in parts]),
                np.cumsum([0] + [len(p[0]) for p in parts]),
            )
        return self._sole_plan_memo

    def _planted(
        self, m: np.ndarray, st: np.ndarray, positions: np.ndarray, rot: np.ndarray
    ) -> np.ndarray:
        """The group matrices ``m`` (F, G, 3, 4) with each foot and toe group moved by
        its :meth:`_plant_shifts` (in place; ``m`` is returned)."""
        shifts = self._plant_shifts(m, st, positions, rot)
        for s, (*_, groups, _, _) in enumerate(self._soles.values()):
            m[:, groups, 1, 3] += shifts[:, s, None]
        return m

    def foot_shifts(self, positions: np.ndarray, rotations: np.ndarray) -> np.ndarray:
        """How far foot planting moves each foot up (+) or down (-): (F, 2) metres,
        left then right, for poses (F, J, 3) / (F, J, 3, 3); see :meth:`_plant_shifts`.
        The body's ankles leave the skeleton's by this much, on purpose: the soles, not
        the joints, stand on the floor."""
        m, st, rot = self._unplanted(positions, rotations)
        return self._plant_shifts(m, st, positions, rot)
