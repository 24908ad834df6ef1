"""A small library of short synthetic clips for the batch tests (seconds to process)."""

from __future__ import annotations

from pathlib import Path

from snapcore.motion import synth
from snapcore.motion.bvh import format_bvh, write_bvh


def make_library(root: Path, *, broken: bool = True) -> Path:
    """Two clips in two folders, a two-character manifest whose members are not run
    alone, a JSON file that is not a manifest, and (``broken``) a truncated BVH, a text
    file named .bvh and a .glb."""
    (root / "walks").mkdir(parents=True)
    (root / "jumps").mkdir()
    (root / "duo").mkdir()
    write_bvh(synth.humanoid_document("walk", seconds=1.5), root / "walks" / "walk.bvh")
    write_bvh(synth.humanoid_document("jump", seconds=2.0), root / "jumps" / "jump.bvh")
    write_bvh(synth.humanoid_document("punch", seconds=1.5), root / "duo" / "a.bvh")
    write_bvh(synth.humanoid_document("idle", seconds=1.5, facing_deg=180), root / "duo" / "b.bvh")
    (root / "duo" / "duo.toml").write_text(
        'name = "duo"\nscale = 1.0\n[[characters]]\nfile = "a.bvh"\n'
        '[[characters]]\nfile = "b.bvh"\noffset = [0.0, 0.0, 1.2]\n',
        encoding="utf-8",
    )
    (root / "notes.json").write_text('{"hello": "not a scene"}\n', encoding="utf-8")
    if broken:
        text = format_bvh(synth.humanoid_document("kick", seconds=1.5))
        (root / "jumps" / "truncated.bvh").write_text(text[: len(text) * 2 // 3], encoding="utf-8")
        (root / "notes.bvh").write_text("shopping list: milk, eggs\n", encoding="utf-8")
        (root / "model.glb").write_bytes(b"glTF\x02\x00\x00\x00" + bytes(64))
    return root
