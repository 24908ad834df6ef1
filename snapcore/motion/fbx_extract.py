"""The FBX extraction worker: one FBX file → plain arrays (an ``.npz``), in a child process.

Run by :func:`snapcore.motion.fbx.read_fbx` as ``python -m snapcore.motion.fbx_extract IN
OUT [--animation A] [--fps F]``; never imported by the suite. It is the only code that
touches the ufbx binding (the ``ufbx`` package, a generated binding of the ufbx C loader;
why this one: ``docs/fbx.md``).

Why a child process: ufbx 0.0.5's Python wrappers of FBX nodes are returned without
their reference being counted when the same node is asked for twice (``nodes[4]`` twice,
or a node's ``parent``), and its garbage collection of a scene crashes the interpreter
(a segmentation fault, reproduced in ``docs/fbx.md``). Here every node wrapper is kept
alive for the worker's whole life, the cyclic collector is off, and the worker leaves
by ``os._exit`` after writing its arrays, so nothing is ever freed; a crash of the
binding on a hostile file is this process's exit code, which the reader turns into one
line. Exit codes: 0 written; 3 a refused file (the message on stderr, one line).

What it writes (names of the ``.npz`` arrays):

- ``meta``: JSON (FBX version, ASCII or binary, unit in metres, fps, original up axis,
  the animation stacks' names and time spans, the chosen stack, warnings);
- ``node_parent`` (N,), ``node_name`` (N,), ``node_bone`` (N,) bool, ``node_inherit``
  (N,): the node tree (index 0 is the root), as ufbx orders it (parents first);
- ``rest_world`` (N, 4, 4): node-to-world at load (the file's default pose);
- ``local`` (F, N, 10): each node's local translation, rotation (quaternion x, y, z,
  w) and scale at every sample time of the chosen stack, and ``times`` (F,) seconds;
- per mesh instance ``m``: ``mesh{m}_node``, ``_vertices`` (V, 3), ``_triangles``
  (T, 3), ``_geometry_to_node`` (4, 4), and when skinned ``_skin_vertices`` (V, 3)
  (first weight, count, DQ weight), ``_skin_weights`` (W, 2) (cluster, weight),
  ``_cluster_node`` (C,), ``_geometry_to_bone`` (C, 4, 4).
"""

from __future__ import annotations

import gc
import json
import os
import sys

import numpy as np

_KEEP: list = []  # every wrapper the worker was handed: never released (see above)


def _matrix(m) -> np.ndarray:
    """ufbx's affine matrix (four column vectors) → 4 × 4."""
    out = np.eye(4)
    out[:3, :4] = np.asarray(tuple(m), dtype=float).T
    return out


def _refuse(message: str) -> None:
    sys.stderr.write(message.replace("\n", " ") + "\n")
    sys.stderr.flush()
    os._exit(3)


def _triangles(faces: np.ndarray, vertex_indices: np.ndarray) -> np.ndarray:
    """Fan triangulation of every polygon (index_begin, count) into vertex indices."""
    faces = faces.astype(np.int64).reshape(-1, 2)
    faces = faces[faces[:, 1] >= 3]
    n_tri = faces[:, 1] - 2
    first = np.repeat(faces[:, 0], n_tri)
    k = np.arange(n_tri.sum()) - np.repeat(np.cumsum(n_tri) - n_tri, n_tri) + 1
    corners = np.stack([first, first + k, first + k + 1], axis=1)
    return vertex_indices[corners]


def _pick_stack(stacks, animation: str | None) -> int:
    names = [s.name for s in stacks]
    if animation is None:
        return 0
    if animation in names:
        return names.index(animation)
    if animation.isdigit() and int(animation) < len(names):
        return int(animation)
    _refuse(f"no animation '{animation}' (it has: {', '.join(names)})")
    return -1


def extract(path: str, out: str, animation: str | None, fps: float | None) -> None:
    import ufbx

    gc.disable()
    try:
        scene = ufbx.load_file(path, target_axes=ufbx.axes_right_handed_y_up)
    except ufbx.UfbxError as err:
        _refuse(f"not a readable FBX file ({type(err).__name__}: {err})")
    except Exception as err:  # the binding's own failures, named, never a traceback
        _refuse(f"not a readable FBX file ({type(err).__name__}: {err})")
    _KEEP.append(scene)
    md = scene.metadata
    if md.file_format != ufbx.FileFormat.FBX:
        _refuse("not an FBX file")
    nodes = [scene.nodes[i] for i in range(len(scene.nodes))]
    _KEEP.extend(nodes)
    index = {n.typed_id: i for i, n in enumerate(nodes)}
    parent = np.full(len(nodes), -1, dtype=np.int64)
    for i, n in enumerate(nodes):
        for c in n.children:
            _KEEP.append(c)
            parent[index[c.typed_id]] = i
    bone = np.array([n.bone is not None for n in nodes], dtype=bool)
    inherit = np.array([int(n.inherit_mode) for n in nodes], dtype=np.int64)
    arrays: dict[str, np.ndarray] = {
        "node_parent": parent,
        "node_name": np.array([n.name for n in nodes], dtype=object).astype(str),
        "node_inherit": inherit,
        "rest_world": np.stack([_matrix(n.node_to_world) for n in nodes]),
    }
    stacks = [scene.anim_stacks[i] for i in range(len(scene.anim_stacks))]
    _KEEP.extend(stacks)
    settings = scene.settings
    raw_fps = float(settings.frames_per_second or 0.0)
    file_fps = raw_fps
    if file_fps and abs(file_fps - round(file_fps)) < 1e-4 * file_fps:
        # a whole rate written as a custom float (Blender: 120 fps as 120.0048); the
        # file's key times are on its own time base, so it is sampled on that one
        file_fps = float(round(file_fps))
    rate = float(fps or file_fps or 30.0)
    step = float(fps or raw_fps or 30.0)
    meta: dict = {
        "version": int(md.version),
        "ascii": bool(md.ascii),
        "unit_meters": float(settings.unit_meters),
        "file_fps": file_fps,
        "fps": rate,
        "up_axis": int(settings.original_axis_up),
        "creator": str(md.creator),
        "animations": [s.name for s in stacks],
        "spans": [[float(s.time_begin), float(s.time_end)] for s in stacks],
        "warnings": [str(w.description) for w in md.warnings],
    }
    if stacks:
        k = _pick_stack(stacks, animation)
        stack = stacks[k]
        anim = stack.anim
        _KEEP.append(anim)
        t0, t1 = float(stack.time_begin), float(stack.time_end)
        # key times are often stored in single precision (67 frames as 66.99993): a
        # thousandth of a frame short of a whole frame is that frame
        count = max(1, int(np.floor((t1 - t0) * step + 1e-3)) + 1)
        times = t0 + np.arange(count) / step
        local = np.empty((count, len(nodes), 10))
        for fi, t in enumerate(times):  # ufbx evaluates one time per call
            for ni, n in enumerate(nodes):
                tr = ufbx.evaluate_transform(anim, n, float(t))
                local[fi, ni, 0:3] = tr.translation
                local[fi, ni, 3:7] = tr.rotation
                local[fi, ni, 7:10] = tr.scale
        arrays["local"], arrays["times"] = local, times
        meta["animation"] = stack.name
        meta["animation_index"] = k
    used_bones: set[int] = set()
    m = 0
    for mi in range(len(scene.meshes)):
        mesh = scene.meshes[mi]
        _KEEP.append(mesh)
        verts = np.array(mesh.vertices, dtype=float).reshape(-1, 3)
        tris = _triangles(np.array(mesh.faces), np.array(mesh.vertex_indices, dtype=np.int64))
        skins = [mesh.skin_deformers[i] for i in range(len(mesh.skin_deformers))]
        _KEEP.extend(skins)
        for inst in mesh.instances:
            _KEEP.append(inst)
            key = f"mesh{m}"
            arrays[f"{key}_node"] = np.array(index[inst.typed_id])
            arrays[f"{key}_vertices"] = verts
            arrays[f"{key}_triangles"] = tris
            arrays[f"{key}_geometry_to_node"] = _matrix(inst.geometry_to_node)
            if skins:
                sk = skins[0]
                clusters = [sk.clusters[i] for i in range(len(sk.clusters))]
                _KEEP.extend(clusters)
                cnodes = []
                for c in clusters:
                    b = c.bone_node
                    _KEEP.append(b)
                    cnodes.append(-1 if b is None else index[b.typed_id])
                used_bones.update(x for x in cnodes if x >= 0)
                arrays[f"{key}_skin_vertices"] = np.array(sk.vertices, dtype=float)
                arrays[f"{key}_skin_weights"] = np.array(sk.weights, dtype=float)
                arrays[f"{key}_cluster_node"] = np.array(cnodes, dtype=np.int64)
                arrays[f"{key}_geometry_to_bone"] = np.stack(
                    [_matrix(c.geometry_to_bone) for c in clusters]
                ).reshape(-1, 4, 4)
                meta.setdefault("skinning", []).append(int(sk.skinning_method))
            m += 1
    # joints: FBX skeleton nodes (LimbNode) and any node a skin binds to
    bone[list(used_bones)] = True
    arrays["node_bone"] = bone
    arrays["meta"] = np.array(json.dumps(meta))
    with open(out, "wb") as fh:
        np.savez(fh, **arrays)  # type: ignore[arg-type]


def main(argv: list[str]) -> None:
    path, out = argv[0], argv[1]
    animation = fps = None
    rest = argv[2:]
    while rest:
        flag, value, rest = rest[0], rest[1], rest[2:]
        if flag == "--animation":
            animation = value
        elif flag == "--fps":
            fps = float(value)
    extract(path, out, animation, fps)
    sys.stdout.flush()
    os._exit(0)  # never let the binding's objects be freed (see the module notes)


if __name__ == "__main__":
    main(sys.argv[1:])
