"""Scenes of animated characters: the data every other module reads.

A :class:`Scene` is one or more :class:`Character` objects sharing a world frame (metres,
Y up) and a frame rate. Each character holds its skeleton and the result of forward
kinematics for all frames, computed once at construction:

- ``positions`` ``(F, J, 3)`` world joint positions in metres,
- ``rotations`` ``(F, J, 3, 3)`` world joint rotations,
- ``local_rotations`` ``(F, J, 3, 3)`` rotations relative to the parent,
- ``local_quaternions`` ``(F, J, 4)`` the same as unit quaternions (what FK computes;
  pose selection measures rotation changes on these: four numbers per joint, not nine).

Joints include BVH end sites (flag ``end_site``) because they carry the length of the
last link of each chain (hands, feet, head).

Units
-----
A BVH file's unit is whatever its exporter chose (CMU cgspeed ~0.0564 m, Daz-style cm,
rescaled salsa files ~1.25 m). :func:`infer_scale` sizes a scene by its people: it
estimates each character's stature from its thigh + shank length (Drillis & Contini
1966: thigh 0.245 H, shank 0.246 H of stature H) and snaps to the known unit that makes
that stature a plausible adult one; if no known unit does, it scales the scene so the
mean stature is 1.70 m and warns. Characters loaded together share one scale, so two
people captured in one world frame keep their distances (hands that touch still touch).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from functools import cached_property

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import SceneError
from snapcore.motion.anatomy import REFERENCE_STATURE_M, body_landmarks, joint_roles, joint_sides
from snapcore.motion.bvh import BVHDocument
from snapcore.motion.kinematics import (
    channel_layout,
    forward_kinematics_rows,
    local_rows,
    matrix_to_quat,
    quat_mul,
    rest_positions,
    rows_to_matrix,
)
from snapcore.motion.skinning import SkinnedMesh

__all__ = [
    "Skeleton",
    "Character",
    "Scene",
    "character_from_bvh",
    "infer_scale",
    "stature_units",
    "stands_along_z",
    "Z_UP_TO_Y_UP",
    "yaw_matrix",
    "KNOWN_UNITS",
    "TPOSE_SPEED",
    "tpose_lead_in",
]

#: Units a BVH file plausibly uses, metres per file unit. Scale inference snaps to one.
KNOWN_UNITS = {
    "m": 1.0,
    "cm": 0.01,
    "mm": 0.001,
    "inch": 0.0254,
    "cmu": 0.056444,  # CMU cgspeed conversions: (1/0.45) inch per unit
    "dm": 0.1,
}
#: Adult statures (m) accepted when snapping to a known unit.
PLAUSIBLE_STATURE_M = (1.45, 2.10)
#: Thigh + shank as a fraction of stature (Drillis & Contini 1966: 0.245 + 0.246).
LEG_FRACTION = 0.491
#: Root-relative joint speed (m/s) above which leading frames are an added T-pose or
#: the blend out of it (see :func:`tpose_lead_in`). Real clips in ../shared/motions
#: start below 8 m/s; the blends run at 12-80 m/s.
TPOSE_SPEED = 10.0


def yaw_matrix(degrees: float) -> np.ndarray:
    """Rotation about +Y by ``degrees`` (counter-clockwise seen from above), shape (3, 3)."""
    a = math.radians(degrees)
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


@dataclass(frozen=True, eq=False)
class Skeleton:
    """Joint hierarchy of one character.

    Attributes
    ----------
    names : tuple of str, length J
    parents : ndarray of int, shape (J,)
        ``-1`` for the root; parents precede children.
    offsets : ndarray of float, shape (J, 3)
        Rest offsets in metres.
    end_site : ndarray of bool, shape (J,)
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    end_site: np.ndarray

    @property
    def n_joints(self) -> int:
        return len(self.names)

    def index(self, name: str) -> int:
        """Index of the joint called ``name`` (exact match)."""
        try:
            return self.names.index(name)
        except ValueError:
            raise SceneError(f"no joint named '{name}'") from None

    @cached_property
    def children(self) -> tuple[tuple[int, ...], ...]:
        """Children of each joint, length J."""
        kids: list[list[int]] = [[] for _ in self.names]
        for j, p in enumerate(self.parents):
            if p >= 0:
                kids[p].append(j)
        return tuple(tuple(k) for k in kids)

    @cached_property
    def roles(self) -> tuple[str, ...]:
        """Anatomical role of each joint, length J (``"pelvis"``, ``"thigh"``, ``"foot"``,
        ``"hand"``, ``"hidden"``...): :func:`snapcore.motion.anatomy.joint_roles` of the
        names and parents, computed once per skeleton."""
        return tuple(joint_roles(self.names, self.parents))

    @cached_property
    def sides(self) -> tuple[str, ...]:
        """Side of each joint read from its name, length J: ``"L"``, ``"R"`` or ``""``
        (:func:`snapcore.motion.anatomy.joint_sides`), computed once per skeleton."""
        return tuple(joint_sides(self.names))

    @cached_property
    def links(self) -> np.ndarray:
        """Bones as (parent, child) joint pairs with non-zero rest length, shape (L, 2)."""
        j = np.flatnonzero((self.parents >= 0) & (np.linalg.norm(self.offsets, axis=1) > 1e-9))
        return np.stack([self.parents[j], j], axis=1)


@dataclass(eq=False)
class Character:
    """One animated skeleton in world space.

    Attributes
    ----------
    name : str
    skeleton : Skeleton
    positions : ndarray of shape (F, J, 3)
        World joint positions, metres.
    rotations : ndarray of shape (F, J, 3, 3)
        World joint rotations.
    local_rotations : ndarray of shape (F, J, 3, 3)
        Joint rotations relative to the parent (for a root: relative to the world).
    fps : float
        Frames per second.
    scale : float
        Metres per unit of the source file.
    source : BVHDocument or None
        The file content this character was built from (file units), for writing back.
    local_quaternions : ndarray of shape (F, J, 4) or None
        ``local_rotations`` as unit quaternions ``(w, x, y, z)``, when the builder has
        them (FK does); None otherwise (:func:`snapcore.select.paper.local_information` then
        converts the matrices).
    mesh : SkinnedMesh or None
        The character's own skinned mesh (a glTF character,
        :func:`snapcore.motion.gltf.read_gltf`), posed by its joints; None for a
        skeleton (BVH), which the renderer dresses itself. Copies (``transformed``,
        ``rescaled``, ``frames``) share it.
    """

    name: str
    skeleton: Skeleton
    positions: np.ndarray
    rotations: np.ndarray
    local_rotations: np.ndarray
    fps: float
    scale: float = 1.0
    source: BVHDocument | None = None
    meta: dict = field(default_factory=dict)
    local_quaternions: np.ndarray | None = field(default=None, repr=False)
    mesh: SkinnedMesh | None = field(default=None, repr=False)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return self.skeleton.names

    @property
    def parents(self) -> np.ndarray:
        return self.skeleton.parents

    @property
    def n_frames(self) -> int:
        return int(self.positions.shape[0])

    @property
    def n_joints(self) -> int:
        return int(self.positions.shape[1])

    @cached_property
    def height(self) -> float:
        """Estimated standing height (stature) in metres; see :func:`stature_units`."""
        return stature_units(self.skeleton, self.positions)

    def transformed(
        self,
        *,
        yaw_deg: float = 0.0,
        offset: ArrayLike = (0.0, 0.0, 0.0),
        rotation: np.ndarray | None = None,
    ) -> Character:
        """A copy rotated about +Y by ``yaw_deg`` (or by the 3×3 ``rotation``) then
        translated by ``offset`` (metres)."""
        r = yaw_matrix(yaw_deg) if rotation is None else np.asarray(rotation, dtype=float)
        off = np.asarray(offset, dtype=float)
        return Character(
            name=self.name,
            skeleton=self.skeleton,
            positions=self.positions @ r.T + off,
            rotations=r @ self.rotations,
            local_rotations=_rotate_roots(self.local_rotations, self.parents, r),
            fps=self.fps,
            scale=self.scale,
            source=self.source,
            meta=dict(self.meta),
            local_quaternions=(
                None
                if self.local_quaternions is None
                else _rotate_root_quaternions(
                    self.local_quaternions,
                    self.parents,
                    _yaw_quaternion(yaw_deg) if rotation is None else matrix_to_quat(r),
                )
            ),
            mesh=self.mesh,
        )

    def rescaled(self, scale: float) -> Character:
        """A copy whose source unit is ``scale`` metres (positions and offsets rescaled)."""
        k = scale / self.scale
        return Character(
            name=self.name,
            skeleton=Skeleton(
                self.skeleton.names,
                self.skeleton.parents,
                self.skeleton.offsets * k,
                self.skeleton.end_site,
            ),
            positions=self.positions * k,
            rotations=self.rotations,
            local_rotations=self.local_rotations,
            fps=self.fps,
            scale=float(scale),
            source=self.source,
            meta=dict(self.meta),
            local_quaternions=self.local_quaternions,
            mesh=self.mesh,
        )

    def frames(self, start: int, stop: int) -> Character:
        """A copy holding frames ``start:stop`` only."""
        return Character(
            name=self.name,
            skeleton=self.skeleton,
            positions=self.positions[start:stop],
            rotations=self.rotations[start:stop],
            local_rotations=self.local_rotations[start:stop],
            fps=self.fps,
            scale=self.scale,
            source=self.source,
            meta=dict(self.meta),
            local_quaternions=(
                None if self.local_quaternions is None else self.local_quaternions[start:stop]
            ),
            mesh=self.mesh,
        )


def _rotate_roots(local_rot: np.ndarray, parents: ArrayLike, r: np.ndarray) -> np.ndarray:
    out = local_rot.copy()
    roots = np.flatnonzero(np.asarray(parents) < 0)
    out[:, roots] = r @ local_rot[:, roots]
    return out


def _yaw_quaternion(yaw_deg: float) -> np.ndarray:
    """The unit quaternion ``(w, x, y, z)`` of a turn by ``yaw_deg`` about +Y."""
    half = np.radians(yaw_deg) / 2.0
    return np.array([np.cos(half), 0.0, np.sin(half), 0.0])


def _rotate_root_quaternions(local_q: np.ndarray, parents: ArrayLike, q: ArrayLike) -> np.ndarray:
    """:func:`_rotate_roots` on quaternions: roots turned by the unit quaternion ``q``."""
    out = local_q.copy()
    roots = np.flatnonzero(np.asarray(parents) < 0)
    out[:, roots] = quat_mul(np.asarray(q, dtype=float), local_q[:, roots])
    return out


@dataclass(eq=False)
class Scene:
    """Characters sharing one world frame (metres, Y up) and one frame rate.

    Attributes
    ----------
    characters : list of Character
        All with the same number of frames and fps.
    fps : float
    ground : float
        Height of the ground plane (metres, world Y).
    name : str
    props : list of dict
        Static objects from the scene manifest (``type`` sphere/box/capsule, metres).
    frame_offset : int
        Source-file frame number of internal frame 0 (non-zero when an added T-pose
        frame or a manifest's ``frames`` range was cut). Report ``i + frame_offset``.
    """

    characters: list[Character]
    fps: float
    ground: float = 0.0
    name: str = "scene"
    props: list[dict] = field(default_factory=list)
    frame_offset: int = 0
    meta: dict = field(default_factory=dict)

    def __post_init__(self) -> None:
        if not self.characters:
            raise SceneError("a scene needs at least one character")
        counts = {c.n_frames for c in self.characters}
        if len(counts) != 1:
            raise SceneError(
                "characters have different frame counts "
                f"({', '.join(f'{c.name}: {c.n_frames}' for c in self.characters)})"
            )
        if not (np.isfinite(self.fps) and self.fps > 0):
            raise SceneError(f"fps must be a positive number, got {self.fps}")

    @property
    def n_frames(self) -> int:
        return self.characters[0].n_frames

    @property
    def duration(self) -> float:
        """Seconds from the first to the last frame."""
        return (self.n_frames - 1) / self.fps

    @property
    def n_characters(self) -> int:
        return len(self.characters)

    def bounds(self) -> np.ndarray:
        """Axis-aligned box of every joint over all frames, shape (2, 3), metres."""
        lo = np.min([c.positions.min(axis=(0, 1)) for c in self.characters], axis=0)
        hi = np.max([c.positions.max(axis=(0, 1)) for c in self.characters], axis=0)
        return np.stack([lo, hi])

    def source_frame(self, i: ArrayLike) -> np.ndarray:
        """Source-file frame number of internal frame(s) ``i``."""
        return np.asarray(i) + self.frame_offset

    def internal_frame(self, source_frame: int) -> int:
        """Internal index of source-file frame ``source_frame``.

        Raises
        ------
        SceneError
            The frame is not in the scene: the message gives the source frames it keeps
            and, for a frame before them, why those were cut (``meta["cut"]``).
        """
        i = int(source_frame) - self.frame_offset
        if not 0 <= i < self.n_frames:
            first, last = self.frame_offset, self.frame_offset + self.n_frames - 1
            why = ""
            if i < 0 and self.meta.get("cut"):
                why = f"; frames before {first} were cut: {self.meta['cut']}"
            raise SceneError(
                f"frame {source_frame} is not in this scene, which keeps source "
                f"frames {first}..{last}{why}"
            )
        return i

    def transformed(
        self, *, yaw_deg: float = 0.0, offset: ArrayLike = (0.0, 0.0, 0.0), scale: float = 1.0
    ) -> Scene:
        """The whole scene rotated about +Y, scaled about the origin, then translated."""
        chars = []
        for c in self.characters:
            c2 = c.transformed(yaw_deg=yaw_deg)
            c2.positions = c2.positions * scale + np.asarray(offset, dtype=float)
            c2.skeleton = Skeleton(
                c.skeleton.names,
                c.skeleton.parents,
                c.skeleton.offsets * scale,
                c.skeleton.end_site,
            )
            c2.scale = c.scale * scale
            chars.append(c2)
        return Scene(
            characters=chars,
            fps=self.fps,
            ground=self.ground * scale + float(np.asarray(offset, dtype=float)[1]),
            name=self.name,
            props=[_transform_prop(p, yaw_matrix(yaw_deg), scale, offset) for p in self.props],
            frame_offset=self.frame_offset,
            meta=dict(self.meta),
        )

    def frames(self, start: int, stop: int) -> Scene:
        """The scene's internal frames ``start:stop`` (source numbering kept)."""
        start, stop, _ = slice(start, stop).indices(self.n_frames)
        if stop <= start:
            raise SceneError(f"frames {start}:{stop} of a {self.n_frames}-frame scene are empty")
        return replace(
            self,
            characters=[c.frames(start, stop) for c in self.characters],
            props=[dict(p) for p in self.props],
            frame_offset=self.frame_offset + start,
            meta=dict(self.meta),
        )


def _transform_prop(prop: dict, r: np.ndarray, scale: float, offset: ArrayLike) -> dict:
    """A prop moved like its scene: points rotated, scaled, translated; sizes scaled.

    Boxes stay axis-aligned (props are static and a yaw of a box is not modelled), so
    only their centre moves and their size scales; callers rotating boxed scenes by
    other than multiples of 90 degrees should re-declare them.
    """
    out = dict(prop)
    off = np.asarray(offset, dtype=float)
    for key in ("center", "a", "b"):
        if key in prop:
            out[key] = (r @ np.asarray(prop[key], dtype=float) * scale + off).tolist()
    if "radius" in prop:
        out["radius"] = float(prop["radius"]) * scale
    if "size" in prop:
        size = np.abs(r) @ np.asarray(prop["size"], dtype=float) * scale  # swaps x/z at 90°
        out["size"] = size.tolist()
    return out


# --------------------------------------------------------------------------- building


def character_from_bvh(
    doc: BVHDocument, *, scale: float, name: str | None = None, fps: float | None = None
) -> Character:
    """Run forward kinematics on a BVH document and return a :class:`Character`.

    Parameters
    ----------
    doc : BVHDocument
    scale : float
        Metres per file unit.
    name : str, optional
        Defaults to the file's stem.
    fps : float, optional
        Overrides the file's frame time (some headers are wrong).
    """
    if not (np.isfinite(scale) and scale > 0):
        raise SceneError(f"scale must be a positive number of metres per unit, got {scale}")
    # component-major (4, J, F) rows from the channels to the matrices: one transposed
    # copy each for the positions and the local quaternions (see local_rows)
    quat_local, trans_local = local_rows(channel_layout(doc.channels), doc.offsets, doc.motion)
    pos_rows, quat_world = forward_kinematics_rows(doc.parents, quat_local, trans_local)
    positions = np.empty(pos_rows.shape[::-1])
    np.multiply(pos_rows.transpose(2, 1, 0), scale, out=positions)  # metres, (F, J, 3)
    skeleton = Skeleton(
        names=doc.names,
        parents=doc.parents,
        offsets=doc.offsets * scale,
        end_site=doc.end_site,
    )
    if name is None:
        name = _stem(doc.path) if doc.path else "character"
    if not fps:
        # Headers round the frame time (".0083333"): 120.0048 fps is 120 fps.
        fps = doc.fps
        if abs(fps - round(fps)) < 1e-3 * fps:
            fps = float(round(fps))
    return Character(
        name=name,
        skeleton=skeleton,
        positions=positions,
        rotations=rows_to_matrix(quat_world),
        local_rotations=rows_to_matrix(quat_local),
        fps=float(fps),
        scale=float(scale),
        source=doc,
        local_quaternions=np.ascontiguousarray(quat_local.transpose(2, 1, 0)),
    )


def _stem(path: str) -> str:
    base = path.replace("\\", "/").rsplit("/", 1)[-1]
    return base.rsplit(".", 1)[0] if "." in base else base


def _leaf_paths(parents: np.ndarray) -> dict[int, list[int]]:
    """Joint path root→leaf for every leaf."""
    has_child = np.zeros(parents.size, dtype=bool)
    has_child[parents[parents >= 0]] = True
    paths = {}
    for leaf in np.flatnonzero(~has_child):
        path, j = [], int(leaf)
        while j >= 0:
            path.append(j)
            j = int(parents[j])
        paths[int(leaf)] = path[::-1]
    return paths


def stature_units(skeleton: Skeleton, positions: np.ndarray) -> float:
    """Estimated standing height in the units of ``positions``.

    The two legs are the root-to-leaf chains whose leaves sit lowest (median over
    frames); each leg's two longest bones are thigh and shank, and stature is their
    mean sum divided by :data:`LEG_FRACTION`. This ignores how the exporter placed the
    head end site (often well below the top of the skull) and works on any pose. For a
    skeleton without two distinguishable legs, the vertical extent of the median frame
    is returned instead.

    Parameters
    ----------
    skeleton : Skeleton
        Its offsets must be in the same unit as ``positions``.
    positions : ndarray of shape (F, J, 3)
    """
    parents = np.asarray(skeleton.parents)
    lengths = np.linalg.norm(skeleton.offsets, axis=1)
    height = np.median(positions[..., 1], axis=0)  # (J,)
    paths = _leaf_paths(parents)
    leaves = sorted(paths, key=lambda j: height[j])
    if len(leaves) >= 2:
        a, b = paths[leaves[0]], paths[leaves[1]]
        shared = 0  # joints both legs share (root .. pelvis): not leg bones
        while shared < min(len(a), len(b)) and a[shared] == b[shared]:
            shared += 1
        legs = []
        for path in (a, b):
            bones = np.sort(lengths[path[shared:]])[::-1]
            if bones.size >= 2 and bones[1] > 0:
                legs.append(bones[0] + bones[1])
        pelvis = height[a[max(shared - 1, 0)]]
        below = height[leaves[0]] < pelvis and height[leaves[1]] < pelvis
        if len(legs) == 2 and min(legs) > 0.5 * max(legs) and below:
            return float(np.mean(legs) / LEG_FRACTION)
    median_frame = positions[positions.shape[0] // 2]
    return float(np.ptp(median_frame[:, 1]))


#: Z up → Y up, ``(x, y, z) → (x, z, -y)``: a Z-up tool's forward (-Y) becomes +Z.
Z_UP_TO_Y_UP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def stands_along_z(skeleton: Skeleton, positions: np.ndarray) -> bool:
    """Whether a skeleton was written Z up (BVH is Y up by convention; a few tools write Z).

    Both must hold: its rest pose stands along +Z (pelvis → head within 37° of +Z, hip →
    ankle within 37° of -Z), and so does its motion (the median pelvis → head direction
    has z > 0.5, more than 30° above the horizon). The rest pose is what tells a
    Z-up file from a Y-up take of someone lying down: exporters write it standing in
    their own up axis. A skeleton without named pelvis, head and left leg is left as it is.

    Parameters
    ----------
    skeleton : Skeleton
    positions : ndarray of shape (F, J, 3)
        World joint positions in the file's axes.
    """
    lm = body_landmarks(skeleton.names, skeleton.parents)
    if any(lm[k] is None for k in ("pelvis", "head", "hip_L", "ankle_L")):
        return False
    rest = rest_positions(skeleton.parents, skeleton.offsets)

    def unit(v: np.ndarray) -> np.ndarray:
        n = np.linalg.norm(v, axis=-1, keepdims=True)
        return v / np.where(n > 0, n, 1.0)

    up = unit(rest[lm["head"]] - rest[lm["pelvis"]])
    leg = unit(rest[lm["ankle_L"]] - rest[lm["hip_L"]])
    moving = unit(np.median(unit(positions[:, lm["head"]] - positions[:, lm["pelvis"]]), axis=0))
    return bool(up[2] > 0.8 and leg[2] < -0.8 and moving[2] > 0.5)


def infer_scale(statures_units: Sequence[float] | np.ndarray) -> tuple[float, str]:
    """Metres per file unit for characters of the given statures (file units).

    Returns
    -------
    scale : float
        Metres per unit.
    how : str
        The unit's name from :data:`KNOWN_UNITS`, or ``"fitted"`` when none was
        plausible and the mean stature was set to :data:`REFERENCE_STATURE_M`.
    """
    s = float(np.mean(statures_units))
    if not (np.isfinite(s) and s > 0):
        raise SceneError("cannot infer the unit: the skeleton has no extent; pass a scale")
    best, best_err = None, np.inf
    lo, hi = PLAUSIBLE_STATURE_M
    for unit, metres in KNOWN_UNITS.items():
        h = s * metres
        err = abs(math.log(h / REFERENCE_STATURE_M))
        if lo <= h <= hi and err < best_err:
            best, best_err = unit, err
    if best is not None:
        return KNOWN_UNITS[best], best
    return REFERENCE_STATURE_M / s, "fitted"


def tpose_lead_in(positions: list[np.ndarray], fps: float) -> int:
    """Number of leading frames that are an added T-pose and the blend out of it.

    CMU cgspeed files start with one T-pose frame; the Daz-style conversions (soccer,
    salsa) blend from it over three or four frames; other exporters hold it for a while
    first. All move joints, relative to the pelvis, faster than a person can
    (:data:`TPOSE_SPEED`) out of it; real motion never starts that way. Frames are cut
    while any character's fastest root-relative joint exceeds that speed (at most half
    a second), after the frames that repeat the first one exactly (within 1 mm, at most
    two seconds) when that snap follows them: a person standing still and then moving
    at a human speed keeps every frame.

    Parameters
    ----------
    positions : list of ndarray of shape (F, J, 3)
        World positions in metres, one per character.
    fps : float

    Returns
    -------
    int
        Frames to drop from the start (0 if none).
    """
    cut = 0
    for x in positions:
        if x.shape[0] < 4:
            continue
        # Only the first 2.5 s can be cut: the rest of a long clip is not looked at.
        head = x[: int(2 * fps) + int(0.5 * fps) + 2]
        rel = head - head[:, :1]  # root-relative: a running root is not a glitch
        speed = np.linalg.norm(rel[1:] - rel[:-1], axis=2).max(axis=1) * fps  # (W-1,) m/s
        moved = np.linalg.norm(rel - rel[:1], axis=2).max(axis=1) > 1e-3  # (W,)
        held = min(int(np.argmax(moved)) if moved.any() else len(head) - 1, int(2 * fps))
        k = held - 1 if held > 1 and speed[held - 1] > TPOSE_SPEED else 0
        limit = min(k + int(0.5 * fps), x.shape[0] - 3)
        while k < limit and speed[k] > TPOSE_SPEED:
            k += 1
        cut = max(cut, k)
    return cut
