"""Regenerate the README pictures: ``python -m snapcore.cli.readme_images [OUT_DIR]``.

Writes into ``docs/images/`` (or OUT_DIR), from the real CMU modern-dance clip
``dance/05_06.bvh`` of the motion data folder (``SNAPSHOT_DATA``):

- ``contact_sheet.png`` — the three most informative poses (story information), side by side,
  seen from the selected view (the paper's Fig. 5 strip);
- ``three_views.png`` — the selected pose from ours (projected motion area), viewpoint
  entropy and motion area, same panel size and scale (the paper's Fig. 8-10);
- ``relief.png`` — the raking-light preview of the bas-relief of that pose from our
  view (``snapshot relief``'s default; the paper's Fig. 11-12);
- ``body_*.png`` — the human body beside the mannequin on one skeleton of each family
  (:data:`BODY_CLIPS`: Bandai, CMU, Daz/Poser, a glTF character), the same camera.

Everything comes from the pipeline (:func:`snapcore.pipeline.take_snapshot`); a view a
module cannot give yet is left out (and said so on stderr).
"""

from __future__ import annotations

import sys
import warnings
from pathlib import Path

from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

__all__ = ["make_readme_images", "make_body_images", "body_caption", "CLIP", "BODY_CLIPS"]

#: The clip shown in the README (relative to the motion data folder).
CLIP = "dance/05_06.bvh"
#: Panel size of both pictures, pixels.
PANEL = (420, 480)
#: The body pictures: (file name, clip files, source frame, motion fps or None, title).
BODY_CLIPS = (
    (
        "body_bandai_run.png",
        ("walk_run/dataset-2_run_normal_001.bvh",),
        20,
        None,
        "Bandai Namco run (identity rest pose), frame 20",
    ),
    (
        "body_bandai_punch.png",
        ("boxing_jump/dataset-1_punch_normal_001.bvh",),
        60,
        None,
        "Bandai Namco punch, frame 60",
    ),
    ("body_cmu.png", ("walk_run/131_01.bvh",), 300, None, "CMU 131_01 (3ds Max naming), frame 300"),
    (
        "body_daz.png",
        ("two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh"),
        525,
        60,
        "Daz/Poser salsa pair (eye joints), frame 525",
    ),
    (
        "body_gltf.png",
        ("gltf/BrainStem.glb",),
        300,
        None,
        "glTF BrainStem: its own skinned mesh and material colours, frame 300",
    ),
)
#: Panel size of the body pictures, pixels.
BODY_PANEL = (300, 330)


def make_readme_images(out_dir="docs/images", *, clip: str = CLIP, panel=PANEL) -> list[Path]:
    """Render the README's contact sheet, three-view comparison and relief; returns the paths."""
    from snapcore.cli.render import pipeline_picks
    from snapcore.motion.load import data_dir, load_scene
    from snapcore.relief.scene import relief_from_scene
    from snapcore.render.composites import compare_views, contact_sheet
    from snapcore.render.renderer import save_png

    path = data_dir(required=True) / clip
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene(path)
    picks = pipeline_picks(scene, k=3)
    views = picks["views"]
    missing = [m.label for m in VIEW_METHODS if m not in views]
    if missing:
        print(f"note: no {', '.join(missing)} view available; shown without it", file=sys.stderr)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    name = Path(clip).stem
    sheet_view = views.get(ViewMethod.OURS)
    sheet = contact_sheet(
        scene,
        picks["frames"],
        view=sheet_view,
        captions=picks["captions"],
        size=panel,
        title=f"CMU {name}: the three most informative poses (story information), selected view",
    )
    frame = picks["frame"]
    labels = {ViewMethod.OURS: "ours (projected motion area)"}  # the README's panel names
    cmp = compare_views(
        scene,
        frame,
        {labels.get(m, m.label): v for m, v in views.items()},
        size=panel,
        title=f"CMU {name}, frame {frame}: the selected pose from each method's view",
    )
    paths = [out / "contact_sheet.png", out / "three_views.png", out / "relief.png"]
    save_png(sheet, paths[0])
    save_png(cmp, paths[1])
    if sheet_view is not None:
        relief_from_scene(scene, frame, sheet_view).write_preview(paths[2])
    return [p for p in paths if p.exists()]


def body_caption(scene, kind: str) -> str:
    """What a body picture of ``scene`` drawn as ``kind`` shows: a glTF character's own
    mesh is not the MakeHuman "human body" (the glTF picture said it was)."""
    if kind == "mannequin":
        return "mannequin"
    own = [c.mesh is not None for c in scene.characters]
    if kind == "human" and all(own):
        return "its own mesh"
    if kind == "human" and any(own):
        return "own meshes and human body"
    return "human body"


def make_body_images(out_dir="docs/images", *, panel=BODY_PANEL) -> list[Path]:
    """Render the README's body pictures (:data:`BODY_CLIPS`): on each, the human body
    (a glTF character's own mesh) and the mannequin, from one camera fitted to both."""
    import numpy as np

    from snapcore.motion.load import data_dir, load_scene
    from snapcore.render.bodies import BodyKind, scene_body
    from snapcore.render.camera import default_view, fit_camera
    from snapcore.render.composites import tile_panels
    from snapcore.render.renderer import SceneRenderer, save_png

    root = data_dir(required=True)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for name, files, source_frame, fps, title in BODY_CLIPS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            scene = load_scene([root / f for f in files], fps=fps)
        frame = int(source_frame) - scene.frame_offset
        kinds: tuple[BodyKind, ...] = ("human", "mannequin")
        bodies = [scene_body(scene, kind=k) for k in kinds]  # one loaded scene, both kinds
        pts = np.vstack([b.vertices(frame) for b in bodies])
        cam = fit_camera(pts, default_view(scene), size=panel)
        panels = [SceneRenderer(scene, size=panel, body=b).render(frame, cam) for b in bodies]
        sheet = tile_panels(panels, [body_caption(scene, k) for k in kinds], title=title)
        paths.append(out / name)
        save_png(sheet, paths[-1])
    return paths


def main(argv=None) -> int:
    argv = sys.argv[1:] if argv is None else argv
    for p in make_readme_images(*(argv[:1] or [])):
        print(p)
    for p in make_body_images(*(argv[:1] or [])):
        print(p)
    return 0


if __name__ == "__main__":
    sys.exit(main())
