"""Benchmark cases of the bodies (issue 15): skinning the human mesh, glTF characters,
viewpoint entropy on human bodies. Registered with :func:`snapcore.bench.registry.case`
like :mod:`snapcore.bench.cases`; the stills and videos there draw the human bodies too
(the default body).

Targets (issue 41, one core; issue 15's were 60 s and 3 s): the 1000-frame 1280x720
video of the two salsa dancers with human bodies <= 20 s (the video case in
:mod:`snapcore.bench.cases`); viewpoint entropy over 162 views of the two human bodies
<= 0.5 s; skinning both bodies over all 2,242 frames <= 1 s.
"""

from __future__ import annotations

from snapcore.bench.registry import BenchContext, case

#: Frames skinned per call when skinning a whole clip (bounds the memory of the output).
SKIN_CHUNK = 128


@case(
    "skin: two salsa human bodies, all 2242 frames",
    target_ms=1000.0,
    note="retargeted MakeHuman mesh (2 x 13,380 vertices) posed by dual-quaternion skinning "
    f"in float32 as drawn, bone matrices included, {SKIN_CHUNK} frames per call; "
    "retargeting itself not timed",
)
def _skin_salsa(ctx: BenchContext):
    scene = ctx.salsa()
    if scene is None:
        return None
    from snapcore.render.human import DRAW_DTYPE, HumanBody

    bodies = [HumanBody(c) for c in scene.characters]

    def work():
        for b in bodies:
            c = b.character
            for a in range(0, c.n_frames, SKIN_CHUNK):
                b.skin(
                    c.positions[a : a + SKIN_CHUNK],
                    c.rotations[a : a + SKIN_CHUNK],
                    dtype=DRAW_DTYPE,
                )

    return work


@case(
    "viewpoint entropy 162 views, two human bodies",
    target_ms=500.0,
    note="salsa pair at frame 900, 2 x 26,756 faces; face-id renders at 256² + entropies",
)
def _entropy_human_salsa(ctx: BenchContext):
    scene = ctx.salsa()
    if scene is None:
        return None
    from types import SimpleNamespace

    from snapcore.render.bodies import posed_mesh
    from snapcore.render.viewpoint_entropy import select_view_entropy

    m = posed_mesh(scene, 900, kind="human")
    mesh = SimpleNamespace(vertices=m.vertices, faces=m.faces)
    return lambda: select_view_entropy(None, 0, mesh=mesh, min_elevation_deg=None)


@case(
    "glTF: read CesiumMan.glb (sample at 30 fps, mesh, ground)",
    note="pygltflib parse + accessors + node FK + unit and ground from the skinned mesh",
)
def _read_cesium(ctx: BenchContext):
    p = ctx.path("gltf/CesiumMan.glb")
    if p is None:
        return None
    from snapcore.motion.load import load_scene

    return lambda: load_scene(p)
