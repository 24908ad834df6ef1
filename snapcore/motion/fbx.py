"""Animated FBX skeletons (``.fbx``, binary and ASCII, FBX 6100-7700) → :class:`Character`.

The file is read by the ufbx loader (the ``ufbx`` package; the choice among the
bindings on the package index is argued in ``docs/fbx.md``) in a worker process,
:mod:`snapcore.motion.fbx_extract`, which hands back plain arrays: the node tree, each
node's local transform at every sample time of one animation stack, and the meshes
with their skins. Everything else is done here with arrays: world transforms composed
down the node tree for all frames at once (a loop over nodes, never over frames), the
characters found, the skinned mesh built.

- **Characters**: the joints are the file's skeleton nodes (``LimbNode``) and every
  node a skin binds to; each tree of joints (joints whose nearest joint ancestor is
  none) is one character, trees bound by one skin are merged (as for glTF). A file with
  two skeletons is two characters (``load_scene`` names them ``<file>_<root>``).
- **Animation**: one animation stack (``animation=`` name or index, default the
  first), sampled at ``fps`` (default the file's own frame rate) from the stack's
  first time to its last. Frame 0 is the stack's first time; ``meta["first_frame"]``
  is that time in the file's frames (Maya and Blender number from there).
- **Units and axes**: ufbx turns the scene to Y up (right-handed) whatever the file's
  up axis (``meta["up_axis"]`` keeps the original); positions stay in the file's unit,
  ``UnitScaleFactor`` (``meta["unit_meters"]``: 0.01 for centimetres), which
  :func:`snapcore.motion.load.load_scene` applies as the character's scale.
- **Mesh**: a skinned mesh bound to the character's joints is its own mesh, as glTF
  characters wear theirs (:class:`~snapcore.motion.skinning.SkinnedMesh`: a cluster's
  ``geometry_to_bone`` is its inverse bind matrix); a mesh without a skin below a joint
  moves rigidly with it. Dual-quaternion skins are skinned linearly (with a warning).
- **End sites**: leaf joints named ``*_end`` (the tips Blender's exporter adds, where a
  BVH's end sites were) are end sites, as in BVH.
"""

from __future__ import annotations

import functools
import json
import os
import subprocess
import sys
import tempfile
import warnings
from pathlib import Path

import numpy as np

from snapcore.errors import FBXError
from snapcore.motion.gltf import _unique_names, node_world_matrices
from snapcore.motion.kinematics import joints_from_world, matrix_to_quat, trs_matrix
from snapcore.motion.scene import Character, Skeleton
from snapcore.motion.skinning import SkinnedMesh, weight_matrix

__all__ = [
    "read_fbx",
    "fbx_characters",
    "fbx_unit",
    "fbx_unit_name",
    "still_fbx",
    "FBX_SUFFIXES",
    "EXTRACT_TIMEOUT_S",
    "MAX_STATURE_M",
]

FBX_SUFFIXES = (".fbx",)
#: Seconds the extraction worker may take before the file is refused.
EXTRACT_TIMEOUT_S = 300.0
#: ufbx's inherit mode of a node that ignores its parent's scale (Maya's segment scale
#: compensation, HumanIK rigs).
_IGNORE_PARENT_SCALE = 1
#: ufbx's skinning methods that are not linear (dual quaternion, blended).
_DQ_METHODS = (2, 3)


#: The units ``snapshot info`` names (data_schema/info.schema.json), in metres.
_UNIT_NAMES = {"m": 1.0, "dm": 0.1, "cm": 0.01, "mm": 0.001, "inch": 0.0254}


def fbx_unit_name(unit_meters: float) -> str:
    """The name of an FBX file's unit (``UnitScaleFactor``, in metres): ``"cm"`` for
    0.01...; ``"given"`` for a unit without a name (taken as written all the same)."""
    for unit, metres in _UNIT_NAMES.items():
        if abs(unit_meters - metres) <= 1e-9 * metres:
            return unit
    return "given"


#: An FBX character taller than this (metres) in the unit its file states is read in
#: centimetres: no creature an animator rigs is that tall, while files that misstate
#: their unit are off by 100x (a 1.7 m person read as 170 m).
MAX_STATURE_M = 20.0


def fbx_unit(character) -> tuple[float, str, str | None]:
    """Metres per unit of a character read by :func:`read_fbx`, its name, and why it
    is not the file's own (None when it is).

    The file's ``UnitScaleFactor``, unless the character would then be taller than
    :data:`MAX_STATURE_M`: FBX 6100 files have no ``UnitScaleFactor`` and some exporters
    write 1 (m) for a rig in centimetres (Maya's HumanIK samples: 174 "m" tall).
    """
    metres = float(character.meta["unit_meters"])
    height = character.height * metres / character.scale
    if height <= MAX_STATURE_M:
        return metres, fbx_unit_name(metres), None
    why = (
        f"{character.meta['path']}: in the unit the file states ({metres:g} m) "
        f"'{character.name}' would be {height:.0f} m tall; read in centimetres. "
        "Pass --scale to override."
    )
    return metres * 0.01, fbx_unit_name(metres * 0.01), why


def still_fbx(characters) -> None:
    """Refuse FBX characters of which none moves a joint in its take (a rig saved with
    an empty take: there is no animation to take a snapshot of). One still character
    beside moving ones is kept: standing still is part of a scene.

    Raises
    ------
    FBXError
        Naming the first character's file and take.
    """
    if characters and all(np.ptp(c.positions, axis=0).max() == 0.0 for c in characters):
        c = characters[0]
        raise FBXError(
            f"its take '{c.meta['animation']}' moves no joint: there is no "
            "animation (a rig saved with an empty take)",
            path=c.meta["path"],
        )


def _extract(path: Path, animation: str | None, fps: float | None) -> dict:
    """The worker's arrays for one file (see :mod:`snapcore.motion.fbx_extract`)."""
    if not path.is_file():
        raise FBXError("no such file", path=str(path))
    st = path.stat()
    return _extract_cached(str(path.resolve()), st.st_mtime_ns, st.st_size, animation, fps)


@functools.lru_cache(maxsize=4)
def _extract_cached(path: str, mtime: int, size: int, animation, fps) -> dict:
    # (mtime and size only key the cache: a file changed on disk is read again)
    args = [sys.executable, "-m", "snapcore.motion.fbx_extract", path]
    with tempfile.TemporaryDirectory(prefix="snapshot-fbx-") as folder:
        out = os.path.join(folder, "scene.npz")
        args.append(out)
        if animation is not None:
            args += ["--animation", str(animation)]
        if fps:
            args += ["--fps", repr(float(fps))]
        try:
            done = subprocess.run(args, capture_output=True, text=True, timeout=EXTRACT_TIMEOUT_S)
        except subprocess.TimeoutExpired:
            raise FBXError(
                f"the FBX loader took more than {EXTRACT_TIMEOUT_S:g} s", path=path
            ) from None
        if done.returncode == 3:
            lines = done.stderr.strip().splitlines()
            raise FBXError(lines[-1] if lines else "refused by the FBX loader", path=path)
        if done.returncode != 0 or not os.path.exists(out):
            how = f"signal {-done.returncode}" if done.returncode < 0 else f"exit {done.returncode}"
            raise FBXError(f"the FBX loader failed on this file ({how})", path=path)
        with np.load(out, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    arrays["meta"] = json.loads(str(arrays["meta"]))
    return arrays


def _order(parent: np.ndarray) -> list[int]:
    """Node indices, parents before children."""
    depth = np.zeros(parent.size, dtype=int)
    for i in range(parent.size):
        j, d = parent[i], 0
        while j >= 0 and d <= parent.size:
            j, d = parent[j], d + 1
        depth[i] = d
    return sorted(range(parent.size), key=lambda i: (depth[i], i))


def _world(local: np.ndarray, parent: np.ndarray, inherit: np.ndarray, order) -> np.ndarray:
    """World matrices (F, N, 4, 4) from local T, R (xyzw), S (F, N, 10), parents first."""
    mats = trs_matrix(local[..., 0:3], local[..., 3:7], local[..., 7:10])
    if not np.any(inherit == _IGNORE_PARENT_SCALE):
        return node_world_matrices(mats, parent, order)
    world = np.empty_like(mats)
    for i in order:
        p = parent[i]
        if p < 0:
            world[:, i] = mats[:, i]
            continue
        pw = world[:, p]
        if inherit[i] == _IGNORE_PARENT_SCALE:  # the parent's frame without its scale
            pw = pw.copy()
            pw[:, :3, :3] /= np.linalg.norm(pw[:, :3, :3], axis=1, keepdims=True)
        world[:, i] = pw @ mats[:, i]
    return world


def _groups(z: dict) -> list[list[int]]:
    """The characters: joint node indices (parents first), one list per skeleton."""
    parent, bone = z["node_parent"], z["node_bone"]
    order = _order(parent)
    top: dict[int, int] = {}
    for i in order:
        if not bone[i]:
            continue
        a = parent[i]
        while a >= 0 and not bone[a]:
            a = parent[a]
        top[i] = top[a] if a >= 0 else i
    link = {t: t for t in set(top.values())}

    def find(t):
        while link[t] != t:
            t = link[t]
        return t

    for key in [k for k in z if k.endswith("_cluster_node")]:
        tops = [find(top[int(c)]) for c in z[key] if int(c) in top]
        for t in tops[1:]:
            link[find(t)] = find(tops[0])
    groups: dict[int, list[int]] = {}
    for i in order:
        if i in top:
            groups.setdefault(find(top[i]), []).append(i)
    return sorted(groups.values(), key=lambda g: order.index(g[0]))


def fbx_characters(path) -> list[str]:
    """Names of the animated skeletons of an FBX file (each one's topmost joint), in
    the order ``read_fbx(..., character=k)`` reads them.

    Raises
    ------
    FBXError
        The file cannot be read, or has no skeleton.
    """
    path = Path(path)
    z = _extract(path, None, None)
    groups = _groups(z)
    if not groups:
        raise FBXError(
            "has no skeleton (no LimbNode, no skin): only animated skeletons can be read",
            path=str(path),
        )
    return [str(z["node_name"][g[0]]) for g in groups]


def _mesh(z: dict, joints: list[int], rest_world: np.ndarray, joint_scale, path) -> SkinnedMesh:
    """The character's own mesh: skinned meshes bound to its joints, rigid ones below."""
    parent = z["node_parent"]
    joint_index = {n: k for k, n in enumerate(joints)}
    rest_v, faces, bones, wts = [], [], [], []
    ibms: list[np.ndarray] = []
    slot_joint: list[int] = []
    n_v = 0
    dq = False
    m = 0
    while f"mesh{m}_node" in z:
        key, m = f"mesh{m}", m + 1
        verts, tris = z[f"{key}_vertices"], z[f"{key}_triangles"]
        if not len(verts) or not len(tris):
            continue
        if f"{key}_cluster_node" in z:
            cnode = z[f"{key}_cluster_node"]
            if not all(int(c) in joint_index for c in cnode if c >= 0):
                continue  # another character's mesh
            base = len(slot_joint)
            slot_joint += [joint_index.get(int(c), 0) for c in cnode]
            ibms.append(z[f"{key}_geometry_to_bone"])
            sv, sw = z[f"{key}_skin_vertices"], z[f"{key}_skin_weights"]
            first, count = sv[:, 0].astype(np.int64), sv[:, 1].astype(np.int64)
            width = max(1, int(count.max()) if count.size else 1)
            k = np.arange(width)
            idx = np.minimum(first[:, None] + k, max(len(sw) - 1, 0))
            live = (k < count[:, None]) & (len(sw) > 0)
            cl = np.where(live, sw[idx, 0].astype(np.int64), 0) if len(sw) else np.zeros_like(idx)
            ww = np.where(live, sw[idx, 1], 0.0) if len(sw) else np.zeros(idx.shape)
            bones.append(cl + base)
            wts.append(ww)
            dq = dq or any(s in _DQ_METHODS for s in z["meta"].get("skinning", []))
        else:
            node = int(z[f"{key}_node"])
            a = parent[node]
            while a >= 0 and a not in joint_index:
                a = parent[a]
            if a < 0:
                continue  # not this character's (or no character's) piece
            slot = len(slot_joint)
            slot_joint.append(joint_index[a])
            g2w = rest_world[node] @ z[f"{key}_geometry_to_node"]
            ibms.append((np.linalg.inv(rest_world[a]) @ g2w)[None])
            bones.append(np.full((len(verts), 1), slot))
            wts.append(np.ones((len(verts), 1)))
        rest_v.append(verts)
        faces.append(tris + n_v)
        n_v += len(verts)
    if not rest_v:
        return None  # type: ignore[return-value]
    if dq:
        warnings.warn(
            f"{path}: a dual-quaternion skin is skinned linearly (its bends may thin)",
            stacklevel=4,
        )
    width = max(b.shape[1] for b in bones)
    bb = np.vstack([np.pad(b, ((0, 0), (0, width - b.shape[1]))) for b in bones])
    ww = np.vstack([np.pad(w, ((0, 0), (0, width - w.shape[1]))) for w in wts])
    return SkinnedMesh(
        rest=np.vstack(rest_v),
        faces=np.vstack(faces).astype(np.int64),
        weights=weight_matrix(bb, ww, len(slot_joint)),
        slot_joint=np.asarray(slot_joint, dtype=np.int64),
        inverse_bind=np.concatenate(ibms, axis=0),
        joint_scale=joint_scale,
    )


def _end_sites(names: list[str], parents: np.ndarray) -> np.ndarray:
    """Which joints are end sites: leaves named ``*_end`` (Blender's exporter adds one
    at each bone's tip; a BVH's end sites come back as them)."""
    leaf = np.ones(len(names), dtype=bool)
    leaf[parents[parents >= 0]] = False
    return leaf & np.array([n.lower().endswith("_end") for n in names], dtype=bool)


def read_fbx(
    path,
    *,
    animation: str | int | None = None,
    fps: float | None = None,
    name: str | None = None,
    character: int | None = None,
) -> Character:
    """Read one animated skeleton of an FBX file as a :class:`Character`.

    Parameters
    ----------
    path : str or path-like
    animation : str or int, optional
        Animation stack (take) name or index; default the first.
    fps : float, optional
        Sampling rate, frames per second (default the file's frame rate).
    name : str, optional
        Character name (default the file's stem).
    character : int, optional
        Which skeleton (:func:`fbx_characters`); required when the file holds several.

    Returns
    -------
    Character
        Positions (F, J, 3) in the file's unit (``scale`` 1; ``meta["unit_meters"]``
        says what it is), its own ``mesh`` when a mesh is bound to it (else None: the
        renderer dresses it), ``meta`` with ``format`` ``"fbx"``, ``animation``,
        ``animations``, ``first_frame``, ``version``, ``ascii``, ``up_axis``.

    Raises
    ------
    FBXError
        One line naming the file: unreadable, truncated or damaged file, no skeleton,
        no animation, an unknown animation.
    """
    path = Path(path)
    z = _extract(path, None if animation is None else str(animation), fps)
    meta = z["meta"]
    groups = _groups(z)
    if not groups:
        raise FBXError(
            "has no skeleton (no LimbNode, no skin): only animated skeletons can be read",
            path=str(path),
        )
    if "local" not in z:
        raise FBXError("has no animation stack (no take to play)", path=str(path))
    if character is None and len(groups) > 1:
        names = ", ".join(str(z["node_name"][g[0]]) for g in groups)
        raise FBXError(
            f"holds {len(groups)} skeletons ({names}); read them with load_scene, one "
            "character each",
            path=str(path),
        )
    k = character or 0
    if not 0 <= k < len(groups):
        raise FBXError(f"has no character {k} (it has {len(groups)})", path=str(path))
    joints = groups[k]
    parent = z["node_parent"]
    order = _order(parent)
    local = z["local"]
    if not np.all(np.isfinite(local)):
        raise FBXError("its animation has non-finite transforms (NaN or infinity)", path=str(path))
    world = _world(local, parent, z["node_inherit"], order)
    joint_index = {n: j for j, n in enumerate(joints)}
    jparent = []
    for n in joints:
        a = parent[n]
        while a >= 0 and a not in joint_index:
            a = parent[a]
        jparent.append(joint_index[a] if a >= 0 else -1)
    frames = joints_from_world(world[:, joints], np.asarray(jparent))
    if not frames["uniform"]:
        warnings.warn(
            f"{path}: joints scale non-uniformly or over time; a mesh follows their "
            "median uniform scale",
            stacklevel=2,
        )
    # rigid pieces are placed by the file's own default pose (its node transforms at load)
    mesh = _mesh(z, joints, z["rest_world"], frames["joint_scale"], path)
    rate = float(meta["fps"])
    t0 = float(z["times"][0])
    joint_names = [str(z["node_name"][n]) for n in joints]
    return Character(
        name=name or path.stem,
        skeleton=Skeleton(
            names=_unique_names(joint_names),
            parents=np.asarray(jparent, dtype=int),
            offsets=frames["offsets"],
            end_site=_end_sites(joint_names, np.asarray(jparent)),
        ),
        positions=frames["positions"],
        rotations=frames["rotations"],
        local_rotations=frames["local_rotations"],
        fps=rate,
        scale=1.0,
        source=None,
        meta={
            "format": "fbx",
            "path": str(path),
            "animation": meta["animation"],
            "animations": list(meta["animations"]),
            "first_frame": int(round(t0 * float(meta["file_fps"] or rate))),
            "unit_meters": float(meta["unit_meters"]),
            "version": int(meta["version"]),
            "ascii": bool(meta["ascii"]),
            "up_axis": "XYZ"[int(meta["up_axis"]) // 2] if int(meta["up_axis"]) < 6 else "?",
        },
        local_quaternions=matrix_to_quat(frames["local_rotations"]),
        mesh=mesh,
    )
