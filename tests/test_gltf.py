"""glTF 2.0 characters: interpolation, accessors, skinning and node transforms, checked by hand.

The two-bone file is written here byte by byte (JSON + a base64 data URI), so every
expected value is computed from numbers the test chose, not from the reader.
"""

from __future__ import annotations

import base64
import json
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from snapcore.errors import GLTFError
from snapcore.motion.gltf import read_gltf
from snapcore.motion.gltf_sample import sample_curve, slerp

# ----------------------------------------------------------------- interpolation


def test_linear_and_step_match_hand_values():
    """LINEAR is the straight line between keys, STEP holds the last key; ends clamp."""
    times = np.array([0.0, 1.0, 3.0])
    values = np.array([[0.0, 0.0, 0.0], [2.0, 4.0, -2.0], [6.0, 4.0, 0.0]])
    t = np.array([-1.0, 0.25, 1.0, 2.0, 2.999, 5.0])
    lin = sample_curve(times, values, "LINEAR", t)
    np.testing.assert_allclose(
        lin,
        [
            [0, 0, 0],
            [0.5, 1, -0.5],
            [2, 4, -2],
            [4, 4, -1],
            [2 + 4 * 0.9995, 4, -2 + 2 * 0.9995],
            [6, 4, 0],
        ],
        atol=1e-12,
    )
    step = sample_curve(times, values, "STEP", t)
    np.testing.assert_allclose(
        step, [[0, 0, 0], [0, 0, 0], [2, 4, -2], [2, 4, -2], [2, 4, -2], [6, 4, 0]], atol=1e-12
    )


def test_cubicspline_is_the_hermite_curve():
    """CUBICSPLINE (glTF Appendix C) at s = 0.5 of a 2 s interval, computed by hand."""
    times = np.array([1.0, 3.0])
    # per key: in-tangent, value, out-tangent
    values = np.array(
        [
            [9.0],
            [1.0],
            [2.0],  # key 0: v = 1, out-tangent b0 = 2
            [-4.0],
            [5.0],
            [9.0],
        ]
    )  # key 1: in-tangent a1 = -4, v = 5
    # s = 0.5, dt = 2: h00 = 0.5, h10 = 0.125, h01 = 0.5, h11 = -0.125
    # p = 0.5*1 + 0.125*2*2 + 0.5*5 + (-0.125)*2*(-4) = 0.5 + 0.5 + 2.5 + 1.0
    got = sample_curve(times, values, "CUBICSPLINE", np.array([2.0, 1.0, 3.0]))
    np.testing.assert_allclose(got[:, 0], [4.5, 1.0, 5.0], atol=1e-12)


def test_linear_rotations_are_slerped_the_short_way():
    """Half-way between 0° and 90° about Z is 45°; a key stored as -q still turns 45°."""
    q0 = np.array([0.0, 0.0, 0.0, 1.0])  # glTF order x, y, z, w
    q1 = np.array([0.0, 0.0, np.sin(np.pi / 4), np.cos(np.pi / 4)])
    half = np.array([0.0, 0.0, np.sin(np.pi / 8), np.cos(np.pi / 8)])
    np.testing.assert_allclose(slerp(q0[None], q1[None], np.array([0.5]))[0], half, atol=1e-12)
    got = sample_curve(
        np.array([0.0, 1.0]), np.stack([q0, -q1]), "LINEAR", np.array([0.5]), rotation=True
    )[0]
    assert abs(abs(got @ half) - 1.0) < 1e-12
    # a third of the way: 30°, not the 1/3 chord (slerp keeps the angular speed)
    third = sample_curve(
        np.array([0.0, 1.0]), np.stack([q0, q1]), "LINEAR", np.array([1 / 3]), rotation=True
    )[0]
    np.testing.assert_allclose(third, [0, 0, np.sin(np.pi / 12), np.cos(np.pi / 12)], atol=1e-12)


def test_unknown_interpolation_is_refused():
    with pytest.raises(ValueError, match="unknown interpolation 'SMOOTH'"):
        sample_curve(np.array([0.0, 1.0]), np.zeros((2, 3)), "SMOOTH", np.array([0.5]))


# ----------------------------------------------------------------- a hand-made file


def _two_bone_document(*, ibm=True, interpolation="LINEAR") -> dict:
    """Joint 0 at the origin, joint 1 one metre up (Y); joint 1 turns 90° about Z in 1 s.

    Mesh A (skin 0, joints [0, 1]): three vertices, interleaved (position float32 x3,
    joints uint8 x4, weights normalised uint8 x4; stride 20):
      v0 (0.5, 0.5, 0) all on joint 0; v1 (1, 1, 0) all on joint 1;
      v2 (1, 1, 0) with weights 128/255 on joint 0 and 127/255 on joint 1, its position
      stored as (9, 9, 9) and corrected by a sparse accessor.
    Mesh B (skin 1, joints [1] only): one triangle at (0, 2, 0), (1, 2, 0), (0, 2, 1)
    on that skin's joint 0 (= node 1).
    The root translates by (0, 0, 2) with STEP at t = 1.
    """
    buf = bytearray()

    def add(data: bytes) -> tuple[int, int]:
        while len(buf) % 4:
            buf.append(0)
        off = len(buf)
        buf.extend(data)
        return off, len(data)

    verts = [
        ((0.5, 0.5, 0.0), (0, 0, 0, 0), (255, 0, 0, 0)),
        ((1.0, 1.0, 0.0), (1, 0, 0, 0), (255, 0, 0, 0)),
        ((9.0, 9.0, 9.0), (0, 1, 0, 0), (128, 127, 0, 0)),
    ]
    inter = b"".join(struct.pack("<3f4B4B", *p, *j, *w) for p, j, w in verts)
    o_int, n_int = add(inter)
    o_idx, n_idx = add(struct.pack("<3H", 0, 1, 2))
    o_spi, n_spi = add(struct.pack("<B", 2))  # sparse index: vertex 2
    o_spv, n_spv = add(struct.pack("<3f", 1.0, 1.0, 0.0))
    bpos = [(0.0, 2.0, 0.0), (1.0, 2.0, 0.0), (0.0, 2.0, 1.0)]
    o_bp, n_bp = add(b"".join(struct.pack("<3f", *p) for p in bpos))
    o_bj, n_bj = add(struct.pack("<12B", *([0, 0, 0, 0] * 3)))
    o_bw, n_bw = add(struct.pack("<12f", *([1.0, 0, 0, 0] * 3)))
    o_bi, n_bi = add(struct.pack("<3H", 0, 1, 2))
    # inverse bind matrices (column-major): joint 0 at the origin, joint 1 at y = 1
    eye = np.eye(4)
    down = np.eye(4)
    down[1, 3] = -1.0
    o_ibm, n_ibm = add(np.stack([eye, down]).transpose(0, 2, 1).astype("<f4").tobytes())
    o_ibm1, n_ibm1 = add(down.T.astype("<f4").tobytes())
    o_t, n_t = add(struct.pack("<2f", 0.0, 1.0))
    s45 = np.sin(np.pi / 4)
    o_rot, n_rot = add(struct.pack("<8f", 0, 0, 0, 1, 0, 0, s45, s45))
    o_tr, n_tr = add(struct.pack("<6f", 0, 0, 0, 0, 0, 2))

    views = [
        {"buffer": 0, "byteOffset": o_int, "byteLength": n_int, "byteStride": 20},
        {"buffer": 0, "byteOffset": o_idx, "byteLength": n_idx},
        {"buffer": 0, "byteOffset": o_spi, "byteLength": n_spi},
        {"buffer": 0, "byteOffset": o_spv, "byteLength": n_spv},
        {"buffer": 0, "byteOffset": o_bp, "byteLength": n_bp},
        {"buffer": 0, "byteOffset": o_bj, "byteLength": n_bj},
        {"buffer": 0, "byteOffset": o_bw, "byteLength": n_bw},
        {"buffer": 0, "byteOffset": o_bi, "byteLength": n_bi},
        {"buffer": 0, "byteOffset": o_ibm, "byteLength": n_ibm},
        {"buffer": 0, "byteOffset": o_ibm1, "byteLength": n_ibm1},
        {"buffer": 0, "byteOffset": o_t, "byteLength": n_t},
        {"buffer": 0, "byteOffset": o_rot, "byteLength": n_rot},
        {"buffer": 0, "byteOffset": o_tr, "byteLength": n_tr},
    ]
    acc = [
        {
            "bufferView": 0,
            "byteOffset": 0,
            "componentType": 5126,
            "count": 3,
            "type": "VEC3",
            "sparse": {
                "count": 1,
                "indices": {"bufferView": 2, "componentType": 5121},
                "values": {"bufferView": 3},
            },
        },  # 0
        {"bufferView": 0, "byteOffset": 12, "componentType": 5121, "count": 3, "type": "VEC4"},
        {
            "bufferView": 0,
            "byteOffset": 16,
            "componentType": 5121,
            "count": 3,
            "type": "VEC4",
            "normalized": True,
        },  # 2
        {"bufferView": 1, "componentType": 5123, "count": 3, "type": "SCALAR"},  # 3
        {"bufferView": 4, "componentType": 5126, "count": 3, "type": "VEC3"},  # 4
        {"bufferView": 5, "componentType": 5121, "count": 3, "type": "VEC4"},  # 5
        {"bufferView": 6, "componentType": 5126, "count": 3, "type": "VEC4"},  # 6
        {"bufferView": 7, "componentType": 5123, "count": 3, "type": "SCALAR"},  # 7
        {"bufferView": 8, "componentType": 5126, "count": 2, "type": "MAT4"},  # 8
        {"bufferView": 9, "componentType": 5126, "count": 1, "type": "MAT4"},  # 9
        {
            "bufferView": 10,
            "componentType": 5126,
            "count": 2,
            "type": "SCALAR",
            "min": [0.0],
            "max": [1.0],
        },  # 10
        {"bufferView": 11, "componentType": 5126, "count": 2, "type": "VEC4"},  # 11
        {"bufferView": 12, "componentType": 5126, "count": 2, "type": "VEC3"},  # 12
    ]
    skin0 = {"joints": [0, 1]}
    skin1 = {"joints": [1]}
    if ibm:
        skin0["inverseBindMatrices"] = 8
        skin1["inverseBindMatrices"] = 9
    return {
        "asset": {"version": "2.0"},
        "scene": 0,
        "scenes": [{"nodes": [0, 2, 3]}],
        "nodes": [
            {"name": "root", "children": [1]},
            {"name": "arm", "translation": [0.0, 1.0, 0.0]},
            {"name": "meshA", "mesh": 0, "skin": 0},
            {"name": "meshB", "mesh": 1, "skin": 1},
        ],
        "meshes": [
            {
                "primitives": [
                    {"attributes": {"POSITION": 0, "JOINTS_0": 1, "WEIGHTS_0": 2}, "indices": 3}
                ]
            },
            {
                "primitives": [
                    {"attributes": {"POSITION": 4, "JOINTS_0": 5, "WEIGHTS_0": 6}, "indices": 7}
                ]
            },
        ],
        "skins": [skin0, skin1],
        "animations": [
            {
                "name": "raise",
                "samplers": [
                    {"input": 10, "output": 11, "interpolation": interpolation},
                    {"input": 10, "output": 12, "interpolation": "STEP"},
                ],
                "channels": [
                    {"sampler": 0, "target": {"node": 1, "path": "rotation"}},
                    {"sampler": 1, "target": {"node": 0, "path": "translation"}},
                ],
            }
        ],
        "accessors": acc,
        "bufferViews": views,
        "buffers": [
            {
                "byteLength": len(buf),
                "uri": "data:application/octet-stream;base64,"
                + base64.b64encode(bytes(buf)).decode(),
            }
        ],
    }


def _write(tmp_path: Path, doc: dict, name="two_bone.gltf") -> Path:
    p = tmp_path / name
    p.write_text(json.dumps(doc))
    return p


def test_two_bone_file_gives_hand_computed_vertices(tmp_path):
    """Interleaved, normalised-uint8, sparse accessors; two skins; LINEAR/STEP channels."""
    c = read_gltf(_write(tmp_path, _two_bone_document()), fps=4.0)  # t = 0, .25, .5, .75, 1
    assert c.n_frames == 5 and c.joint_names == ("root", "arm")
    mesh = c.mesh
    v = mesh.vertices(c, np.arange(5))  # (5, 6, 3): mesh A's 3 vertices, then mesh B's
    w0, w1 = 128 / 255, 127 / 255
    # bind pose (t = 0): the mesh as stored, the sparse vertex corrected
    np.testing.assert_allclose(
        v[0], [[0.5, 0.5, 0], [1, 1, 0], [1, 1, 0], [0, 2, 0], [1, 2, 0], [0, 2, 1]], atol=1e-6
    )
    # t = 0.5: the arm has turned 45° about Z around (0, 1, 0); the root has not moved yet
    c45, s45 = np.cos(np.pi / 4), np.sin(np.pi / 4)
    arm = np.array([c45, 1 + s45, 0.0])  # (1, 0, 0) from the arm joint, turned 45°
    np.testing.assert_allclose(v[2, 0], [0.5, 0.5, 0], atol=1e-6)
    np.testing.assert_allclose(v[2, 1], arm, atol=1e-6)
    np.testing.assert_allclose(v[2, 2], w0 * np.array([1, 1, 0]) + w1 * arm, atol=1e-6)
    # mesh B's (1, 2, 0) is (1, 1, 0) from the arm joint: turned 45° → (c - s, 1 + s + c)
    np.testing.assert_allclose(v[2, 4], [c45 - s45, 1 + s45 + c45, 0], atol=1e-6)
    # t = 1: 90°, and the STEP translation of the root by (0, 0, 2) has happened
    np.testing.assert_allclose(v[4, 1], [0, 2, 2], atol=1e-6)
    np.testing.assert_allclose(
        v[4, 2], w0 * np.array([1, 1, 2]) + w1 * np.array([0, 2, 2]), atol=1e-6
    )
    np.testing.assert_allclose(v[3, 1, 2], 0.0, atol=1e-6)  # STEP: nothing before t = 1
    np.testing.assert_allclose(c.positions[4], [[0, 0, 2], [0, 1, 2]], atol=1e-6)


def test_the_mesh_is_a_typed_field_that_survives_a_frame_cut(tmp_path):
    """The skinned mesh is ``Character.mesh`` (not a ``meta`` key), and a scene cut to a
    frame range, moved or rescaled keeps it, posed at the frames it kept."""
    from snapcore.motion.scene import Scene
    from snapcore.motion.skinning import SkinnedMesh

    c = read_gltf(_write(tmp_path, _two_bone_document()), fps=4.0)
    assert isinstance(c.mesh, SkinnedMesh) and "mesh" not in c.meta
    cut = Scene([c], fps=c.fps).frames(2, 5).characters[0]
    assert cut.mesh is c.mesh and "mesh" not in cut.meta
    np.testing.assert_allclose(cut.mesh.vertices(cut, 0), c.mesh.vertices(c, 2), atol=1e-12)
    for copy in (c.transformed(yaw_deg=30.0), c.rescaled(2.0), c.frames(1, 3)):
        assert copy.mesh is c.mesh


def test_accessors_read_interleaved_normalised_and_sparse_data(tmp_path):
    """The stride-20 view gives each attribute; uint8 weights normalise to k/255; the
    sparse accessor replaces vertex 2's stored (9, 9, 9)."""
    import pygltflib

    from snapcore.motion.gltf_access import Buffers

    p = _write(tmp_path, _two_bone_document())
    b = Buffers(pygltflib.GLTF2().load(str(p)), p)
    np.testing.assert_array_equal(b.accessor(0), [[0.5, 0.5, 0], [1, 1, 0], [1, 1, 0]])
    np.testing.assert_array_equal(b.accessor(1)[:, :2], [[0, 0], [1, 0], [0, 1]])
    np.testing.assert_allclose(b.accessor(2)[:, :2], [[1, 0], [1, 0], [128 / 255, 127 / 255]])
    np.testing.assert_array_equal(
        b.accessor(8)[1], [[1, 0, 0, 0], [0, 1, 0, -1], [0, 0, 1, 0], [0, 0, 0, 1]]
    )  # column-major → rows


def test_missing_inverse_bind_matrices_mean_identity(tmp_path):
    """Without inverseBindMatrices the vertices are in joint space (spec: identity)."""
    c = read_gltf(_write(tmp_path, _two_bone_document(ibm=False)), fps=4.0)
    v = c.mesh.vertices(c, 0)
    # v1 (1, 1, 0) on the arm joint at (0, 1, 0) with no inverse bind: (1, 2, 0)
    np.testing.assert_allclose(v[1], [1, 2, 0], atol=1e-6)
    np.testing.assert_allclose(v[0], [0.5, 0.5, 0], atol=1e-6)  # the root is at the origin


def test_bind_pose_skinning_gives_the_bind_mesh(motions_dir):
    """Posed at the bind pose (joint world = inverse of its inverse bind matrix), every
    vertex of CesiumMan's skinned mesh is where the file stores it (1e-6 m)."""
    from dataclasses import replace

    c = read_gltf(motions_dir / "gltf" / "CesiumMan.glb")
    mesh = c.mesh
    bind = np.linalg.inv(mesh.inverse_bind)  # (K, 4, 4): joint world at bind
    pos = c.positions[:1].copy()
    rot = c.rotations[:1].copy()
    pos[0, mesh.slot_joint] = bind[:, :3, 3]
    rot[0, mesh.slot_joint] = bind[:, :3, :3] / mesh.joint_scale[mesh.slot_joint, None, None]
    at_bind = replace(c, positions=pos, rotations=rot)
    np.testing.assert_allclose(mesh.vertices(at_bind, 0), mesh.rest, atol=1e-6)


def test_cesium_man_joints_match_an_independent_scipy_composition(motions_dir):
    """World positions of CesiumMan's skin joints at several times = node transforms
    composed here with SciPy (Slerp, np.interp, Rotation), not by the reader (1e-6 m)."""
    import pygltflib
    from scipy.spatial.transform import Rotation, Slerp

    path = motions_dir / "gltf" / "CesiumMan.glb"
    g = pygltflib.GLTF2().load(str(path))
    blob = g.binary_blob()

    def read(i):
        a = g.accessors[i]
        bv = g.bufferViews[a.bufferView]
        n = {"SCALAR": 1, "VEC3": 3, "VEC4": 4, "MAT4": 16}[a.type]
        assert a.componentType == 5126 and not bv.byteStride or bv.byteStride == 4 * n
        start = (bv.byteOffset or 0) + (a.byteOffset or 0)
        return np.frombuffer(blob, "<f4", a.count * n, start).reshape(a.count, n).astype(float)

    fps = 30.0
    c = read_gltf(path, fps=fps)
    anim = g.animations[0]
    t0 = min(read(s.input)[0, 0] for s in anim.samplers)
    frames = np.array([0, 7, 23, 40, c.n_frames - 1])
    times = t0 + frames / fps
    parent = {ch: i for i, n in enumerate(g.nodes) for ch in (n.children or [])}

    def local(node, t):
        n = g.nodes[node]
        if n.matrix is not None:
            return np.asarray(n.matrix, float).reshape(4, 4).T
        tr = np.array(n.translation or [0, 0, 0], float)
        rq = np.array(n.rotation or [0, 0, 0, 1], float)
        sc = np.array(n.scale or [1, 1, 1], float)
        for ch in anim.channels:
            if ch.target.node != node:
                continue
            s = anim.samplers[ch.sampler]
            kt, kv = read(s.input)[:, 0], read(s.output)
            tt = np.clip(t, kt[0], kt[-1])
            if ch.target.path == "rotation":
                rq = Slerp(kt, Rotation.from_quat(kv))(tt).as_quat()
            elif ch.target.path == "translation":
                tr = np.array([np.interp(tt, kt, kv[:, k]) for k in range(3)])
            else:
                sc = np.array([np.interp(tt, kt, kv[:, k]) for k in range(3)])
        m = np.eye(4)
        m[:3, :3] = Rotation.from_quat(rq).as_matrix() * sc
        m[:3, 3] = tr
        return m

    def world(node, t):
        m = local(node, t)
        while node in parent:
            node = parent[node]
            m = local(node, t) @ m
        return m

    joints = g.skins[0].joints
    names = [g.nodes[j].name for j in joints]
    for f, t in zip(frames, times):
        want = np.array([world(j, t)[:3, 3] for j in joints])
        got = c.positions[f, [c.joint_names.index(n) for n in names]]
        np.testing.assert_allclose(got, want, atol=1e-6, err_msg=f"frame {f}, t = {t:.4f} s")


# ----------------------------------------------------------------- errors


def _glb(doc: dict, binary: bytes) -> bytes:
    js = json.dumps(doc).encode()
    js += b" " * (-len(js) % 4)
    binary += b"\0" * (-len(binary) % 4)
    body = (
        struct.pack("<II", len(js), 0x4E4F534A)
        + js
        + struct.pack("<II", len(binary), 0x004E4942)
        + binary
    )
    return struct.pack("<III", 0x46546C67, 2, 12 + len(body)) + body


BAD_CASES = {
    "no_skin": "has no skin",
    "missing_buffer": "file 'gone.bin' not found",
    "truncated": "not a readable glTF/GLB file",
    "short_buffer": "buffer 0 is truncated",
    "interpolation": "unknown interpolation 'SMOOTH'",
    # geometry only the extension can decode: its accessors have no data of their own
    "compressed": "requires the extension KHR_draco_mesh_compression",
    # issue 26: an animation whose sampler has no key (was a traceback from min())
    "no_keys": "sampler 0 has no key times",
    # issue 26: garbage bytes over a mesh's positions, inside a valid GLB container
    # (was read: exit 0 and a picture of nothing)
    "garbage": "the binary data is damaged",
    # issue 40: garbage that holds signalling NaNs printed numpy's "invalid value
    # encountered in cast" warning before the error line
    "nan_garbage": "holds non-finite numbers",
}


def _bad_file(tmp_path: Path, case: str) -> Path:
    doc = _two_bone_document()
    if case == "no_skin":
        for n in doc["nodes"]:
            n.pop("skin", None)
        doc.pop("skins")
    elif case == "missing_buffer":
        doc["buffers"][0]["uri"] = "gone.bin"
    elif case in ("truncated", "short_buffer"):
        raw = base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1])
        data = _glb(doc, raw)
        p = tmp_path / f"{case}.glb"
        # cut inside the JSON chunk, or only the end of the binary chunk
        p.write_bytes(data[:150] if case == "truncated" else data[: len(data) - 64])
        return p
    elif case == "interpolation":
        doc = _two_bone_document(interpolation="SMOOTH")
    elif case == "compressed":
        doc["extensionsUsed"] = doc["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    elif case == "no_keys":
        doc["accessors"][10].update(count=0, min=None, max=None)
        doc["accessors"][10] = {k: v for k, v in doc["accessors"][10].items() if v is not None}
    elif case == "nan_garbage":
        # signalling NaNs (exponent all ones, quiet bit clear) over mesh B's positions
        raw = bytearray(base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1]))
        view = doc["bufferViews"][4]
        snan = np.full(view["byteLength"] // 4, 0x7F800001, "<u4").tobytes()
        raw[view["byteOffset"] : view["byteOffset"] + view["byteLength"]] = snan
        p = tmp_path / f"{case}.glb"
        p.write_bytes(_glb(doc, bytes(raw)))
        return p
    elif case == "garbage":
        # mesh B's positions carry their bounds (as the spec requires), then garbage
        doc["accessors"][4].update(min=[0.0, 2.0, 0.0], max=[1.0, 2.0, 1.0])
        raw = bytearray(base64.b64decode(doc["buffers"][0].pop("uri").split(",", 1)[1]))
        view = doc["bufferViews"][4]
        noise = np.random.default_rng(26).normal(0.0, 1e3, view["byteLength"] // 4)
        raw[view["byteOffset"] : view["byteOffset"] + view["byteLength"]] = noise.astype(
            "<f4"
        ).tobytes()
        p = tmp_path / f"{case}.glb"
        p.write_bytes(_glb(doc, bytes(raw)))
        return p
    return _write(tmp_path, doc, f"{case}.gltf")


def test_extensions_that_do_not_change_geometry_are_accepted(tmp_path):
    """Required material/texture extensions do not move a vertex: the file still reads."""
    doc = _two_bone_document()
    doc["extensionsUsed"] = doc["extensionsRequired"] = [
        "KHR_materials_pbrSpecularGlossiness",
        "KHR_texture_transform",
    ]
    assert read_gltf(_write(tmp_path, doc, "materials.gltf")).n_joints == 2


def test_joints_with_the_same_name_stay_apart(tmp_path):
    """glTF node names need not be unique: the character's joint names are."""
    doc = _two_bone_document()
    for n in doc["nodes"]:
        n["name"] = "bone"
    names = read_gltf(_write(tmp_path, doc, "same_names.gltf")).joint_names
    assert len(set(names)) == len(names) == 2 and names[0] == "bone"


@pytest.fixture(scope="module")
def bad_runs(tmp_path_factory):
    """`snapshot info` on every bad file, in ONE subprocess (the CLI's start-up is slow)."""
    d = tmp_path_factory.mktemp("bad_gltf")
    paths = {case: _bad_file(d, case) for case in BAD_CASES}
    code = (
        "import contextlib, io, json, sys\n"
        "from snapcore.cli.main import main\n"
        "for p in sys.argv[1:]:\n"
        "    err = io.StringIO()\n"
        "    with contextlib.redirect_stderr(err):\n"
        "        rc = main(['info', p])\n"
        "    print(json.dumps([p, rc, err.getvalue()]))\n"
    )
    res = subprocess.run(
        [sys.executable, "-c", code, *map(str, paths.values())], capture_output=True, text=True
    )
    assert res.returncode == 0, res.stderr
    out = {p: (rc, err) for p, rc, err in map(json.loads, res.stdout.splitlines())}
    return {case: (p, *out[str(p)]) for case, p in paths.items()}


@pytest.mark.parametrize("case", list(BAD_CASES))
def test_bad_gltf_is_one_line_naming_the_file_exit_2(bad_runs, case):
    """Malformed or unsupported glTF → GLTFError; `snapshot info` prints one line naming
    the file and the problem, exit code 2, no traceback."""
    path, rc, err = bad_runs[case]
    message = BAD_CASES[case]
    with pytest.raises(GLTFError, match=message):
        read_gltf(path)
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert rc == 2
    assert len(lines) == 1 and str(path) in lines[0] and message in lines[0], err
    assert "Traceback" not in err


def test_manifest_mixes_bvh_and_gltf(motions_dir, tmp_path):
    """A scene manifest with a BVH dancer and the glTF Fox: one scene, the Fox sampled at
    the BVH's rate, its animation chosen by name, read in centimetres (it is 80 "m" tall
    in its file), standing on the floor with its paws (mesh), not its joints."""
    manifest = tmp_path / "mixed.json"
    manifest.write_text(
        json.dumps(
            {
                "name": "mixed",
                "characters": [
                    {"file": str(motions_dir / "dance" / "05_06.bvh")},
                    {
                        "file": str(motions_dir / "gltf" / "Fox.glb"),
                        "animation": "Run",
                        "offset": [2, 0, 0],
                    },
                ],
            }
        )
    )
    import warnings

    from snapcore.motion.load import load_scene

    with warnings.catch_warnings(record=True) as rec:
        warnings.simplefilter("always")
        scene = load_scene(manifest, ground=0.0)
    dancer, fox = scene.characters
    assert fox.fps == dancer.fps == 120.0
    assert fox.meta["animation"] == "Run" and fox.meta["unit"] == "cm"
    assert any("read in cm" in str(w.message) for w in rec)
    assert scene.n_frames == min(dancer.n_frames, fox.n_frames)
    # the fox is fox-sized: 0.5-1 m tall, and its mesh carries the offset
    v = fox.mesh.vertices(fox, 0)
    assert 0.5 < np.ptp(v[:, 1]) < 1.0 and 1.5 < v[:, 0].mean() < 2.5
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        alone = load_scene(motions_dir / "gltf" / "Fox.glb", animation="Walk")
    f = alone.characters[0]
    # the ground is where the mesh's lowest points (the paws) are, below every joint
    low = f.mesh.vertices(f, np.arange(alone.n_frames))[..., 1].min(axis=1)
    assert abs(np.percentile(low, 5) - alone.ground) < 1e-9
    assert f.positions[..., 1].min() > alone.ground + 0.005


def test_a_study_scene_chooses_a_gltf_animation(motions_dir, tmp_path, monkeypatch):
    """A study config's scene takes ``animation`` for its glTF characters, as a scene
    manifest and ``--animation`` do (issue 40: the study schema refused it): the Fox's
    "Run" is loaded, not its first animation; on a scene of BVH files only, the key is
    one error naming the scene."""
    from study_app.design.build import load_study_scene
    from study_app.design.protocol import load_study
    from study_app.design.stimuli import StimuliError

    monkeypatch.setenv("SNAPSHOT_DATA", str(motions_dir))
    config = tmp_path / "fox.toml"
    config.write_text(
        '[study]\nid = "fox"\ntitle = "Fox"\ndescription = "A fox."\nvideo_fps = 12\n'
        'size = [160, 120]\npicker = "video"\n\n'
        '[[scenes]]\nid = "fox"\nfiles = ["gltf/Fox.glb"]\nanimation = "Run"\n\n'
        '[[scenes]]\nid = "walk"\nfiles = ["walk_run/02_01.bvh"]\nanimation = "Run"\n',
        encoding="utf-8",
    )
    study = load_study(config)
    scene, doc = load_study_scene(study, study.scenes[0], tmp_path / "work" / "fox")
    assert scene.characters[0].meta["animation"] == "Run"
    assert doc["characters"][0]["animation"] == "Run"
    with pytest.raises(StimuliError, match="scene walk: 'animation'"):
        load_study_scene(study, study.scenes[1], tmp_path / "work" / "walk")


@pytest.mark.slow
def test_stimuli_builder_takes_a_gltf_character(motions_dir, tmp_path):
    """`snapshot stimuli build` on the glTF Fox: a verified folder whose video has one
    frame per 1/video_fps of the clip, and whose three candidate views show the Fox's
    own mesh (many pixels differ from the empty background) from different directions."""
    import os

    from PIL import Image

    from study_app.design.stimuli import load_stimuli

    config = tmp_path / "fox.toml"
    config.write_text(
        '[study]\nid = "fox"\ntitle = "Fox"\ndescription = "A fox."\nvideo_fps = 12\n'
        'size = [160, 120]\npicker = "video"\n\n'
        '[[scenes]]\nid = "fox"\ntitle = "Fox"\nfiles = ["gltf/Fox.glb"]\n',
        encoding="utf-8",
    )
    out = tmp_path / "stimuli"
    env = {**os.environ, "SNAPSHOT_DATA": str(motions_dir)}
    snapshot = str(Path(sys.executable).with_name("snapshot"))
    r = subprocess.run(
        [snapshot, "stimuli", "build", str(config), "-o", str(out), "-q"],
        capture_output=True,
        text=True,
        env=env,
    )
    assert r.returncode == 0, r.stderr
    r = subprocess.run([snapshot, "stimuli", "verify", str(out)], capture_output=True, text=True)
    assert r.returncode == 0, r.stderr
    sc = load_stimuli(out).scenes["fox"]
    assert sc.entry["source"]["files"][0].endswith("Fox.glb")
    assert abs(sc.n_video_frames - sc.n_frames / sc.fps * 12) <= 1
    images = [np.asarray(Image.open(p).convert("RGB"), int) for p in sc.views.values()]
    for im in images:
        corner = im[0, 0]
        assert (np.abs(im - corner).max(axis=-1) > 40).sum() > 500  # the fox is drawn
    assert np.abs(images[0] - images[1]).mean() > 1 or np.abs(images[0] - images[2]).mean() > 1


# ----------------------------------------------------------------- issue 26: the gaps


def test_the_last_key_time_is_sampled(tmp_path):
    """At 2.5 fps a 1 s animation has samples at 0, 0.4, 0.8 s and its last key at
    1 s: the last frame is that key (the arm turned 90° about Z), not 0.8 s (72°)."""
    c = read_gltf(_write(tmp_path, _two_bone_document()), fps=2.5)
    assert c.n_frames == 4
    rz90 = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    np.testing.assert_allclose(c.local_rotations[-1, 1], rz90, atol=1e-6)


def test_animations_with_the_same_name_can_each_be_chosen(tmp_path):
    """Two animations called "raise" are listed as raise and raise_2; the second (only
    the root's step) is read by its name, and its arm does not turn."""
    doc = _two_bone_document()
    second = json.loads(json.dumps(doc["animations"][0]))
    second["channels"] = second["channels"][1:]
    doc["animations"].append(second)
    path = _write(tmp_path, doc, "twice.gltf")
    first = read_gltf(path, animation="raise", fps=4.0)
    other = read_gltf(path, animation="raise_2", fps=4.0)
    assert other.meta["animations"] == ["raise", "raise_2"] and other.meta["animation"] == "raise_2"
    assert not np.allclose(first.local_rotations[-1, 1], np.eye(3))
    np.testing.assert_allclose(
        other.local_rotations[:, 1], np.broadcast_to(np.eye(3), (5, 3, 3)), atol=1e-9
    )


def _two_character_document() -> dict:
    """The two-bone file with mesh B bound to a second skeleton: node ``arm2`` (a joint
    of skin 1 only) under an unanimated ``root2`` 5 m along +X."""
    doc = _two_bone_document()
    doc["nodes"].append({"name": "root2", "translation": [5.0, 0.0, 0.0], "children": [5]})
    doc["nodes"].append({"name": "arm2", "translation": [0.0, 1.0, 0.0]})
    doc["scenes"][0]["nodes"].append(4)
    doc["skins"][1]["joints"] = [5]
    return doc


def test_two_skinned_characters_in_one_file_are_two_characters(tmp_path):
    """A file with two skeletons, each with its own skinned mesh, loads as two
    characters, each wearing only its own mesh (they were merged into one); read alone
    without saying which, it is a one-line error."""
    import warnings

    from snapcore.motion.gltf import gltf_characters
    from snapcore.motion.load import load_scene

    path = _write(tmp_path, _two_character_document(), "pair.gltf")
    assert gltf_characters(path) == ["root", "arm2"]
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(path, fps=4.0, ground=0.0)
    a, b = scene.characters
    assert (a.name, b.name) == ("pair_root", "pair_arm2")
    assert a.joint_names == ("root", "arm") and b.joint_names == ("arm2",)
    assert a.mesh.n_vertices == 3 and b.mesh.n_vertices == 3
    # mesh B on arm2: its bind pose at y = 2 (joint at y = 1, IBM one down), 5 m along X
    vb = b.mesh.vertices(b, 0)
    np.testing.assert_allclose(vb, [[5.0, 2.0, 0.0], [6.0, 2.0, 0.0], [5.0, 2.0, 1.0]], atol=1e-6)
    with pytest.raises(GLTFError, match="holds 2 skinned characters"):
        read_gltf(path)


def test_each_character_of_a_merged_file_plays_its_own_animation(tmp_path):
    """Two characters merged into one file, each with its animation ("raise" moves the
    first's joints, "wave" the second's arm): by default each plays the first animation
    that moves it, and says so (issue 40: the second was reported as playing the first
    character's animation, and stood still); a name given plays for both."""
    import warnings

    from snapcore.motion.load import load_scene

    doc = _two_character_document()
    wave = json.loads(json.dumps(doc["animations"][0]))
    wave["name"] = "wave"
    wave["channels"] = [{"sampler": 0, "target": {"node": 5, "path": "rotation"}}]
    doc["animations"].append(wave)
    path = _write(tmp_path, doc, "merged.gltf")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        a, b = load_scene(path, fps=4.0, ground=0.0).characters
        named = load_scene(path, fps=4.0, ground=0.0, animation="raise").characters[1]
    assert (a.meta["animation"], b.meta["animation"]) == ("raise", "wave")
    assert not np.allclose(b.local_rotations[-1, 0], np.eye(3))  # arm2 turns
    assert named.meta["animation"] == "raise"


def test_material_colours_are_drawn(tmp_path):
    """Mesh A's material is red: its face is drawn red; mesh B has no material and
    wears the character colour (glTF characters used to be one flat colour)."""
    from snapcore.render.bodies import SkinnedBody

    doc = _two_bone_document()
    doc["materials"] = [{"pbrMetallicRoughness": {"baseColorFactor": [1.0, 0.0, 0.0, 1.0]}}]
    doc["meshes"][0]["primitives"][0]["material"] = 0
    c = read_gltf(_write(tmp_path, doc, "red.gltf"))
    body = SkinnedBody(c, color=(0.0, 0.0, 1.0))
    np.testing.assert_array_equal(body.face_colors, [[255, 0, 0, 255], [0, 0, 255, 255]])


def test_video_takes_animation_and_body(tmp_path):
    """`snapshot video` has --animation and --body as every other command: a glTF
    animation name it lacks is a one-line error naming it (exit 2), and a BVH clip
    renders in the mannequin."""
    from click.testing import CliRunner

    from snapcore.cli.main import cli

    path = _write(tmp_path, _two_bone_document(), "two_bone.gltf")
    r = CliRunner().invoke(
        cli, ["video", str(path), "--animation", "nope", "-o", str(tmp_path / "a.mp4")]
    )
    assert r.exit_code == 2 and "no animation 'nope'" in r.output, r.output
    from snapcore.motion.bvh import format_bvh
    from snapcore.motion.synth import humanoid_document

    bvh = tmp_path / "walk.bvh"
    bvh.write_text(format_bvh(humanoid_document("walk", seconds=0.5)))
    out = tmp_path / "walk.mp4"
    r = CliRunner().invoke(
        cli, ["video", str(bvh), "--body", "mannequin", "-o", str(out), "--size", "64x48", "-q"]
    )
    assert r.exit_code == 0, r.output
    assert out.stat().st_size > 0
