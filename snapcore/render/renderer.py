"""Offscreen rendering, headless: stills and the per-frame scene renderer.

Everything people look at comes from here: stills and the per-frame renderer
(:class:`SceneRenderer`) used by videos (:mod:`snapcore.render.video`) and composites
(:mod:`snapcore.render.composites`). Depth maps (for the relief) and face-id buffers (for
the viewpoint-entropy baseline) are in :mod:`snapcore.render.buffers`. Cameras and
framing are in :mod:`snapcore.render.camera`, the OpenGL contexts (a bare Mesa EGL
context per thread; pyrender's for :func:`render_mesh` only) in
:mod:`snapcore.render.gl`, and the drawing (raw GL, as pyrender drew, without
importing it) in :mod:`snapcore.render.raster`.

Conventions
-----------
- World: metres, Y up. A *view* is a unit vector from the scene centre to the camera;
  camera bases follow :func:`~snapcore.render.camera.view_basis` (Y up in the picture, −Z up
  when looking straight down).
- Images are row-major ``(H, W[, 3])`` uint8 with row 0 at the top.
- The public functions (:func:`render_still`, the composites, the video, the relief)
  take *source* frames, the file's own numbering (``Snapshot.source_frame``,
  ``scene.source_frame(i)``): a frame a user reads is the frame a user passes. Internal
  indices into the scene's (cut) arrays (0 = first frame after the lead-in cut) are
  named ``index`` (:meth:`SceneRenderer.render`, the bodies' ``vertices``).
- A :class:`SceneRenderer` must be used on the thread that made it (EGL contexts are
  thread-bound); every thread gets its own context.
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Iterator, Sequence
from contextlib import AbstractContextManager, nullcontext
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import RenderError
from snapcore.render.bodies import DEFAULT_BODY, BodyKind, scene_body
from snapcore.render.camera import (
    POLE_COS,
    Camera,
    check_size,
    default_view,
    fit_camera,
    gl_camera_pose,
    gl_node_matrix,
    gl_projection,
    motion_points,
    ortho_box,
    view_basis,
)
from snapcore.render.gl import gl_renderer, load_pyrender
from snapcore.render.mannequin import SceneBody
from snapcore.render.raster import DrawMesh, Light, Pending, submit

if TYPE_CHECKING:
    from snapcore.motion.scene import Scene

__all__ = [
    "SceneRenderer",
    "render_still",
    "scene_index",
    "render_mesh",
    "save_png",
    "BACKGROUND",
]

#: Background ("sky") colour of stills and videos (sRGB 0-1): near white.
BACKGROUND = (0.975, 0.975, 0.975)


# --------------------------------------------------------------------------- stills


#: Floor: grid spacing (m), line half-width (m), radius (m) over which grid lines fade
#: into the floor colour.
GRID_SPACING = 0.5
GRID_LINE_HALF_WIDTH = 0.006
GRID_FADE_RADIUS = 7.0
#: Distance (m) from the motion's centre to the sky backdrop (beyond the grid's fade).
SKY_DISTANCE = 40.0
#: Orthographic views flatter than this (degrees above the horizon) show a horizon at
#: the characters' feet; steeper ones see only floor (see :func:`_sky_mesh`).
ORTHO_HORIZON_DEG = 4.0
#: How a renderer shows the floor. "auto": each view as it looks best alone (the grid
#: and shadows from above; a horizon at the feet in orthographic views within
#: :data:`ORTHO_HORIZON_DEG` of level; nothing of the floor from below, where the grid
#: and shadows would cut through the legs). "horizon": every view with the horizon at
#: the characters' feet (floor colour below, sky above), no grid, no shadows: the look
#: pictures meant to be compared share when one of them is under or near the horizon.
FLOOR_STYLES = ("auto", "horizon")
#: Ambient light (each channel, linear) and the bodies' roughness (highlight
#: strength ``1 - roughness``).
AMBIENT = 0.30
BODY_ROUGHNESS = 0.7
#: Floor and grid colours (sRGB 0-1) and the shadow's darkening of the floor.
FLOOR_COLOR = (0.93, 0.925, 0.915)
GRID_COLOR = (0.74, 0.74, 0.74)
SHADOW_DARKEN = 0.80
#: Direction towards the shadow-casting light in camera terms: mostly overhead, so
#: shadows are short and sit under the feet (they show contact with the floor).
SHADOW_LIGHT = (0.35, 1.0, -0.25)  # (towards camera, up, right)
#: Cropped renders (``SceneRenderer.render(..., crop=True)``): margin around the drawn
#: points (px; covers anti-aliased edges), size step (px) and the largest share of the
#: frame worth cropping (above it the whole frame is rendered). The step is small: the
#: rectangle's restore, resolve, read-back and paste cost by the pixel (a scissor cuts
#: llvmpipe's 64-pixel tiles anywhere); steps of 8 instead of 64 px made the salsa
#: video's rectangles 13% smaller.
CROP_PAD_PX = 3
CROP_STEP_PX = 8
CROP_MAX_AREA = 0.7


def _srgb_to_linear(c: ArrayLike) -> np.ndarray:
    return np.asarray(c, np.float32) ** 2.2


def _ground_mesh(centre_xz: Sequence[float] | np.ndarray, height: float) -> DrawMesh:
    """The floor grid at ``height``: lines every :data:`GRID_SPACING` around
    ``centre_xz`` that fade into the floor colour within :data:`GRID_FADE_RADIUS`;
    thin unlit quads (no normals), one mesh.

    The floor itself is not drawn: the image is cleared to the floor colour and the
    sky is a backdrop (:func:`_sky_mesh`) standing on the floor far behind the
    characters. Filling the whole frame with a floor polygon costs more than all the
    bodies on llvmpipe with 4× multisampling; the backdrop covers only what is above
    the horizon, and shows the horizon at the feet even in a horizontal view.
    """
    cx, cz = centre_xz
    r = GRID_FADE_RADIUS
    n = int(np.ceil(r / GRID_SPACING))
    k = np.arange(-n, n + 1) * GRID_SPACING
    # snap the grid to world multiples of the spacing, so it does not depend on the clip
    cx0, cz0 = (
        np.round(cx / GRID_SPACING) * GRID_SPACING,
        np.round(cz / GRID_SPACING) * GRID_SPACING,
    )
    seg = np.arange(-n, n + 1) * GRID_SPACING
    s0, s1 = seg[:-1], seg[1:]
    hw = GRID_LINE_HALF_WIDTH
    off, a0 = np.meshgrid(k, s0, indexing="ij")
    _, a1 = np.meshgrid(k, s1, indexing="ij")
    off, a0, a1 = off.ravel(), a0.ravel(), a1.ravel()
    along_x = np.stack(
        [
            np.stack([a0, off - hw], -1),
            np.stack([a0, off + hw], -1),
            np.stack([a1, off + hw], -1),
            np.stack([a1, off - hw], -1),
        ],
        axis=1,
    )
    along_z = along_x[..., ::-1]
    q = np.concatenate([along_x, along_z]) + [cx0, cz0]  # (Q, 4, 2) as (x, z)
    pos = np.stack([q[..., 0], np.full(q.shape[:2], height + 2e-3), q[..., 1]], -1).reshape(-1, 3)
    dist = np.hypot(pos[:, 0] - cx, pos[:, 2] - cz)
    t = np.clip(dist / r, 0, 1)[:, None] ** 1.5
    grid, floor = _srgb_to_linear(GRID_COLOR), _srgb_to_linear(FLOOR_COLOR)
    col = np.hstack([grid * (1 - t) + floor * t, np.ones((len(pos), 1))]).astype(np.float32)
    b = 4 * np.arange(len(q))
    faces = np.concatenate([np.stack([b, b + 1, b + 2], 1), np.stack([b, b + 2, b + 3], 1)])
    return DrawMesh(
        "grid", col, pos.astype(np.float32), col, faces.astype(np.uint32), double_sided=True,
        static=True
    )  # fmt: skip


def _sky_mesh(
    centre: np.ndarray, cam: Camera, height: float, *, horizon: bool = False
) -> DrawMesh | None:
    """The sky: a huge unlit vertical backdrop in :data:`BACKGROUND` colour,
    :data:`SKY_DISTANCE` metres behind ``centre`` as seen along the camera axis; None
    when the picture has no horizon.

    Perspective: it stands on the floor (``y = height``), so the horizon falls near eye
    level as in a photograph. Orthographic: an infinite floor fills the whole frame of
    any view from above, so there is no sky; but a finite backdrop would draw a horizon
    ``SKY_DISTANCE · sin(elevation)`` above the feet, cutting through the characters in
    almost-level views. So below :data:`ORTHO_HORIZON_DEG` of elevation the backdrop's
    lower edge is lowered until it projects onto the floor line through ``centre``:
    the horizon sits at the characters' feet, as it does in an exactly level view.
    ``horizon``: every orthographic view gets that horizon at the feet, whatever its
    elevation (views below the floor included; see :data:`FLOOR_STYLES`).
    """
    y = np.array([0.0, 1.0, 0.0])
    back = cam.back
    hb = np.asarray(back, float) - y * (back @ y)
    if np.linalg.norm(hb) < np.sin(np.radians(1.0)):
        return None
    hb /= np.linalg.norm(hb)
    hr = np.cross(y, hb)
    ground_c = np.array([centre[0], height, centre[2]])
    c = ground_c - hb * SKY_DISTANCE
    if cam.projection == "orthographic":
        elevation = np.degrees(np.arcsin(np.clip(back @ y, -1, 1)))
        if not (horizon or 0.0 <= elevation < ORTHO_HORIZON_DEG):
            return None
        # bottom edge at the height whose projection equals the floor point's: (c - ground_c
        # + y·dh)·up = 0
        dh = -((c - ground_c) @ cam.up) / (y @ cam.up)
        c = c + y * dh
    w, h = 20 * SKY_DISTANCE, 20 * SKY_DISTANCE
    pos = np.array([c - hr * w, c + hr * w, c + hr * w + y * h, c - hr * w + y * h], np.float32)
    col = np.tile(np.append(_srgb_to_linear(BACKGROUND), 1.0), (4, 1)).astype(np.float32)
    faces = np.array([[0, 1, 2], [0, 2, 3]], np.uint32)
    return DrawMesh("sky", pos, pos, col, faces, double_sided=True, static=True)


def shadow_vertices(vertices: np.ndarray, light: ArrayLike, ground: float) -> np.ndarray:
    """Planar shadow: ``vertices`` (N, 3) projected onto the floor ``y = ground`` along
    the direction ``light`` (towards the light, ``light[1] > 0``); points under the
    floor drop straight down. Returns (N, 3)."""
    d = np.asarray(light, float)
    v = np.asarray(vertices, float)
    h = np.maximum(v[:, 1] - ground, 0.0)
    out = v - (h / d[1])[:, None] * d
    out[:, 1] = ground
    return out


#: Per-vertex colours of shared read-only meshes (:meth:`SceneRenderer._vertex_colors`).
_VERTEX_COLOURS: list[tuple] = []


class SceneRenderer:
    """Renders one scene's bodies, floor, shadows and lights, frame after frame.

    Build it once (floor, lights, colours), then call :meth:`render` per frame; the body
    pieces are re-posed (a gather and one matrix product, see :mod:`snapcore.render.mannequin`) and
    uploaded as one mesh per character. Use it on the thread that created it.

    Parameters
    ----------
    scene : Scene
    size : (int, int)
        Image width and height, pixels.
    ground : bool
        Draw the floor with its grid at ``scene.ground``.
    shadows : bool
        Draw each body's shadow on the floor (a planar projection along a mostly
        overhead light: cheap, exact, and it shows where feet touch the floor).
    body : {"human", "mannequin"} or SceneBody
        The body kind to draw (:data:`snapcore.render.bodies.BodyKind`, default
        :data:`~snapcore.render.bodies.DEFAULT_BODY`), or a body already built for the
        scene (:func:`snapcore.render.bodies.scene_body`).
    floor : {"auto", "horizon"}
        How the floor shows (with ``ground``): "auto", the grid and shadows from above
        and a horizon at the feet in almost level orthographic views; "horizon", a
        horizon at the feet in every view, no grid or shadows (one look for views
        on both sides of the horizon, see :data:`FLOOR_STYLES`).
    """

    def __init__(
        self,
        scene: Scene,
        *,
        size: tuple[int, int] = (640, 480),
        ground: bool = True,
        shadows: bool = True,
        body: BodyKind | SceneBody = DEFAULT_BODY,
        floor: str = "auto",
    ) -> None:
        self.scene = scene
        self.size = check_size(size)
        self.body = scene_body(scene, kind=body) if isinstance(body, str) else body
        self.ground = bool(ground)
        if floor not in FLOOR_STYLES:
            raise RenderError(f"floor must be one of {', '.join(FLOOR_STYLES)}, got {floor!r}")
        self.floor = floor
        #: Where the "horizon" floor style puts the horizon (a floor point, metres):
        #: default, the floor under the middle of the motion; a picture of one pose
        #: passes the pose's own floor contact, where the figure stands.
        self.horizon_point: np.ndarray | None = None
        self.shadows = bool(shadows) and self.ground and floor == "auto"
        #: Light the bodies per vertex (:attr:`~snapcore.render.raster.DrawMesh.vertex_lighting`).
        self.vertex_lighting = False
        self._thread = threading.get_ident()
        # cleared to the floor colour: the floor is everything the sky does not cover
        self._clear = FLOOR_COLOR if self.ground else BACKGROUND
        self._sky: DrawMesh | None = None
        n = len(self.body.characters)
        self._body_mesh: DrawMesh | None = None
        self._shadow_mesh: DrawMesh | None = None
        self._below = False  # camera under the floor (set with the camera)
        self._vcols = np.vstack([self._vertex_colors(i) for i in range(n)])
        self._faces = self.body.faces.astype(np.uint32)
        if self.shadows:
            from snapcore.render.bodies import MixedSceneBody, shadow_body
            from snapcore.render.mannequin import TESSELLATION_COARSE, SceneBody

            # a coarse mannequin, or a glTF character's own mesh (posed once for both)
            self._shadow_body = (
                shadow_body(self.body, TESSELLATION_COARSE)
                if isinstance(self.body, MixedSceneBody)
                else SceneBody(scene, tessellation=TESSELLATION_COARSE)
            )
            rgb = np.append(_srgb_to_linear(FLOOR_COLOR) * SHADOW_DARKEN, 1.0)
            self._shadow_rgb = np.tile(rgb, (self._shadow_body.n_vertices, 1)).astype(np.float32)
        self._grid: DrawMesh | None = None
        # the scene's box, once: every camera asks (a batch scene sets 13 cameras)
        self._bounds = scene.bounds()
        if self.ground:
            b = self._bounds
            self._grid = _ground_mesh((b[0, [0, 2]] + b[1, [0, 2]]) / 2, scene.ground)
        self._last_cam: Camera | None = None
        self._camera_uses = 0  # renders with the last camera
        self._background_key: object = None  # its samples in GL (see _background_image)
        self._gl_cam: Camera | None = None  # set with the first camera, see _set_camera
        self._background: np.ndarray | None = None
        self._lights: list[Light] = []
        self._lights_key: object = None  # the camera direction the lights were made for
        self._shadow_dir = np.array([0.0, 1.0, 0.0])

    def _vertex_colors(self, i: int) -> np.ndarray:
        b = self.body.characters[i]
        # kept for a body whose faces and colours are shared arrays (the human mesh's:
        # the same for every scene of a library), by identity; entries hold the arrays
        for faces, colours, c in list(_VERTEX_COLOURS):
            if faces is b.faces and colours is b.face_colors:
                return c
        c = np.zeros((b.n_vertices, 4), np.float32)
        c[b.faces.ravel()] = np.repeat(b.face_colors, 3, axis=0) / 255.0
        c[:, :3] = c[:, :3] ** 2.2  # colours are sRGB; the shader multiplies in linear light
        if not b.face_colors.flags.writeable:  # a shared mesh's colours (see above)
            c.flags.writeable = False
            _VERTEX_COLOURS.insert(0, (b.faces, b.face_colors, c))
            del _VERTEX_COLOURS[4:]
        return c

    def _set_camera(self, cam: Camera) -> None:
        # The floor reaches far beyond the characters: extend the depth range so it is
        # not clipped (an orthographic eye can move back freely without changing the
        # image; a perspective one keeps its near plane and sees farther).
        far = 2.0 * SKY_DISTANCE + float(np.ptp(self._bounds[:, [0, 2]]))
        if cam.projection == "orthographic":
            back = far
            gl_cam = Camera(
                cam.position + cam.back * back,
                cam.right,
                cam.up,
                cam.back,
                cam.size,
                cam.projection,
                cam.half_height,
                cam.yfov,
                cam.znear + back,
                cam.zfar + back + far,
            )
        else:
            gl_cam = Camera(
                cam.position,
                cam.right,
                cam.up,
                cam.back,
                cam.size,
                cam.projection,
                cam.half_height,
                cam.yfov,
                cam.znear,
                max(cam.zfar, far),
            )
        self._gl_cam = gl_cam
        self._background = None
        if self.ground and self._grid is not None:
            b = self._bounds
            centre = (b[0] + b[1]) / 2 if self.horizon_point is None else self.horizon_point
            self._sky = _sky_mesh(centre, cam, self.scene.ground, horizon=self.floor == "horizon")
            # an almost level orthographic view sees the grid edge-on: a row of dashes
            # along the horizon, not a floor; leave it out
            level = (
                cam.projection == "orthographic"
                and abs(np.degrees(np.arcsin(np.clip(cam.back[1], -1, 1)))) < ORTHO_HORIZON_DEG
            )
            # a camera under the floor would see its underside hide the feet; drawn, the
            # grid and the shadows cut through the legs instead: leave them out
            self._below = (
                cam.back[1] < 0
                if cam.projection == "orthographic"
                else cam.position[1] < self.scene.ground
            )
            self._grid.visible = not (level or self._below or self.floor == "horizon")
        y = np.array([0.0, 1.0, 0.0])
        # Lights follow the camera so every view is lit alike: a key light from above
        # the camera's left, a weaker fill from the right, a rim light from behind.
        lights = (
            (cam.back + 1.4 * y - 0.8 * cam.right, 2.4),
            (cam.back + 0.2 * y + 1.0 * cam.right, 0.9),
            (-cam.back + 1.2 * y + 0.3 * cam.right, 1.1),
        )
        key = (cam.back.tobytes(), cam.right.tobytes())
        if key != self._lights_key:  # the panels of a strip share one direction
            self._lights_key = key
            self._lights = []
            for direction, intensity in lights:
                d = direction / np.linalg.norm(direction)  # from the scene towards the light
                m = np.eye(4)
                m[:3, :3] = np.stack(
                    view_basis(d, None if abs(d[1]) < POLE_COS else [1.0, 0, 0]), 1
                )
                # shining along the light's -z, through the matrix its scene node renders with
                self._lights.append(Light(-gl_node_matrix(m)[:3, 2], intensity))
        # the shadow light, in world terms: horizontal part from the camera's side
        hb = cam.back - y * (cam.back @ y)
        hb = hb / np.linalg.norm(hb) if np.linalg.norm(hb) > 1e-6 else cam.up
        hr = np.cross(y, hb)
        la, lb, lc = SHADOW_LIGHT
        d = la * hb + lb * y + lc * hr
        self._shadow_dir = d / np.linalg.norm(d)
        self._last_cam = cam

    def _full_camera(self) -> Camera:
        """The GL camera of the whole view (set by :meth:`_set_camera`)."""
        if self._gl_cam is None:
            raise RenderError("internal: SceneRenderer used before its camera was set")
        return self._gl_cam

    def draw_list(self, bodies: bool = True) -> list[DrawMesh]:
        """What a picture draws, in order: the floor grid, the sky, the bodies and
        their shadows (``bodies``), as posed by the last :meth:`render`."""
        meshes = [self._grid, self._sky]
        if bodies:
            meshes += [self._body_mesh, self._shadow_mesh]
        return [m for m in meshes if m is not None]

    def lights(self) -> list[Light]:
        """The directional lights of the last camera (ambient: :data:`AMBIENT`)."""
        return list(self._lights)

    def _draw(
        self,
        gl_cam: Camera,
        bodies: bool = True,
        window: tuple[int, int, int, int] | None = None,
    ) -> np.ndarray:
        """The picture ``gl_cam`` sees, (H, W, 3) uint8, or its rectangle ``window``
        (``x0, y0, width, height``)."""
        return self._submit_draw(gl_cam, bodies, window).read()

    def _submit_draw(
        self,
        gl_cam: Camera,
        bodies: bool = True,
        window: tuple[int, int, int, int] | None = None,
        keep: object = None,
        background: object = None,
        buffer: int = 0,
    ) -> Pending:
        pose = gl_camera_pose(gl_cam)
        under = len(self.draw_list(False))
        return submit(
            self.draw_list(bodies),
            keep=keep,
            buffer=buffer,
            background=None if background is None else (background, under),
            size=gl_cam.size,
            view=np.linalg.inv(pose),
            projection=gl_projection(gl_cam),
            cam_pos=pose[:3, 3],
            lights=self._lights,
            ambient=AMBIENT,
            clear=self._clear,
            window=window,
        )

    def _update_bodies(self, index: int) -> list[np.ndarray]:
        # All characters in one mesh and all shadows in another: one draw call each.
        verts = self.body.vertices(index)
        drawn = [verts]
        self._body_mesh = DrawMesh(
            "body",
            self._vcols,
            verts.astype(np.float32),
            self._vcols,
            self._faces,
            normals=self.body.normals(index).astype(np.float32),
            roughness=BODY_ROUGHNESS,
            vertex_lighting=self.vertex_lighting,
        )
        if self.shadows:
            # a coarse stand-in, and only its faces turned to the light: every closed piece
            # then covers its shadow once (a tenth of the triangles, no overdraw)
            sb = self._shadow_body
            cv = sb.vertices(index)
            tri = cv[sb.faces]
            lit = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) @ self._shadow_dir > 0
            sv = shadow_vertices(cv, self._shadow_dir, self.scene.ground + 3e-3)
            self._shadow_mesh = DrawMesh(
                "shadow",
                self._shadow_rgb,
                sv.astype(np.float32),
                self._shadow_rgb,
                sb.faces[lit].astype(np.uint32),
                double_sided=True,
                visible=not self._below,
                dynamic_indices=True,
            )
            if not self._below:
                drawn.append(sv)
        return drawn

    def render(self, index: int, camera: Camera, *, crop: bool = False) -> np.ndarray:
        """The image of the pose at internal index ``index`` (``frame - scene.frame_offset``)
        seen by ``camera``: (H, W, 3) uint8.

        Many frames seen by one camera (a video, or ``crop=True`` from the first
        frame; otherwise from the second frame with the same camera object): the
        picture without the bodies is rendered once per camera, and each frame draws,
        resolves and reads back only the rectangle its bodies and shadows cover (a
        scissor in the full view: the same matrices, so those pixels are the full
        render's bit for bit), pasted into a copy of it. The result equals the full
        render; software GL pays per pixel (multisampled), so this is 2-4x less work
        when the bodies fill part of the frame. A camera used once (a still, a
        thumbnail) renders the whole frame: a background would cost a frame more.
        """
        return self._submit(index, camera, crop)()

    def render_frames(
        self,
        indices: Iterable[int],
        camera: Camera,
        *,
        crop: bool = True,
        turns: Iterable[AbstractContextManager] | None = None,
    ) -> Iterator[np.ndarray]:
        """The images of the poses at ``indices`` seen by ``camera``, one after the
        other, each as :meth:`render` gives it (the same pixels), pipelined: a frame's
        bodies are posed while llvmpipe's threads rasterise the frame before. Videos
        draw this way. ``turns`` (one context manager per index) holds each frame's
        posing, e.g. to pose in one order frames that two renderers draw on two
        threads with one body (see :mod:`snapcore.render.video`)."""
        pending = None
        turns_it = iter(turns) if turns is not None else None
        for k, index in enumerate(indices):
            # two sets of GL buffers taking turns: this frame is posed and submitted
            # (llvmpipe's vertex work, on this thread) while the last one rasterises
            turn = next(turns_it) if turns_it is not None else None
            frame = self._submit(int(index), camera, crop, buffer=k % 2, turn=turn)
            if pending is not None:
                yield pending()
            pending = frame
        if pending is not None:
            yield pending()

    def _submit(
        self,
        index: int,
        camera: Camera,
        crop: bool,
        buffer: int = 0,
        turn: AbstractContextManager | None = None,
    ) -> _Frame:
        """Pose ``index`` (inside ``turn`` if given), submit it in GL buffer set
        ``buffer`` (0 or 1) and return the frame (call it for the image). Set 2 draws
        backgrounds."""
        if threading.get_ident() != self._thread:
            raise RenderError(
                "a SceneRenderer must be used on the thread that created it "
                "(EGL contexts are thread-bound); make one per thread"
            )
        if tuple(camera.size) != self.size:
            raise RenderError(f"camera size {camera.size} differs from the renderer's {self.size}")
        self.body._check(index)
        if camera is not self._last_cam:
            self._set_camera(camera)
            self._camera_uses = 0
        self._camera_uses += 1
        with turn if turn is not None else nullcontext():
            drawn = self._update_bodies(int(index))
        many = crop or self._camera_uses > 1
        window = self._crop_window(camera, drawn) if many else None
        gl_cam = self._full_camera()
        if window is None:
            return _Frame(self._submit_draw(gl_cam, buffer=buffer), None, None)
        background = self._background_image()
        pending = self._submit_draw(
            gl_cam, window=window, background=self._background_key, buffer=buffer
        )
        return _Frame(pending, background, window)

    def _crop_window(
        self, camera: Camera, drawn: list[np.ndarray]
    ) -> tuple[int, int, int, int] | None:
        """``(x0, y0, width, height)`` in pixels of a rectangle holding every drawn
        point (bodies, shadows) of this frame, or None to render the whole frame."""
        w, h = self.size
        if camera.projection == "orthographic":
            lo, hi = ortho_box(camera, drawn)
        else:
            points = np.concatenate([np.asarray(d, float) for d in drawn])
            depth = (camera.position - points) @ camera.back
            if not np.all(depth > camera.znear):  # beside or behind the eye: no box
                return None
            xy = camera.project(points)
            lo, hi = xy.min(axis=0), xy.max(axis=0)
        lo = np.floor(lo) - CROP_PAD_PX
        hi = np.ceil(hi) + CROP_PAD_PX
        # sizes in steps of CROP_STEP_PX (8 px: within 2% of the tight box in area, and
        # read-back rows of RGBA in multiples of 32 bytes)
        cw, ch = (
            int(min(n, np.ceil(max(b - a, 1) / CROP_STEP_PX) * CROP_STEP_PX))
            for a, b, n in zip(lo, hi, (w, h))
        )
        if cw * ch > CROP_MAX_AREA * w * h:
            return None
        x0 = int(np.clip(lo[0], 0, w - cw))
        y0 = int(np.clip(lo[1], 0, h - ch))
        return x0, y0, cw, ch

    def _background_image(self) -> np.ndarray:
        """The full view without bodies and shadows (once per camera). Its samples are
        kept in GL too: a frame's rectangle starts from them (a copy) instead of
        clearing and drawing the floor and sky again."""
        if self._background is None:
            self._background_key = object()
            pending = self._submit_draw(
                self._full_camera(), False, keep=self._background_key, buffer=2
            )
            self._background = np.ascontiguousarray(pending.read())
        return self._background


class _Frame:
    """A submitted frame: calling it waits for the picture (once; later calls return
    the same image), pasted into the background when only a rectangle was drawn."""

    def __init__(
        self,
        pending: Pending,
        background: np.ndarray | None,
        window: tuple[int, int, int, int] | None,
    ) -> None:
        self._pending, self._background, self._window = pending, background, window
        self._image: np.ndarray | None = None

    def __call__(self) -> np.ndarray:
        if self._image is None:
            part = self._pending.read()
            if self._background is None or self._window is None:
                self._image = _copy_rgb(part, np.empty(part.shape, np.uint8))
            else:
                x0, y0, cw, ch = self._window
                image = self._background.copy()
                _copy_rgb(part, image[y0 : y0 + ch, x0 : x0 + cw])
                self._image = image
        return self._image


def _copy_rgb(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """Copy (H, W, 3) uint8 ``src`` (a strided view, e.g. the RGB of a read-back RGBA
    array) into ``dst``, channel by channel: NumPy copies one strided byte plane ~4x
    faster than 3-byte pixels (0.5 against 2.1 ms for a 640x704 rectangle), same
    bytes. Returns ``dst``."""
    for c in range(3):
        dst[..., c] = src[..., c]
    return dst


def scene_index(scene: Scene, frame: int, what: str = "frame") -> int:
    """The internal index of source frame ``frame``, or a :class:`RenderError` naming the
    source frames the scene keeps.

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame number (the file's own, ``scene.source_frame(index)``).
    what : str
        How the message names the value (``"frame"``, ``"frame_range"``...).

    Returns
    -------
    int
        ``frame - scene.frame_offset``, in ``0 .. scene.n_frames - 1``.
    """
    f = int(frame)
    index = f - int(scene.frame_offset)
    if not 0 <= index < scene.n_frames:
        first = int(scene.frame_offset)
        raise RenderError(
            f"{what} {f} is not in the scene, which keeps source frames "
            f"{first}..{first + scene.n_frames - 1}"
        )
    return index


def render_still(
    scene: Scene,
    frame: int,
    view: ArrayLike | None = None,
    *,
    size: tuple[int, int] | None = None,
    projection: str = "orthographic",
    fit: str = "frame",
    ground: bool = True,
    shadows: bool = True,
    camera: Camera | None = None,
    body: BodyKind = DEFAULT_BODY,
    renderer: SceneRenderer | None = None,
) -> np.ndarray:
    """One frame of a scene as an image.

    Parameters
    ----------
    scene : Scene
    frame : int
        Source frame: the file's own number (``Snapshot.source_frame``, what the JSON's
        ``frame`` says), not an index into the cut arrays.
    view : array of shape (3,), optional
        From the scene towards the camera; default :func:`default_view`.
    size : (int, int), optional
        Width and height, pixels (default: the renderer's, else 800 × 600).
    projection : {"orthographic", "perspective"}
    fit : {"frame", "motion"}
        Frame this pose tightly, or the whole motion (the same framing for every frame,
        as in videos).
    ground, shadows : bool
        Draw the floor grid / the bodies' shadows (ignored with ``renderer``: its own).
    camera : Camera, optional
        Use this camera instead of fitting one (``view``, ``projection``, ``fit`` ignored).
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`; ignored with
        ``renderer``: its own).
    renderer : SceneRenderer, optional
        Reuse one (same thread, same size) when rendering many stills of a scene.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)

    Examples
    --------
    >>> import numpy as np
    >>> from snapcore import render_still
    >>> from snapcore.motion.synth import synth_scene
    >>> image = render_still(synth_scene("walk"), 0, size=(160, 120))
    >>> image.shape, image.dtype.name
    ((120, 160, 3), 'uint8')
    >>> len(np.unique(image.reshape(-1, 3), axis=0)) > 10  # shaded figure and floor, not blank
    True
    """
    if size is None:
        size = renderer.size if renderer is not None else (800, 600)
    size = check_size(size)
    index = scene_index(scene, frame)
    sr = renderer or SceneRenderer(scene, size=size, ground=ground, shadows=shadows, body=body)
    if camera is None:
        if view is None:
            view = default_view(scene)
        if fit == "frame":
            pts = sr.body.vertices(index)
        elif fit == "motion":
            pts = motion_points(scene, body=sr.body)
        else:
            raise RenderError(f"fit must be 'frame' or 'motion', got {fit!r}")
        camera = fit_camera(pts, view, size=size, projection=projection)
    return sr.render(index, camera)


def render_mesh(
    vertices: np.ndarray,
    faces: np.ndarray,
    view: ArrayLike,
    *,
    size: tuple[int, int] = (512, 512),
    face_colors: np.ndarray | None = None,
    projection: str = "orthographic",
) -> np.ndarray:
    """Render any triangle mesh (e.g. a relief) lit like the stills, no floor:
    (H, W, 3) uint8. ``face_colors`` (M, 3|4) uint8, default light grey."""
    pyrender = load_pyrender()
    import trimesh

    size = check_size(size)
    colors = [200, 200, 200, 255] if face_colors is None else face_colors
    tm = trimesh.Trimesh(
        np.asarray(vertices, float), np.asarray(faces, np.int64), face_colors=colors, process=False
    )
    mesh = pyrender.Mesh.from_trimesh(tm, smooth=False)
    cam = fit_camera(tm.vertices, view, size=size, projection=projection)
    ps = pyrender.Scene(bg_color=[*BACKGROUND, 1.0], ambient_light=[0.3] * 3)
    ps.add(mesh)
    ps.add(cam.pyrender_camera(), pose=cam.pose)
    for d, k in ((cam.back + cam.up - 0.6 * cam.right, 2.5), (cam.back + cam.right, 1.0)):
        d = d / np.linalg.norm(d)
        r, u, b = view_basis(d, cam.up if abs(d @ cam.up) < 0.99 else cam.right)
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2] = r, u, b
        ps.add(pyrender.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=k), pose=m)
    color, _ = gl_renderer(*size).render(ps)
    return np.ascontiguousarray(color)


def save_png(image: np.ndarray, path: str | Path) -> None:
    """Write an (H, W, 3|4) uint8 image as PNG."""
    from PIL import Image

    Image.fromarray(np.asarray(image, np.uint8)).save(str(path))
