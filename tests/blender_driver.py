"""Run inside a Python with the ``bpy`` module (Blender 4.2): for each shared BVH clip,
import it with Blender's own BVH importer, export the armature with Blender's own FBX
exporter, run the Action Snapshot add-on's operator, and write what Blender shows.

Usage: ``python tests/blender_driver.py SPEC.json`` with SPEC ``{"addon": zip,
"snapshot": command, "out": result.json, "clips": [{"bvh": path, "scale": metres per
unit, "fbx": path}, ...], "pair": path}``; ``pair`` (optional): the first two clips'
armatures side by side, exported to one FBX file. Run by ``tests/test_blender.py`` in its own process (bpy
is a whole Blender: kept out of the test process).
"""

from __future__ import annotations

import importlib
import json
import os
import sys
import tempfile
import zipfile


def main(spec_path: str) -> None:
    import bpy
    from mathutils import Vector

    spec = json.loads(open(spec_path, encoding="utf-8").read())
    folder = tempfile.mkdtemp(prefix="addon-")
    with zipfile.ZipFile(spec["addon"]) as zf:
        zf.extractall(f"{folder}/action_snapshot")
    sys.path.insert(0, folder)
    addon = importlib.import_module("action_snapshot")
    addon.register()
    results = []
    for clip in spec["clips"]:
        bpy.ops.wm.read_homefile(use_empty=True)
        bpy.ops.import_anim.bvh(
            filepath=clip["bvh"],
            global_scale=float(clip["scale"]),
            update_scene_fps=True,
            update_scene_duration=True,
            rotate_mode="NATIVE",
        )
        arm = next(o for o in bpy.data.objects if o.type == "ARMATURE")
        bpy.context.view_layer.objects.active = arm
        addon._export_fbx(bpy.context, arm, clip["fbx"])
        scene = bpy.context.scene
        scene.action_snapshot.command = spec["snapshot"]
        scene.action_snapshot.top_k = 3
        done = bpy.ops.action_snapshot.compute()
        cam = scene.camera
        forward = cam.matrix_world.to_quaternion() @ Vector((0.0, 0.0, -1.0))
        back = -forward  # from the character towards the camera, Blender Z up
        markers = sorted(
            (m.name, m.frame) for m in scene.timeline_markers if m.name.startswith("snapshot ")
        )
        # the camera frames the character: the bones' centre at the story pose is ahead
        scene.frame_set(markers[0][1])
        pts = [arm.matrix_world @ pb.head for pb in arm.pose.bones]
        centre = sum(pts, Vector()) / len(pts)
        to_centre = (centre - cam.location).normalized()
        results.append(
            {
                "bvh": clip["bvh"],
                "operator": sorted(done),
                "action_start": int(round(arm.animation_data.action.frame_range[0])),
                "markers": markers,
                "camera_view": [back.x, back.z, -back.y],  # as snapshot's Y-up vector
                "centre_angle_deg": float(forward.angle(to_centre)) * 57.29577951308232,
                "result": json.loads(scene["action_snapshot_result"]),
            }
        )
    if spec.get("pair"):  # two armatures in one scene, exported to one FBX file
        bpy.ops.wm.read_homefile(use_empty=True)
        for k, clip in enumerate(spec["clips"][:2]):
            bpy.ops.import_anim.bvh(filepath=clip["bvh"], global_scale=float(clip["scale"]))
            bpy.context.view_layer.objects.active.location.x = 2.0 * k
        bpy.ops.export_scene.fbx(
            filepath=spec["pair"],
            object_types={"ARMATURE"},
            add_leaf_bones=False,
            bake_anim_use_all_actions=False,  # one take playing both armatures' actions
            bake_anim_use_nla_strips=False,
            bake_anim_simplify_factor=0.0,  # every frame's key, none reduced
        )
    with open(spec["out"], "w", encoding="utf-8") as fh:
        json.dump(results, fh)


if __name__ == "__main__":
    main(sys.argv[1])
    sys.stdout.flush()
    os._exit(0)  # bpy 4.2 can crash while tearing itself down; the results are written
