"""Action Snapshot in Blender: the story pose and the best view of the active armature.

A Blender 4.2+ extension (``blender_manifest.toml`` beside this file), built by
``snapshot blender-addon -o action_snapshot.zip``. For the active armature and its
action it writes the action to a temporary FBX file with Blender's own exporter, runs
the installed ``snapshot select`` on it (the suite's one implementation of the story
selector and the Projected Motion Area view, so Blender and the command line agree),
then

- puts timeline markers ``snapshot 1``, ``snapshot 2``... on the top-k poses;
- sets up a camera (``Snapshot camera``) along the chosen view, framing the character
  at the chosen frame, and makes it the scene camera;
- (Render still) renders that frame through it.

Frame numbering: ``snapshot`` numbers the exported clip's frames from 0 at the action's
first frame, so Blender frame = action start + snapshot frame. The view comes back in
the suite's Y-up world; the FBX exporter wrote Blender's Z-up scene as Y-up
(``axis_up="Y"``, ``axis_forward="-Z"``), so a snapshot direction ``(x, y, z)`` is
Blender's ``(x, -z, y)``.

Why the installed command rather than bundled wheels: the suite needs SciPy,
pyrender and more, wheels that Blender's extension rules would have us ship for every
platform inside the zip; calling the command keeps one implementation and one install
(``pip install`` of the project), and its path is a setting of the panel.
"""

from __future__ import annotations

import json
import math
import os
import shutil
import subprocess
import tempfile

import bpy
from mathutils import Vector

MARKER_PREFIX = "snapshot "
CAMERA_NAME = "Snapshot camera"
#: The scene property where the last result is kept (JSON: frames, view, method).
RESULT_KEY = "action_snapshot_result"


def blender_direction(view) -> Vector:
    """A snapshot view (unit vector, Y up) as a Blender direction (Z up)."""
    x, y, z = (float(c) for c in view)
    return Vector((x, -z, y)).normalized()


def _action_range(obj) -> tuple[int, int]:
    start, end = obj.animation_data.action.frame_range
    return int(round(start)), int(round(end))


def _export_fbx(context, obj, path: str) -> None:
    """The armature's action, baked over its own frame range, as FBX."""
    scene = context.scene
    old = (scene.frame_start, scene.frame_end, scene.frame_current)
    scene.frame_start, scene.frame_end = _action_range(obj)
    for o in context.view_layer.objects:
        o.select_set(o == obj)
    context.view_layer.objects.active = obj
    try:
        bpy.ops.export_scene.fbx(
            filepath=path,
            use_selection=True,
            object_types={"ARMATURE"},
            # the bones' tips as leaf joints: a BVH's end sites, which its importer
            # made tails, come back where they were (the feet's and hands' extremities)
            add_leaf_bones=True,
            bake_anim=True,
            bake_anim_use_all_actions=False,
            bake_anim_use_nla_strips=False,
            bake_anim_force_startend_keying=True,
            bake_anim_simplify_factor=0.0,
            apply_scale_options="FBX_SCALE_ALL",
            axis_forward="-Z",
            axis_up="Y",
        )
    finally:
        scene.frame_start, scene.frame_end, scene.frame_current = old


def run_snapshot(command: str, path: str, top_k: int, method: str, baselines: bool) -> dict:
    """``snapshot select PATH --json``; its JSON document."""
    exe = shutil.which(command) or command
    args = [exe, "select", path, "--json", "-k", str(top_k), "--pose-method", method]
    if not baselines:
        args.append("--no-baselines")
    done = subprocess.run(args, capture_output=True, text=True, timeout=900)
    if done.returncode != 0:
        lines = (done.stderr or done.stdout).strip().splitlines()
        raise RuntimeError(lines[-1] if lines else f"snapshot exited with {done.returncode}")
    return json.loads(done.stdout)


def _bone_points(obj) -> list[Vector]:
    mw = obj.matrix_world
    pts = []
    for pb in obj.pose.bones:
        pts.append(mw @ pb.head)
        pts.append(mw @ pb.tail)
    return pts


def place_camera(context, obj, frame: int, direction: Vector, margin: float = 1.15):
    """A camera along ``direction`` (from the character towards the camera) framing the
    armature's bones at ``frame``; the scene's camera from now on."""
    scene = context.scene
    scene.frame_set(frame)
    pts = _bone_points(obj)
    lo = Vector([min(p[i] for p in pts) for i in range(3)])
    hi = Vector([max(p[i] for p in pts) for i in range(3)])
    center = (lo + hi) / 2
    radius = max((hi - lo).length / 2, 1e-3)
    cam_obj = bpy.data.objects.get(CAMERA_NAME)
    if cam_obj is None or cam_obj.type != "CAMERA":
        cam_obj = bpy.data.objects.new(CAMERA_NAME, bpy.data.cameras.new(CAMERA_NAME))
        scene.collection.objects.link(cam_obj)
    fov = min(cam_obj.data.angle_x, cam_obj.data.angle_y)
    dist = margin * radius / math.sin(fov / 2)
    cam_obj.location = center + direction * dist
    cam_obj.rotation_mode = "QUATERNION"
    cam_obj.rotation_quaternion = (-direction).to_track_quat("-Z", "Y")
    cam_obj.data.clip_end = max(cam_obj.data.clip_end, dist + 4 * radius)
    scene.camera = cam_obj
    return cam_obj


class ACTIONSNAPSHOT_OT_compute(bpy.types.Operator):
    """Story pose (markers on the top-k poses) and best view (a camera) of the action"""

    bl_idname = "action_snapshot.compute"
    bl_label = "Snapshot the action"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return (
            obj is not None
            and obj.type == "ARMATURE"
            and obj.animation_data is not None
            and obj.animation_data.action is not None
        )

    def execute(self, context):
        scene, obj = context.scene, context.active_object
        settings = scene.action_snapshot
        folder = tempfile.mkdtemp(prefix="action-snapshot-")
        try:
            path = os.path.join(folder, f"{bpy.path.clean_name(obj.name)}.fbx")
            _export_fbx(context, obj, path)
            doc = run_snapshot(
                settings.command, path, settings.top_k, settings.pose_method, settings.baselines
            )
        except (RuntimeError, OSError, ValueError, subprocess.SubprocessError) as err:
            self.report({"ERROR"}, f"snapshot: {err}")
            return {"CANCELLED"}
        finally:
            shutil.rmtree(folder, ignore_errors=True)
        start = _action_range(obj)[0]
        frames = [start + int(f) for f in doc["frames"]]
        for m in [m for m in scene.timeline_markers if m.name.startswith(MARKER_PREFIX)]:
            scene.timeline_markers.remove(m)
        for rank, f in enumerate(frames, 1):
            scene.timeline_markers.new(f"{MARKER_PREFIX}{rank}", frame=f)
        direction = blender_direction(doc["view"])
        place_camera(context, obj, frames[0], direction)
        scene[RESULT_KEY] = json.dumps(
            {
                "frames": frames,
                "snapshot_frames": doc["frames"],
                "view": doc["view"],
                "blender_view": list(direction),
                "pose_method": doc.get("pose_method"),
                "baselines": {k: doc[k] for k in ("motion_area", "viewpoint_entropy") if k in doc},
            }
        )
        self.report({"INFO"}, f"story pose at frame {frames[0]}; top-{len(frames)}: {frames}")
        return {"FINISHED"}


class ACTIONSNAPSHOT_OT_render(bpy.types.Operator):
    """Render the story pose through the snapshot camera"""

    bl_idname = "action_snapshot.render"
    bl_label = "Render still"

    @classmethod
    def poll(cls, context):
        return RESULT_KEY in context.scene and bpy.data.objects.get(CAMERA_NAME) is not None

    def execute(self, context):
        scene = context.scene
        result = json.loads(scene[RESULT_KEY])
        scene.frame_set(result["frames"][0])
        scene.camera = bpy.data.objects[CAMERA_NAME]
        if scene.action_snapshot.output:
            scene.render.filepath = bpy.path.abspath(scene.action_snapshot.output)
        bpy.ops.render.render(write_still=True)
        return {"FINISHED"}


class ActionSnapshotSettings(bpy.types.PropertyGroup):
    command: bpy.props.StringProperty(  # type: ignore[valid-type]
        name="snapshot command",
        description="The installed `snapshot` command (a name on PATH or a full path)",
        default="snapshot",
    )
    top_k: bpy.props.IntProperty(  # type: ignore[valid-type]
        name="Top k", description="How many top poses to mark", default=3, min=1, max=20
    )
    pose_method: bpy.props.EnumProperty(  # type: ignore[valid-type]
        name="Pose method",
        items=[
            ("story", "Story", "The default story selector"),
            ("paper", "Paper", "The paper's pose entropy"),
        ],
        default="story",
    )
    baselines: bpy.props.BoolProperty(  # type: ignore[valid-type]
        name="Baseline views",
        description="Also compute the motion-area and viewpoint-entropy views (slower)",
        default=False,
    )
    output: bpy.props.StringProperty(  # type: ignore[valid-type]
        name="Still",
        description="Where Render still writes",
        default="//snapshot.png",
        subtype="FILE_PATH",
    )


class ACTIONSNAPSHOT_PT_panel(bpy.types.Panel):
    bl_label = "Action Snapshot"
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Snapshot"

    def draw(self, context):
        s = context.scene.action_snapshot
        col = self.layout.column()
        for prop in ("command", "top_k", "pose_method", "baselines"):
            col.prop(s, prop)
        col.operator(ACTIONSNAPSHOT_OT_compute.bl_idname)
        col.prop(s, "output")
        col.operator(ACTIONSNAPSHOT_OT_render.bl_idname)
        if RESULT_KEY in context.scene:
            r = json.loads(context.scene[RESULT_KEY])
            col.label(text=f"story pose: frame {r['frames'][0]}")
            col.label(text="top-k: " + ", ".join(map(str, r["frames"])))


CLASSES = (
    ActionSnapshotSettings,
    ACTIONSNAPSHOT_OT_compute,
    ACTIONSNAPSHOT_OT_render,
    ACTIONSNAPSHOT_PT_panel,
)


def register():
    for cls in CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Scene.action_snapshot = bpy.props.PointerProperty(type=ActionSnapshotSettings)


def unregister():
    del bpy.types.Scene.action_snapshot
    for cls in reversed(CLASSES):
        bpy.utils.unregister_class(cls)
