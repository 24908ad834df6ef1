"""The glTF reader keeps the document it decoded last: a scene's load reads its file
twice (the characters' names, then each character) and decodes it once; a file written
again is decoded again."""

from __future__ import annotations

import json

import numpy as np
from test_gltf import _two_bone_document, _write


def test_a_scene_decodes_its_gltf_once_and_a_rewritten_file_again(tmp_path, monkeypatch):
    """Loading a scene reads the file twice (its characters, then each character); the
    JSON is decoded once. A file written again between loads is decoded again."""
    import os

    import snapcore.motion.gltf as gltf
    from snapcore.motion.load import load_scene

    decoded = []
    real = gltf._decode
    monkeypatch.setattr(gltf, "_decode", lambda p: decoded.append(p) or real(p))
    monkeypatch.setattr(gltf, "_LAST", {})
    path = _write(tmp_path, _two_bone_document())
    first = load_scene([str(path)])
    assert len(decoded) == 1
    doc = _two_bone_document()
    doc["nodes"][1]["translation"] = [0.0, 2.0, 0.0]  # a longer second bone
    path.write_text(json.dumps(doc))
    st = path.stat()
    os.utime(path, ns=(st.st_atime_ns, st.st_mtime_ns + 10**9))
    second = load_scene([str(path)])
    assert len(decoded) == 2
    assert not np.allclose(first.characters[0].positions, second.characters[0].positions)
