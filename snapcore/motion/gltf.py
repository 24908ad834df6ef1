"""Skinned, animated glTF 2.0 characters (``.glb``/``.gltf``) → :class:`Character`.

A glTF file is read into one character: its joints are the union of the joints of
every skin in the file (BrainStem has 59 skins over one skeleton), ordered parents
first; the joint hierarchy is the node hierarchy restricted to them. One animation
(``animation=`` name or index; default the first) is sampled at ``fps`` (default
:data:`DEFAULT_FPS`) from its first to its last key time, every node's local
translation/rotation/scale by its channel's interpolation
(:mod:`snapcore.motion.gltf_sample`), then world transforms are composed down the node
tree for all frames at once (a loop over nodes, never over frames).

The character carries its own skinned mesh, a
:class:`~snapcore.motion.skinning.SkinnedMesh` in ``character.mesh``: bind-pose
vertices, faces, sparse weights over *slots*
(one per (skin, joint) pair, with that skin's inverse bind matrix — optional in the
spec, identity when absent) and the character joint of each slot. Posing it is
:func:`snapcore.motion.skinning.blend_skin` with ``M_k = G_joint(k) · IBM_k``, where the
joint's world transform ``G = [scale · s · R | p]`` is rebuilt from the character's
``positions``/``rotations`` — so a character moved, turned or rescaled by a scene
manifest carries its mesh along. Meshes without a skin that hang below a joint node are
attached rigidly to it (a slot whose "inverse bind matrix" is the mesh's rest pose
relative to that joint).

Units: glTF is in metres (spec §3.4); the file unit is taken as given (scale 1) unless a
scene manifest or ``--scale`` says otherwise. Y is up, as in the rest of the suite.
"""

from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from snapcore.errors import GLTFError
from snapcore.motion.gltf_access import Buffers
from snapcore.motion.gltf_sample import INTERPOLATIONS, quat_normalize, sample_curve
from snapcore.motion.kinematics import joints_from_world, matrix_to_quat, trs_matrix
from snapcore.motion.scene import Character, Skeleton
from snapcore.motion.skinning import SkinnedMesh, weight_matrix

__all__ = [
    "read_gltf",
    "gltf_characters",
    "gltf_animations",
    "SkinnedMesh",
    "node_world_matrices",
    "lowest_points",
    "gltf_unit",
    "GLTF_SUFFIXES",
    "DEFAULT_FPS",
    "MAX_HEIGHT_M",
]

GLTF_SUFFIXES = (".glb", ".gltf")
#: Sampling rate (frames per second) of glTF animations when none is given.
DEFAULT_FPS = 30.0
#: A glTF character taller than this (metres) is taken to be written in centimetres (or
#: millimetres): the spec says metres, but exporters often write cm (the Fox sample is
#: 80 "metres" tall).
MAX_HEIGHT_M = 4.0
#: glTF primitive modes: 4 triangles, 5 triangle strip, 6 triangle fan.
_TRIANGLE_MODES = (4, 5, 6)
#: Required extensions a file may list and still be read: they change how a surface looks
#: (materials, textures, lights), not where its vertices are; mesh quantization is only
#: integer accessors, which :mod:`snapcore.motion.gltf_access` reads. Any other required
#: extension (Draco or meshopt compression...) holds data this reader cannot decode.
_HARMLESS_EXTENSIONS = (
    "KHR_materials_",
    "KHR_texture_",
    "EXT_texture_",
    "KHR_lights_",
    "KHR_mesh_quantization",
)


# --------------------------------------------------------------------------- nodes


def _local_trs(node) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A node's rest translation (3,), rotation (4,) xyzw, scale (3,)."""
    if node.matrix is not None:
        m = np.asarray(node.matrix, float).reshape(4, 4).T  # column-major
        t = m[:3, 3]
        lin = m[:3, :3]
        s = np.linalg.norm(lin, axis=0)
        r = lin / np.where(s > 0, s, 1.0)
        if np.linalg.det(r) < 0:
            s[0], r[:, 0] = -s[0], -r[:, 0]
        from scipy.spatial.transform import Rotation

        return t, Rotation.from_matrix(r).as_quat(), s
    t = np.asarray(node.translation if node.translation is not None else (0, 0, 0), float)
    q = np.asarray(node.rotation if node.rotation is not None else (0, 0, 0, 1), float)
    s = np.asarray(node.scale if node.scale is not None else (1, 1, 1), float)
    return t, quat_normalize(q), s


def _node_parents(gltf, buffers: Buffers) -> np.ndarray:
    n = len(gltf.nodes or [])
    parent = np.full(n, -1, dtype=int)
    for i, node in enumerate(gltf.nodes or []):
        for c in node.children or []:
            if not 0 <= c < n:
                raise buffers.error(f"node {i} has child {c}, which does not exist")
            if parent[c] >= 0:
                raise buffers.error(f"node {c} has two parents ({parent[c]} and {i})")
            parent[c] = i
    return parent


def _topological(parent: np.ndarray, buffers: Buffers) -> list[int]:
    """Node indices with every parent before its children (refusing cycles)."""
    depth = np.full(parent.size, -1)
    for i in range(parent.size):
        chain, j = [], i
        while j >= 0 and depth[j] < 0:
            if j in chain:
                raise buffers.error(f"the node hierarchy has a cycle through node {j}")
            chain.append(j)
            j = parent[j]
        base = -1 if j < 0 else depth[j]
        for k, node in enumerate(reversed(chain)):
            depth[node] = base + 1 + k
    return sorted(range(parent.size), key=lambda i: (depth[i], i))


def node_world_matrices(local: np.ndarray, parent: np.ndarray, order) -> np.ndarray:
    """World matrices of every node: (F, N, 4, 4) from local (F, N, 4, 4), parents first."""
    world = np.empty_like(local)
    for i in order:
        p = parent[i]
        world[:, i] = local[:, i] if p < 0 else world[:, p] @ local[:, i]
    return world


# --------------------------------------------------------------------------- animation


def gltf_animations(gltf) -> list[str]:
    """Names of a document's animations (``animation_<i>`` for unnamed ones), made
    unique as joint names are (a second ``walk`` is ``walk_2``), so each can be chosen."""
    return list(
        _unique_names([a.name or f"animation_{i}" for i, a in enumerate(gltf.animations or [])])
    )


def _pick_animation(gltf, animation, buffers: Buffers):
    names = gltf_animations(gltf)
    if animation is None:
        return (0, names[0]) if names else (None, None)
    if not names:
        raise buffers.error(f"has no animations (asked for '{animation}')")
    if str(animation) in names:
        return names.index(str(animation)), str(animation)
    if str(animation).isdigit() and int(animation) < len(names):
        return int(animation), names[int(animation)]
    raise buffers.error(f"no animation '{animation}' (it has: {', '.join(names)})")


def _own_animation(gltf, joints, parent) -> int | None:
    """The first animation that moves one of ``joints`` or a node above them, by index
    (None: none does, or the file has none): in a file holding several characters, each
    merged with its own animation, the first animation moves only the first character,
    and the others stood still while reported as playing it."""
    moved = set()
    for j in joints:
        while j >= 0 and j not in moved:
            moved.add(j)
            j = parent[j]
    for k, anim in enumerate(gltf.animations or []):
        if any(ch.target.node in moved for ch in anim.channels or []):
            return k
    return None


def _sample_animation(gltf, index, buffers: Buffers, rest_trs, fps: float, name: str):
    """Local T, R (xyzw), S of every node at the sample times: (F, N, 3|4|3)."""
    n = len(rest_trs[0])
    if index is None:
        return [x[None] for x in rest_trs]
    anim = gltf.animations[index]
    curves = []
    for c, ch in enumerate(anim.channels or []):
        path = ch.target.path
        if ch.target.node is None or path == "weights":
            continue  # morph weights do not move joints; a channel with no node is ignored
        if not 0 <= ch.target.node < n:
            raise buffers.error(
                f"animation '{name}' channel {c} targets node "
                f"{ch.target.node}, which does not exist"
            )
        if path not in ("translation", "rotation", "scale"):
            raise buffers.error(f"animation '{name}' channel {c}: unknown target path {path!r}")
        if not 0 <= ch.sampler < len(anim.samplers or []):
            raise buffers.error(
                f"animation '{name}' channel {c}: sampler {ch.sampler} does not exist"
            )
        smp = anim.samplers[ch.sampler]
        interp = smp.interpolation or "LINEAR"
        if interp not in INTERPOLATIONS:
            raise buffers.error(
                f"animation '{name}' sampler {ch.sampler}: unknown interpolation "
                f"'{interp}' (glTF 2.0 has {', '.join(INTERPOLATIONS)})"
            )
        times = buffers.floats(smp.input, f"animation '{name}' sampler {ch.sampler} input")
        values = buffers.floats(smp.output, f"animation '{name}' sampler {ch.sampler} output")
        if times.size == 0:
            raise buffers.error(
                f"animation '{name}' sampler {ch.sampler} has no key times "
                "(an animation needs at least one key)"
            )
        curves.append((ch.target.node, path, times, values.reshape(values.shape[0], -1), interp))
    if not curves:
        return [x[None] for x in rest_trs]
    t0 = min(float(c[2][0]) for c in curves if c[2].size)
    t1 = max(float(c[2][-1]) for c in curves if c[2].size)
    # up to and including the last key: the final sample is moved back onto it when
    # the span is not a whole number of frames (the pose the animation ends on)
    count = int(np.ceil((t1 - t0) * fps - 1e-6)) + 1
    t = np.minimum(t0 + np.arange(count) / fps, t1)
    out = [np.repeat(x[None], count, axis=0) for x in rest_trs]
    slot = {"translation": 0, "rotation": 1, "scale": 2}
    for node, path, times, values, interp in curves:
        try:
            v = sample_curve(times, values, interp, t, rotation=path == "rotation")
        except ValueError as err:
            raise buffers.error(f"animation '{name}' {path} of node {node}: {err}") from None
        width = 4 if path == "rotation" else 3
        if v.shape[1] != width:
            raise buffers.error(
                f"animation '{name}' {path} of node {node} has {v.shape[1]} "
                f"components, expected {width}"
            )
        out[slot[path]][:, node] = v
    return out


# --------------------------------------------------------------------------- meshes


def _triangles(indices: np.ndarray, mode: int) -> np.ndarray:
    if mode == 4:
        return indices.reshape(-1, 3)
    if mode == 5:  # strip: alternate winding
        k = np.arange(indices.size - 2)
        tri = np.stack([indices[k], indices[k + 1], indices[k + 2]], axis=1)
        odd = k % 2 == 1
        tri[odd] = tri[odd][:, [1, 0, 2]]
        return tri
    k = np.arange(1, indices.size - 1)  # fan
    return np.stack([np.full(k.size, indices[0]), indices[k], indices[k + 1]], axis=1)


def _material_rgb(gltf, mi) -> np.ndarray | None:
    """A primitive's own colour: its material's base colour factor (RGB 0-1, sRGB as
    glTF stores it), or None for no material or the default white (a textured material
    multiplies its texture by white: its colour is in the texture, not read here)."""
    mats = gltf.materials or []
    if mi is None or not 0 <= mi < len(mats) or mats[mi].pbrMetallicRoughness is None:
        return None
    f = mats[mi].pbrMetallicRoughness.baseColorFactor
    if f is None or len(f) < 3:
        return None
    rgb = np.clip(np.asarray(f[:3], float), 0.0, 1.0)
    return None if np.allclose(rgb, 1.0) or not np.all(np.isfinite(rgb)) else rgb


def _primitive_arrays(gltf, buffers: Buffers, mi: int):
    """(positions, faces, [(joints, weights), ...], own RGB or None) of every triangle
    primitive of mesh mi."""
    meshes = gltf.meshes or []
    if not 0 <= mi < len(meshes):
        raise buffers.error(f"mesh {mi} does not exist")
    out = []
    for pi, prim in enumerate(meshes[mi].primitives or []):
        mode = 4 if prim.mode is None else prim.mode
        if mode not in _TRIANGLE_MODES:
            continue  # points and lines have no surface
        attrs = prim.attributes
        if attrs.POSITION is None:
            raise buffers.error(f"mesh {mi} primitive {pi} has no POSITION")
        pos = buffers.floats(attrs.POSITION, f"mesh {mi} primitive {pi} POSITION")
        if prim.indices is not None:
            idx = np.asarray(buffers.accessor(prim.indices), dtype=np.int64).ravel()
        else:
            idx = np.arange(pos.shape[0])
        if idx.size and (idx.min() < 0 or idx.max() >= pos.shape[0]):
            raise buffers.error(
                f"mesh {mi} primitive {pi}: indices past its {pos.shape[0]} vertices"
            )
        faces = _triangles(idx, mode)
        influences = []
        for k in range(4):
            j = getattr(attrs, f"JOINTS_{k}", None)
            w = getattr(attrs, f"WEIGHTS_{k}", None)
            if j is None or w is None:
                break
            influences.append(
                (
                    np.asarray(buffers.accessor(j), dtype=np.int64),
                    buffers.floats(w, f"mesh {mi} primitive {pi} WEIGHTS_{k}"),
                )
            )
        out.append((pos, faces, influences, _material_rgb(gltf, prim.material)))
    return out


def _build_mesh(
    gltf, buffers, parent, rest_world, joints, joint_index, world_scale, all_joints=()
) -> SkinnedMesh:
    rest_v, faces, bones, wts, colors = [], [], [], [], []
    ibms: list[np.ndarray] = []
    slot_joint: list[int] = []  # skeleton joint of each bind slot
    n_v = 0
    for ni, node in enumerate(gltf.nodes or []):
        if node.mesh is None:
            continue
        prims = _primitive_arrays(gltf, buffers, node.mesh)
        if node.skin is not None:
            skins = gltf.skins or []
            if not 0 <= node.skin < len(skins):
                raise buffers.error(f"node {ni} uses skin {node.skin}, which does not exist")
            skin = skins[node.skin]
            if not all(j in joint_index for j in skin.joints or []):
                continue  # another character's mesh
            sj = [joint_index[j] for j in skin.joints]
            if skin.inverseBindMatrices is not None:
                ibm = buffers.floats(
                    skin.inverseBindMatrices, f"skin {node.skin} inverseBindMatrices"
                )
                if ibm.shape != (len(sj), 4, 4):
                    raise buffers.error(
                        f"skin {node.skin}: {ibm.shape[0]} inverse bind matrices "
                        f"for {len(sj)} joints"
                    )
            else:
                ibm = np.repeat(np.eye(4)[None], len(sj), axis=0)  # spec: identity when absent
            base = len(slot_joint)
            slot_joint += sj
            ibms.append(ibm)
            for pos, f, infl, rgb in prims:
                if not infl:
                    raise buffers.error(
                        f"mesh {node.mesh} is skinned but has no JOINTS_0/WEIGHTS_0"
                    )
                jj = np.concatenate([j for j, _ in infl], axis=1)
                ww = np.concatenate([w for _, w in infl], axis=1)
                if np.any(jj[ww != 0] >= len(sj)):
                    raise buffers.error(
                        f"mesh {node.mesh}: a joint index is past skin "
                        f"{node.skin}'s {len(sj)} joints"
                    )
                rest_v.append(pos)
                faces.append(f + n_v)
                colors.append(np.broadcast_to(np.nan if rgb is None else rgb, (len(f), 3)))
                bones.append(np.where(ww != 0, jj, 0) + base)
                wts.append(ww)
                n_v += pos.shape[0]
            continue
        # an unskinned mesh below a joint moves rigidly with that joint
        a = parent[ni]
        while a >= 0 and a not in joint_index:
            a = parent[a]
        if a < 0:
            b = parent[ni]
            while b >= 0 and b not in all_joints:
                b = parent[b]
            if b < 0:  # (below another character's joint: that character's piece)
                warnings.warn(
                    f"{buffers.path}: mesh of node {ni} is attached to no joint; left out",
                    stacklevel=4,
                )
            continue
        slot = len(slot_joint)
        slot_joint.append(joint_index[a])
        # vertex in mesh space → world at rest → joint space at rest
        ibms.append((np.linalg.inv(rest_world[a]) @ rest_world[ni])[None])
        for pos, f, _, rgb in prims:
            rest_v.append(pos)
            faces.append(f + n_v)
            colors.append(np.broadcast_to(np.nan if rgb is None else rgb, (len(f), 3)))
            bones.append(np.full((pos.shape[0], 1), slot))
            wts.append(np.ones((pos.shape[0], 1)))
            n_v += pos.shape[0]
    if not rest_v:
        raise buffers.error("has no triangle mesh attached to its skeleton")
    width = max(b.shape[1] for b in bones)
    pad = [
        (np.pad(b, ((0, 0), (0, width - b.shape[1]))), np.pad(w, ((0, 0), (0, width - w.shape[1]))))
        for b, w in zip(bones, wts)
    ]
    # skins that share joints and bind poses (BrainStem: 59 skins, one skeleton) share slots
    ibm = np.concatenate(ibms, axis=0)
    key = np.concatenate([np.asarray(slot_joint, float)[:, None], ibm.reshape(-1, 16).round(9)], 1)
    _, first, remap = np.unique(key, axis=0, return_index=True, return_inverse=True)
    slots, ibm = np.asarray(slot_joint, dtype=np.int64)[first], ibm[first]
    weights = weight_matrix(
        remap.ravel()[np.vstack([b for b, _ in pad])], np.vstack([w for _, w in pad]), len(first)
    )
    if np.any(np.asarray(weights.sum(axis=1)).ravel() == 0):
        warnings.warn(
            f"{buffers.path}: some vertices have no skin weight; they stay at the origin",
            stacklevel=4,
        )
    rgb = np.vstack(colors)
    return SkinnedMesh(
        rest=np.vstack(rest_v),
        faces=np.vstack(faces).astype(np.int64),
        weights=weights,
        slot_joint=slots,
        inverse_bind=ibm,
        face_rgb=None if np.all(np.isnan(rgb)) else rgb,
        joint_scale=world_scale,
    )


# --------------------------------------------------------------------------- reader


#: The document :func:`_load` read last, by (path, modification time, size): a scene's
#: loading reads one file twice (its characters' names, then each character), and
#: pygltflib's decoding of the JSON is most of a glTF's load (0.5 s for BrainStem).
_LAST: dict[tuple, object] = {}


def _load(path: Path):
    if not path.is_file():
        raise GLTFError("no such file", path=str(path))
    st = path.stat()
    key = (str(path.resolve()), st.st_mtime_ns, st.st_size)
    g = _LAST.get(key)
    if g is None:
        g = _decode(path)
        _LAST.clear()  # one document: a library's worker reads thousands of files
        _LAST[key] = g
    return g


def _decode(path: Path):
    import pygltflib

    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            g = pygltflib.GLTF2().load(str(path))
    except Exception as err:  # pygltflib raises struct, JSON, Unicode, Key... errors alike
        # Attribute and type errors come from inside pygltflib on a damaged GLB container
        # (a header with no JSON chunk): its own wording would name its internals.
        detail = (
            "a damaged GLB container"
            if isinstance(err, (AttributeError, TypeError))
            else f"{type(err).__name__}: {err}"
        )
        raise GLTFError(f"not a readable glTF/GLB file ({detail})", path=str(path)) from err
    if g is None or not isinstance(g.nodes, list):
        raise GLTFError("not a readable glTF/GLB file (no JSON document)", path=str(path))
    if g.asset is not None and g.asset.version and not str(g.asset.version).startswith("2"):
        raise GLTFError(f"glTF version {g.asset.version} is not supported (2.0 is)", path=str(path))
    unknown = [
        e for e in (g.extensionsRequired or []) if not str(e).startswith(_HARMLESS_EXTENSIONS)
    ]
    if unknown:
        raise GLTFError(
            f"requires the extension {', '.join(map(str, unknown))}, which this "
            "reader does not decode (re-export without it)",
            path=str(path),
        )
    return g


def _characters(gltf, parent, order, joint_set) -> list[list[int]]:
    """The skinned characters of a document: its skin joints (nodes, parents first)
    grouped by skeleton. Joints belong together when they hang below one topmost joint,
    or when one skin binds them (BrainStem: 59 skins, one skeleton): two people in one
    file are two groups, ordered by their first joint."""
    joints = [i for i in order if i in joint_set]
    top: dict[int, int] = {}
    for j in joints:  # the topmost joint above j (parents come first)
        a = parent[j]
        while a >= 0 and a not in joint_set:
            a = parent[a]
        top[j] = top[a] if a >= 0 else j
    link = {t: t for t in set(top.values())}

    def find(t):
        while link[t] != t:
            link[t] = link[link[t]]
            t = link[t]
        return t

    for skin in gltf.skins or []:
        tops = [find(top[j]) for j in skin.joints or [] if j in top]
        for t in tops[1:]:
            link[find(t)] = find(tops[0])
    groups: dict[int, list[int]] = {}
    for j in joints:
        groups.setdefault(find(top[j]), []).append(j)
    return sorted(groups.values(), key=lambda grp: joints.index(grp[0]))


def gltf_characters(path) -> list[str]:
    """Names of the skinned characters of a glTF file (the topmost joint of each
    skeleton), in the order ``read_gltf(..., character=k)`` reads them."""
    path = Path(path)
    g = _load(path)
    buffers = Buffers(g, path)
    nodes = g.nodes or []
    if not g.skins:
        raise buffers.error("has no skin: only skinned characters can be read")
    parent = _node_parents(g, buffers)
    joint_set = {j for skin in g.skins for j in skin.joints or [] if 0 <= j < len(nodes)}
    return [
        nodes[grp[0]].name or f"node_{grp[0]}"
        for grp in _characters(g, parent, _topological(parent, buffers), joint_set)
    ]


def read_gltf(
    path,
    *,
    animation: str | int | None = None,
    fps: float | None = None,
    name: str | None = None,
    character: int | None = None,
) -> Character:
    """Read a skinned glTF 2.0 / GLB file as a :class:`Character` carrying its mesh.

    Parameters
    ----------
    path : str or path-like
    animation : str or int, optional
        Animation name (or index); default the first. A file without animations gives
        one frame, the rest pose.
    fps : float, optional
        Sampling rate, frames per second (default :data:`DEFAULT_FPS`).
    name : str, optional
        Character name (default: the file's stem).
    character : int, optional
        Which skinned character of the file (:func:`gltf_characters`); required when
        it holds more than one (each skeleton with the meshes bound to it).

    Returns
    -------
    Character
        Positions (F, J, 3) and rotations in the file's unit (``scale`` 1), its
        ``mesh`` (:class:`~snapcore.motion.skinning.SkinnedMesh`), ``meta`` with
        ``animation`` (the chosen name), ``animations`` (all names) and ``format``
        ``"gltf"``.

    Raises
    ------
    GLTFError
        One line naming the file and what is wrong: unreadable or truncated file, no
        skin, a missing buffer, an unknown interpolation or animation.
    """
    path = Path(path)
    g = _load(path)
    buffers = Buffers(g, path)
    fps = float(fps or DEFAULT_FPS)
    nodes = g.nodes or []
    if not g.skins:
        raise buffers.error("has no skin: only skinned characters can be read")
    parent = _node_parents(g, buffers)
    order = _topological(parent, buffers)
    joint_set = set()
    for si, skin in enumerate(g.skins):
        for j in skin.joints or []:
            if not 0 <= j < len(nodes):
                raise buffers.error(f"skin {si} names joint node {j}, which does not exist")
            joint_set.add(j)
    if not joint_set:
        raise buffers.error("its skins have no joints")
    groups = _characters(g, parent, order, joint_set)
    if character is None and len(groups) > 1:
        names = ", ".join(nodes[grp[0]].name or f"node_{grp[0]}" for grp in groups)
        raise buffers.error(
            f"holds {len(groups)} skinned characters (skeletons {names}); "
            "read them with load_scene, one character each"
        )
    k = character or 0
    if not 0 <= k < len(groups):
        raise buffers.error(f"has no character {k} (it has {len(groups)})")
    joints = groups[k]
    joint_index = {node: k for k, node in enumerate(joints)}
    jparent_list = []
    for node in joints:
        a = parent[node]
        while a >= 0 and a not in joint_index:
            a = parent[a]
        jparent_list.append(joint_index[a] if a >= 0 else -1)
    jparent = np.asarray(jparent_list, dtype=int)

    rest = [np.array(x) for x in zip(*[_local_trs(n) for n in nodes])]  # T, R, S: (N, ·)
    if animation is None and len(groups) > 1:
        animation = _own_animation(g, joints, parent)
    a_idx, a_name = _pick_animation(g, animation, buffers)
    t, r, s = _sample_animation(g, a_idx, buffers, rest, fps, a_name)
    world = node_world_matrices(trs_matrix(t, r, s), parent, order)  # (F, N, 4, 4)
    rest_world = node_world_matrices(trs_matrix(*rest)[None], parent, order)[0]

    frames = joints_from_world(world[:, joints], jparent)  # world: (F, N, 4, 4)
    if not frames["uniform"]:
        warnings.warn(
            f"{path}: joints scale non-uniformly or over time; the mesh follows their "
            "median uniform scale",
            stacklevel=2,
        )
    pos, rot, local_rot = frames["positions"], frames["rotations"], frames["local_rotations"]
    joint_scale, offsets = frames["joint_scale"], frames["offsets"]
    skeleton = Skeleton(
        names=_unique_names([nodes[i].name or f"node_{i}" for i in joints]),
        parents=jparent,
        offsets=offsets,
        end_site=np.zeros(len(joints), dtype=bool),
    )
    mesh = _build_mesh(g, buffers, parent, rest_world, joints, joint_index, joint_scale, joint_set)
    return Character(
        name=name or path.stem,
        skeleton=skeleton,
        positions=pos,
        rotations=rot,
        local_rotations=local_rot,
        fps=fps,
        scale=1.0,
        source=None,
        meta={
            "format": "gltf",
            "path": str(path),
            "animation": a_name,
            "animations": gltf_animations(g),
        },
        local_quaternions=matrix_to_quat(local_rot),
        mesh=mesh,
    )


def _unique_names(names: list[str]) -> tuple[str, ...]:
    """Node names made unique (glTF does not require it; joints are looked up by name):
    a repeated name gets ``_2``, ``_3``... in node order."""
    taken: set[str] = set()
    out = []
    for n in names:
        name, k = n, 1
        while name in taken:  # also past a suffixed name some node already has
            k += 1
            name = f"{n}_{k}"
        taken.add(name)
        out.append(name)
    return tuple(out)


def _mesh_of(character) -> SkinnedMesh:
    if character.mesh is None:
        raise GLTFError(f"character {character.name!r} carries no skinned mesh")
    return character.mesh


def lowest_points(character, *, max_frames: int = 60, per_frame: int = 16) -> np.ndarray:
    """World positions of the mesh vertices that can touch the floor, at every frame.

    The vertices that are among the ``per_frame`` lowest in any of (up to)
    ``max_frames`` sampled frames, skinned at all frames: (F, n, 3), metres. Cheap
    where skinning the whole mesh at every frame is not (BrainStem: 34k vertices).
    """
    mesh = _mesh_of(character)
    f = np.unique(
        np.linspace(0, character.n_frames - 1, min(character.n_frames, max_frames))
        .round()
        .astype(int)
    )
    v = mesh.vertices(character, f)  # (S, V, 3)
    k = min(per_frame, v.shape[1])
    low = np.unique(np.argpartition(v[..., 1], k - 1, axis=1)[:, :k])
    sub = SkinnedMesh(
        mesh.rest[low],
        mesh.faces[:0],
        mesh.weights[low],
        mesh.slot_joint,
        mesh.inverse_bind,
        mesh.joint_scale,
    )
    return sub.vertices(character, np.arange(character.n_frames))


def gltf_unit(character) -> tuple[float, str]:
    """Metres per unit of a glTF character: 1 (``"m"``, as the spec says) unless its
    mesh is taller than :data:`MAX_HEIGHT_M`, then centimetres or millimetres."""
    mesh = _mesh_of(character)
    height = float(np.ptp(mesh.vertices(character, 0)[:, 1]))
    for unit, metres in (("m", 1.0), ("cm", 0.01), ("mm", 0.001)):
        if height * metres <= MAX_HEIGHT_M:
            return metres, unit
    return 0.001, "mm"
