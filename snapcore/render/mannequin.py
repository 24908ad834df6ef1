"""The mannequin: body meshes for skeletons without skin, a capsule per bone, spheres at joints.

Motion capture gives joints, not a body. This module dresses every character in a
mannequin built from rigid pieces, like the articulated models of the Action Snapshot
paper (3,191-6,412 faces per character):

- one capsule per bone (parent → child joint with non-zero rest length), elliptical in
  cross-section on the torso (wider left-right than front-back);
- a sphere at every joint: the capsule caps. Each capsule ends in a hemisphere centred
  on its joints, so where bones meet, the thickest bone's cap *is* the joint sphere
  (a separate sphere of the largest incident radius would lie exactly inside it and
  only cost faces);
- an ellipsoid head with a small nose (so the facing direction can be read), and a
  hand blob for skeletons without finger bones.

Radii come from the anatomy table (:data:`snapcore.motion.anatomy.ROLE_RADII`), indexed
by the *role* of the bone's parent joint, which
:func:`snapcore.motion.anatomy.joint_roles` reads from the joint names; every size is a
fraction of the character's stature.

Posing
------
Each piece is built once, in the local frame of the joint that carries it (the bone's
parent joint). Posing frame ``f`` is then a gather and one batched matrix product —
``x = R[f, joint] @ x_local + p[f, joint]`` for every vertex (normals rotate alike) —
with no mesh rebuilt per frame. Because a BVH child sits at ``p_parent + R_parent @
offset``, a bone's capsule built along the rest offset stays attached to both joints.

Orientation cues that BVH rest poses do not give reliably (which way is "left" in the
chest's frame, which way is "up" in the head's frame) are measured from the motion:
e.g. the left-minus-right hip vector expressed in the pelvis frame, averaged over frames.

Public API
----------
:class:`SceneBody` (posable merged mesh of all characters), :class:`CharacterBody`,
:class:`PosedMesh`, :func:`posed_mesh`, :func:`scene_trimesh`, :data:`CHARACTER_COLORS`.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from functools import cached_property, lru_cache

import numpy as np

from snapcore.errors import SceneError
from snapcore.motion.anatomy import (
    DEFAULT_ROLE,
    HIDDEN_ROLES,
    ROLE_RADII,
    TORSO_ROLES,
    bone_role,
    per_stature,
)

__all__ = [
    "SceneBody",
    "CharacterBody",
    "PosedMesh",
    "posed_mesh",
    "scene_trimesh",
    "scene_body",
    "CHARACTER_COLORS",
    "TESSELLATION",
    "TESSELLATION_COARSE",
    "TESSELLATION_FINE",
    "tessellation_for",
    "COARSE_MAX_PX",
]

# Sizes below are fractions of the stature (:func:`~snapcore.motion.anatomy.per_stature`).
#: Head ellipsoid semi-axes (lateral, front-back, vertical), and the height of its
#: centre above the head joint along the neck direction.
HEAD_SEMI_AXES = per_stature(0.080, 0.095, 0.112)
(HEAD_CENTRE_ABOVE,) = per_stature(0.085)
#: Nose: a small sphere on the front of the head, so facing can be read in a still.
(NOSE_RADIUS,) = per_stature(0.022)
#: Hand blob for skeletons whose hands have no bones (CMU cgspeed, Bandai): a sphere of
#: this radius centred this far beyond the wrist along the forearm.
HAND_BLOB_RADIUS, HAND_BLOB_BEYOND = per_stature(0.045, 0.045)
#: A hand whose bone lengths below the wrist sum to less than this gets a blob.
(HAND_BONES_MIN,) = per_stature(0.06)


#: Names of helper joints that are no bone of their own: twist and roll bones beside a
#: limb's, Reallusion's "share" bones at elbows and knees, breast and pectoral
#: (Reallusion CC_Base ``L_RibsTwist`` → ``L_Breast``) and corrective joints. Drawn as
#: bones they put blobs on the chest and lumps on the limbs.
HELPER_JOINT = re.compile(r"twist|roll(?!er)|share|breast|bust|pector|ribs|helper|corrective", re.I)


def helper_joints(names, parents) -> np.ndarray:
    """(J,) bool: joints named as helpers (:data:`HELPER_JOINT`) all of whose children
    are helpers or end sites too (so ``NeckTwist01``, with the head below it, stays)."""
    parents = np.asarray(parents)
    out = np.zeros(len(names), bool)
    for j in range(len(names) - 1, -1, -1):  # children come after parents: decided first
        kids = np.flatnonzero(parents == j)
        if HELPER_JOINT.search(str(names[j])) and all(
            out[c] or re.search(r"_end$", str(names[c]), re.I) for c in kids
        ):
            out[j] = True
    return out


def _by_radius(table):
    """Tessellation rows with radii measured on the reference figure → fractions of stature."""
    return tuple((per_stature(r)[0], t) for r, t in table)


#: Bones shorter than this (m) are not drawn (zero-length BVH links, rounding noise).
MIN_BONE_M = 1e-4
#: Tessellation (segments around, rings per cap) by radius (fraction of the stature): thick
#: pieces get more faces so silhouettes stay round. A capsule has 4·around·rings faces.
TESSELLATION = _by_radius(((0.08, (16, 4)), (0.035, (12, 3)), (0.018, (8, 2)), (0.0, (6, 1))))
#: Coarse tessellation for stand-ins whose facets never show (e.g. shadows on the floor).
TESSELLATION_COARSE = _by_radius(((0.08, (10, 2)), (0.035, (8, 2)), (0.018, (6, 1)), (0.0, (4, 1))))
#: Pictures at most this tall (pixels) draw the mannequin at :data:`TESSELLATION_COARSE`
#: (:func:`tessellation_for`): a batch's preview-strip panels (135 px). There the
#: figure stands at most ~125 px, its thickest piece (the trunk, ~0.08 of the stature
#: in radius) ~10 px: 10 segments around put the silhouette within 10 (1 - cos 18°) =
#: 0.5 px of the round one (16: 0.2 px). llvmpipe pays per triangle at this size
#: (4x multisampling or one sample cost the same): a 12-panel strip of one figure drew
#: in ~62 ms with the 4,192 triangles of :data:`TESSELLATION`, ~45 ms with 1,560.
COARSE_MAX_PX = 200
#: Fine tessellation for surfaces that are read as geometry, not as shaded pictures:
#: a relief carves the depth itself, where the flat facets of :data:`TESSELLATION`
#: would show as ridges in raking light (~5x the faces).
TESSELLATION_FINE = _by_radius(
    ((0.08, (40, 10)), (0.035, (28, 7)), (0.018, (16, 4)), (0.0, (10, 2)))
)

#: Base colours of characters 0, 1, 2... (RGB 0-1, Tableau 10): distinct for two people.
CHARACTER_COLORS = (
    (0.306, 0.475, 0.655),  # blue
    (0.949, 0.557, 0.169),  # orange
    (0.349, 0.631, 0.310),  # green
    (0.882, 0.341, 0.349),  # red
    (0.690, 0.478, 0.631),  # purple
    (0.612, 0.459, 0.373),  # brown
)
#: Left limbs are lightened, right limbs darkened, so left and right read apart.
LEFT_LIGHTEN = 0.22
RIGHT_DARKEN = 0.12

# --------------------------------------------------------------------------- geometry


@lru_cache(maxsize=64)
def _capsule_template(around: int, rings: int, ellipsoid: bool):
    """What every capsule of one tessellation shares: the rings' angles (cosines and
    sines, broadcastable), the top half's rows, and the faces. Read-only arrays.

    A library's scenes build their bodies' capsules thousands of times, from a handful
    of tessellations; only the lengths and radii differ."""
    bottom = np.linspace(-np.pi / 2, 0.0, rings + 1)[1:]  # rings up to the equator
    top = np.linspace(0.0, np.pi / 2, rings + 1)[:-1]  # equator up to below the pole
    if ellipsoid:
        top = top[1:]  # an ellipsoid has one equator, not two coincident ones
    phis = np.concatenate([bottom, top])
    is_top = np.concatenate([np.zeros(len(bottom)), np.ones(len(top))])
    theta = np.linspace(0.0, 2 * np.pi, around, endpoint=False)
    cp, sp = np.cos(phis)[:, None], np.sin(phis)[:, None]
    ct, st = np.cos(theta)[None, :], np.sin(theta)[None, :]
    n_rows = len(phis)
    pole = 1 + n_rows * around  # the top pole's vertex
    i = np.arange(around)
    i1 = (i + 1) % around
    lo = (1 + np.arange(n_rows - 1) * around)[:, None]  # each band's lower ring
    hi = lo + around
    band = np.stack(  # per band: the two triangles of each quad, in that order
        [
            np.stack([lo + i, lo + i1, hi + i1], axis=-1),
            np.stack([lo + i, hi + i1, hi + i], axis=-1),
        ],
        axis=1,
    ).reshape(-1, 3)
    last = 1 + (n_rows - 1) * around
    faces = np.vstack(
        [
            np.stack([np.zeros(around, int), 1 + i1, 1 + i], axis=1),  # bottom fan
            band,
            np.stack([last + i, last + i1, np.full(around, pole)], axis=1),  # top fan
        ]
    )
    parts = (cp, sp, ct, st, is_top, faces)
    for a in parts:
        a.flags.writeable = False
    return parts


def _capsule(length: float, a: float, b: float, c: float, around: int, rings: int):
    """Closed capsule along +z from 0 to ``length``: elliptical cross-section (a along x,
    b along y), half-ellipsoid caps of height c. ``length=0`` gives an ellipsoid.

    Returns vertices (n, 3), normals (n, 3), faces (m, 3) with outward normals and
    counter-clockwise faces; 4·around·rings faces (2·around fewer for an ellipsoid).
    The faces array is shared between capsules of one tessellation (read-only).
    """
    cp, sp, ct, st, is_top, faces = _capsule_template(around, rings, length <= 0)
    zoff = is_top * max(length, 0.0)
    x = a * cp * ct
    y = b * cp * st
    z = c * sp + zoff[:, None] + 0 * ct
    ring_v = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    ring_n = np.stack([cp * ct / a, cp * st / b, sp / c + 0 * ct], axis=-1).reshape(-1, 3)
    verts = np.vstack([[0.0, 0.0, -c], ring_v, [0.0, 0.0, length + c]])
    normals = np.vstack([[0.0, 0.0, -1.0], ring_n, [0.0, 0.0, 1.0]])
    normals /= np.linalg.norm(normals, axis=1, keepdims=True)
    return verts, normals, faces


def tessellation_for(height_px: int) -> tuple:
    """The mannequin's tessellation for a picture ``height_px`` pixels tall: coarse up to
    :data:`COARSE_MAX_PX` (small panels), else :data:`TESSELLATION`."""
    return TESSELLATION_COARSE if int(height_px) <= COARSE_MAX_PX else TESSELLATION


def _tessellation(radius: float, table=TESSELLATION) -> tuple[int, int]:
    for r, t in table:
        if radius >= r:
            return t
    return table[-1][1]


def _frame_from(d: np.ndarray, lateral: np.ndarray | None) -> np.ndarray:
    """Right-handed orthonormal basis (columns u, w, d) with d along ``d`` and u as close
    to ``lateral`` as possible (any perpendicular when ``lateral`` is None/parallel)."""
    d = d / np.linalg.norm(d)
    u = None
    if lateral is not None:
        u = lateral - d * (lateral @ d)
        if np.linalg.norm(u) < 0.3:
            u = None
    if u is None:
        helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
        u = helper - d * (helper @ d)
    u = u / np.linalg.norm(u)
    w = np.cross(d, u)
    return np.stack([u, w, d], axis=1)


def _mean_local_direction(rotations, vectors) -> np.ndarray | None:
    """Unit mean over frames of ``R[f]^T v[f]`` (a world direction in a joint's frame)."""
    v = np.einsum("fji,fj->fi", rotations, vectors)
    n = np.linalg.norm(v, axis=1, keepdims=True)
    ok = n[:, 0] > 1e-9
    if not np.any(ok):
        return None
    m = (v[ok] / n[ok]).mean(axis=0)
    nm = np.linalg.norm(m)
    return m / nm if nm > 1e-6 else None


def _lighten(rgb, k):
    rgb = np.asarray(rgb, float)
    return rgb + (1.0 - rgb) * k


@dataclass(frozen=True, eq=False)
class PosedMesh:
    """A body mesh posed at one frame.

    Attributes
    ----------
    vertices : ndarray of shape (N, 3)
        World positions, metres (float64).
    faces : ndarray of shape (M, 3)
        Vertex indices (int64), counter-clockwise seen from outside.
    face_colors : ndarray of shape (M, 4)
        RGBA, uint8.
    normals : ndarray of shape (N, 3)
        Unit vertex normals (smooth within a piece).
    face_character : ndarray of shape (M,)
        Index of the character each face belongs to.
    """

    vertices: np.ndarray
    faces: np.ndarray
    face_colors: np.ndarray
    normals: np.ndarray
    face_character: np.ndarray

    @property
    def vertex_colors(self) -> np.ndarray:
        """RGBA uint8 per vertex, shape (N, 4) (pieces are one colour each)."""
        out = np.zeros((self.vertices.shape[0], 4), np.uint8)
        out[self.faces.ravel()] = np.repeat(self.face_colors, 3, axis=0)
        return out

    def trimesh(self):
        """The mesh as a :class:`trimesh.Trimesh` (face colours set, not processed)."""
        import trimesh

        return trimesh.Trimesh(
            self.vertices,
            self.faces,
            face_colors=self.face_colors,
            vertex_normals=self.normals,
            process=False,
        )


class CharacterBody:
    """Rigid body pieces of one character, posable at any frame.

    Parameters
    ----------
    character : Character
    color : tuple of 3 floats, optional
        Base RGB colour in 0-1 (default: ``CHARACTER_COLORS[0]``).
    tessellation : tuple, optional
        ``(min radius, (around, rings))`` rows, thickest first: :data:`TESSELLATION`
        (default), :data:`TESSELLATION_COARSE` (~4x fewer faces, for stand-ins such as
        shadows) or :data:`TESSELLATION_FINE` (for reliefs).

    Attributes
    ----------
    joint : ndarray of shape (N,)
        Joint carrying each vertex.
    piece : ndarray of shape (N,)
        Index into ``pieces`` of each vertex.
    pieces : list of dict
        One per rigid piece: ``kind`` ("bone", "head", "nose", "hand"), ``joint`` (the
        carrying joint), ``child`` (a bone's child joint, else -1), ``radii``
        (cross-section semi-axes, m), ``length`` (m, 0 for ellipsoids).
    local_vertices, local_normals : ndarray of shape (N, 3)
        Vertex positions (metres) and normals in the carrying joint's local frame.
    faces : ndarray of shape (M, 3)
    face_colors : ndarray of shape (M, 4), uint8
    roles : list of str
        :func:`joint_roles` of the skeleton.
    """

    def __init__(self, character, *, color=None, tessellation=TESSELLATION):
        self.character = character
        sk = character.skeleton
        names, parents = sk.names, np.asarray(sk.parents)
        self.roles = list(sk.roles)
        self.sides = list(sk.sides)  # a copy: sides are inherited below
        # inherit a side from the parent chain (Daz fingers "lIndex1" have one, but
        # e.g. "LeftHandIndex1_End" or unnamed children may not)
        for j in range(len(names)):
            if (
                not self.sides[j]
                and parents[j] >= 0
                and self.roles[j] not in ("spine", "chest", "neck", "head")
            ):
                self.sides[j] = self.sides[parents[j]]
        height = float(character.height)
        if not (np.isfinite(height) and height > 0):
            raise SceneError(f"character '{character.name}' has no stature; cannot size its body")
        self.size = height  # every size table is a fraction of the stature
        base = np.asarray(color if color is not None else CHARACTER_COLORS[0], float)
        self.color = base
        self._table = tessellation
        self._build(base)

    # ---- orientation cues measured from the motion
    @cached_property
    def _sample(self) -> np.ndarray:
        f = self.character.n_frames
        return np.unique(np.linspace(0, f - 1, min(f, 200)).round().astype(int))

    def _first_joint(self, role: str, side: str) -> int | None:
        for j, (r, s) in enumerate(zip(self.roles, self.sides)):
            if r == role and s == side:
                return j
        return None

    def _lateral(self, j: int, pair: tuple[str, ...]) -> np.ndarray | None:
        """Left-minus-right direction in joint j's frame, from the first pair of joints
        with one of the roles ``pair`` (e.g. thighs, then upper arms)."""
        c, s = self.character, self._sample
        for role in pair:
            a, b = self._first_joint(role, "L"), self._first_joint(role, "R")
            if a is not None and b is not None:
                v = c.positions[s, a] - c.positions[s, b]
                return _mean_local_direction(c.rotations[s, j], v)
        return None

    # ---- construction
    def _build(self, base):
        """The mesh at this body's tessellation, from the character's pieces (made once
        per character and colour: the coarse shadow stand-in and the drawn mannequin of
        one scene differ in their tessellation alone)."""
        k = self.size
        pieces = []  # (joint, verts_local, normals_local, faces, rgb)
        self.pieces: list[dict] = []
        for j, length, a, b, cap, frame, start, rgb, kind, child in self._piece_specs(base):
            around, rings = _tessellation(max(a, b) / k, self._table)  # relative to stature
            v, n, f = _capsule(length, a, b, cap, around, rings)
            pieces.append((j, v @ frame.T + start, n @ frame.T, f, rgb))
            self.pieces.append(
                {
                    "kind": kind,
                    "joint": int(j),
                    "child": int(child),
                    "radii": (float(a), float(b)),
                    "length": float(length),
                }
            )
        if not pieces:
            raise SceneError(f"character '{self.character.name}' has no bones to draw")
        joint, verts, norms, faces, cols, which = [], [], [], [], [], []
        n0 = 0
        for k_piece, (j, v, n, f, rgb) in enumerate(pieces):
            which.append(np.full(len(v), k_piece))
            joint.append(np.full(len(v), j))
            verts.append(v)
            norms.append(n)
            faces.append(f + n0)
            cols.append(np.repeat([np.append(np.clip(rgb, 0, 1), 1.0)], len(f), axis=0))
            n0 += len(v)
        self.joint = np.concatenate(joint)
        self.piece = np.concatenate(which)
        self.local_vertices = np.vstack(verts)
        self.local_normals = np.vstack(norms)
        self.faces = np.vstack(faces).astype(np.int64)
        self.face_colors = np.round(np.vstack(cols) * 255).astype(np.uint8)

    def _piece_specs(self, base) -> list[tuple]:
        """The character's rigid pieces, whatever the tessellation: per piece ``(joint,
        length, a, b, cap, frame (3, 3), start (3,), rgb, kind, child)`` (see
        :func:`_capsule`). Kept on the character, by colour and stature (the pieces
        follow the motion: each is oriented by cues measured over its frames)."""
        memo = vars(self.character).setdefault("_snapcore_mannequin_pieces", {})
        key = (np.asarray(base, float).tobytes(), float(self.size))
        if key not in memo:
            memo[key] = self._measure_pieces(base)
        return memo[key]

    def _measure_pieces(self, base) -> list[tuple]:
        """:meth:`_piece_specs`, measured."""
        c = self.character
        sk = c.skeleton
        parents = np.asarray(sk.parents)
        offsets = np.asarray(sk.offsets, float)
        k = self.size
        roles = self.roles
        specs: list[tuple] = []

        def colour_of(j):
            side = self.sides[j]
            if side == "L":
                return _lighten(base, LEFT_LIGHTEN)
            if side == "R":
                return base * (1 - RIGHT_DARKEN)
            return base

        def add(j, length, a, b, cap, frame, start, rgb, kind="bone", child=-1):
            specs.append((j, length, a, b, cap, frame, start, rgb, kind, child))

        lateral_cache: dict[int, np.ndarray | None] = {}

        def lateral(j):
            if j not in lateral_cache:
                pair = (
                    ("thigh", "upperarm")
                    if roles[j] in ("pelvis", "spine")
                    else ("upperarm", "clavicle", "thigh")
                )
                lateral_cache[j] = self._lateral(j, pair)
            return lateral_cache[j]

        helper = helper_joints(sk.names, parents)
        for p, ch in np.asarray(sk.links).reshape(-1, 2):
            off = offsets[ch]
            length = float(np.linalg.norm(off))
            if length < MIN_BONE_M or roles[p] in HIDDEN_ROLES + ("head",) or helper[ch]:
                continue
            if roles[ch] in HIDDEN_ROLES and not sk.end_site[ch]:
                continue
            role = bone_role(roles[p], roles[ch])
            la, de = ROLE_RADII.get(role, ROLE_RADII[DEFAULT_ROLE])
            la, de = la * k, de * k
            lat = lateral(p) if role in TORSO_ROLES else None
            frame = _frame_from(off, lat)
            if lat is None:
                la = de = min(la, de) if role in TORSO_ROLES else la
            add(p, length, la, de, min(la, de), frame, np.zeros(3), colour_of(ch), "bone", ch)

        # head ellipsoid + nose, in the head joint's frame
        s = self._sample
        for j in [j for j, r in enumerate(roles) if r == "head" and not sk.end_site[j]]:
            if parents[j] >= 0 and roles[parents[j]] == "head":
                continue  # only the first head joint of a chain (e.g. Head, Head1)
            anc = parents[j]
            while anc >= 0 and np.allclose(c.positions[s, anc], c.positions[s, j]):
                anc = parents[anc]
            up = None
            if anc >= 0:
                up = _mean_local_direction(
                    c.rotations[s, j], c.positions[s, j] - c.positions[s, anc]
                )
            if up is None:
                up = np.array([0.0, 1.0, 0.0])
            left = self._lateral(j, ("upperarm", "clavicle", "thigh"))
            # columns: left, w = up × left, up. With left = +X and up = +Y, w = −Z while
            # the person faces left × up = +Z: w points backwards.
            frame = _frame_from(up, left)
            forward = -frame[:, 1]
            hx, hy, hz = (v * k for v in HEAD_SEMI_AXES)
            centre = up * HEAD_CENTRE_ABOVE * k
            add(j, 0.0, hx, hy, hz, frame, centre, _lighten(base, 0.08), "head")
            nose = centre + forward * (hy * 0.97) - up * (0.15 * hz)
            r = NOSE_RADIUS * k
            add(j, 0.0, r, r, r, np.eye(3), nose, base * 0.8, "nose")

        # hand blobs for hands without bones of their own
        lengths = np.linalg.norm(offsets, axis=1)
        kids = sk.children
        for j, r in enumerate(roles):
            if r != "hand" or sk.end_site[j] or (parents[j] >= 0 and roles[parents[j]] == "hand"):
                continue
            stack, total = list(kids[j]), 0.0
            while stack:
                q = stack.pop()
                total += lengths[q]
                stack.extend(kids[q])
            if total >= HAND_BONES_MIN * k or parents[j] < 0:
                continue
            d = _mean_local_direction(
                c.rotations[s, j], c.positions[s, j] - c.positions[s, parents[j]]
            )
            if d is None:
                continue
            rr = HAND_BLOB_RADIUS * k
            add(
                j,
                0.0,
                rr,
                rr * 0.8,
                rr * 1.1,
                _frame_from(d, None),
                d * HAND_BLOB_BEYOND * k,
                colour_of(j),
                "hand",
            )

        return specs

    @property
    def n_vertices(self) -> int:
        return int(self.local_vertices.shape[0])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def vertices(self, frame) -> np.ndarray:
        """World vertex positions at internal frame(s) ``frame``: (N, 3) or (K, N, 3)."""
        c = self.character
        rot = c.rotations[frame][..., self.joint, :, :]  # (..., N, 3, 3)
        pos = c.positions[frame][..., self.joint, :]
        return np.einsum("...nij,nj->...ni", rot, self.local_vertices) + pos

    def normals(self, frame) -> np.ndarray:
        """World unit vertex normals at internal frame(s) ``frame``: (N, 3) or (K, N, 3)."""
        rot = self.character.rotations[frame][..., self.joint, :, :]
        return np.einsum("...nij,nj->...ni", rot, self.local_normals)


class SceneBody:
    """Posable body meshes of every character of a scene, merged into one mesh.

    Parameters
    ----------
    scene : Scene
    colors : sequence of RGB tuples, optional
        One base colour per character (default :data:`CHARACTER_COLORS` in order).
    tessellation : tuple, optional
        Faces per piece (:class:`CharacterBody`).

    Examples
    --------
    >>> body = SceneBody(scene)                  # doctest: +SKIP
    >>> m = body.pose(120)                       # internal frame 120
    >>> m.vertices.shape, m.faces.shape          # (N, 3), (M, 3)
    >>> tm = body.trimesh(120)                   # trimesh.Trimesh with face colours
    """

    kind = "mannequin"

    def __init__(self, scene, *, colors=None, tessellation=TESSELLATION):
        colors = list(colors) if colors is not None else list(CHARACTER_COLORS)
        self._merge(
            scene,
            [
                CharacterBody(ch, color=colors[i % len(colors)], tessellation=tessellation)
                for i, ch in enumerate(scene.characters)
            ],
        )

    def _merge(self, scene, bodies) -> None:
        """Merge per-character bodies (anything with ``vertices``, ``normals``, ``faces``,
        ``face_colors``, ``n_vertices``, ``n_faces``) into this scene's one mesh."""
        self.scene = scene
        self.characters = list(bodies)
        offs = np.cumsum([0] + [b.n_vertices for b in self.characters])
        self.vertex_offsets = offs  # character i owns vertices offs[i]:offs[i+1]
        foffs = np.cumsum([0] + [b.n_faces for b in self.characters])
        self.face_offsets = foffs
        self.faces = np.vstack([b.faces + o for b, o in zip(self.characters, offs[:-1])])
        self.face_colors = np.vstack([b.face_colors for b in self.characters])
        self.face_character = np.concatenate(
            [np.full(b.n_faces, i) for i, b in enumerate(self.characters)]
        )

    @property
    def n_vertices(self) -> int:
        return int(self.vertex_offsets[-1])

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def _check(self, frame):
        f = np.asarray(frame)
        n = self.scene.n_frames
        if f.size and (f.min() < 0 or f.max() >= n):
            raise SceneError(f"frame {frame} is outside the scene's internal frames 0..{n - 1}")

    def vertices(self, frame) -> np.ndarray:
        """Merged world vertices at internal frame(s): (N, 3), or (K, N, 3) for K frames."""
        self._check(frame)
        return np.concatenate([b.vertices(frame) for b in self.characters], axis=-2)

    def normals(self, frame) -> np.ndarray:
        """Merged world vertex normals at internal frame(s): (N, 3) or (K, N, 3)."""
        self._check(frame)
        return np.concatenate([b.normals(frame) for b in self.characters], axis=-2)

    def pose(self, frame: int) -> PosedMesh:
        """The merged mesh of all characters at internal frame ``frame``."""
        frame = int(frame)
        return PosedMesh(
            self.vertices(frame),
            self.faces,
            self.face_colors,
            self.normals(frame),
            self.face_character,
        )

    def trimesh(self, frame: int):
        """``self.pose(frame).trimesh()``: a :class:`trimesh.Trimesh` with face colours."""
        return self.pose(frame).trimesh()


def _bodies_of(scene) -> dict:
    """The scene's body cache, kept on the scene object itself. (A module-level
    ``WeakKeyDictionary`` keyed by scene never freed an entry: its values, the bodies,
    hold the scene. On the scene, scene and bodies form a cycle the collector frees.)
    Its own attribute: :func:`snapcore.render.bodies.scene_body` keeps another cache,
    keyed differently, on the same scene."""
    return vars(scene).setdefault("_snapcore_mannequins", {})


def scene_body(scene, tessellation=TESSELLATION) -> SceneBody:
    """The (cached) :class:`SceneBody` of ``scene`` at ``tessellation`` (default colours):
    built once per scene object and tessellation."""
    bodies = _bodies_of(scene)
    body = bodies.get(tessellation)
    if body is None:
        body = bodies[tessellation] = SceneBody(scene, tessellation=tessellation)
    return body


def posed_mesh(scene, index: int) -> PosedMesh:
    """Merged body mesh of every character of ``scene`` at internal index ``index``.

    Returns
    -------
    PosedMesh
        ``vertices`` (N, 3) metres, ``faces`` (M, 3), ``face_colors`` (M, 4) uint8,
        ``normals`` (N, 3), ``face_character`` (M,). Thousands of faces per character.
    """
    return scene_body(scene).pose(index)


def scene_trimesh(scene, index: int):
    """:func:`posed_mesh` as a :class:`trimesh.Trimesh` (face colours set)."""
    return posed_mesh(scene, index).trimesh()
