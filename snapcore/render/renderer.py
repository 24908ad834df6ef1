"""Offscreen rendering, headless: stills, depth maps and face-id buffers.

Everything people look at comes from here: stills and the per-frame renderer
(:class:`SceneRenderer`) used by videos (:mod:`snapcore.render.video`) and composites
(:mod:`snapcore.render.composites`); depth maps for the relief; face-id buffers for the
viewpoint-entropy baseline. Cameras and framing are in :mod:`snapcore.render.camera` and the
OpenGL context (pyrender on Mesa EGL, one renderer per thread) in
:mod:`snapcore.render.gl`; their public names are re-exported here.

Conventions
-----------
- World: metres, Y up. A *view* is a unit vector from the scene centre to the camera;
  camera bases follow :func:`~snapcore.render.camera.view_basis` (Y up in the picture, −Z up
  when looking straight down).
- Images are row-major ``(H, W[, 3])`` uint8 with row 0 at the top.
- Frames are *internal* scene frames (0 = first frame after the lead-in cut); callers
  that show numbers to people convert with ``scene.source_frame(i)``.
- A :class:`SceneRenderer` must be used on the thread that made it (EGL contexts are
  thread-bound); every thread gets its own context.

Face-id buffers
---------------
:func:`render_face_ids` draws the mesh indexed, one-sided, with a fragment shader that
writes the triangle's index + 1 as 24-bit RGB (``id = r | g << 8 | b << 16``; face ``k``
→ ``k + 1``, 0 = background), no lighting and *no multisampling*: pyrender renders into
a 4-sample buffer, and with ``GL_MULTISAMPLE`` on, edge pixels would average two ids
into a third. :func:`render_depth` reuses the id pass and intersects each pixel's ray
with the plane of the face it shows, so depth is exact (float64), free of depth-buffer
quantisation.
"""

from __future__ import annotations

import threading
import warnings
from dataclasses import dataclass

import numpy as np

from snapcore.errors import RenderError
from snapcore.render.camera import (
    POLE_COS,
    Camera,
    check_size,
    default_view,
    fit_camera,
    motion_points,
    view_basis,
)
from snapcore.render.gl import NO_MSAA, gl_renderer, load_pyrender

__all__ = [
    "DepthMap",
    "SceneRenderer",
    "render_face_ids",
    "face_id_camera",
    "render_depth",
    "render_still",
    "render_mesh",
    "save_png",
    "FACE_ID_RESOLUTION",
    "BACKGROUND",
]

#: Default square resolution (pixels) of face-id buffers. The number of faces a view
#: "sees" depends strongly on it (3.2k faces/view at 256² vs 8.9k at 512² for a 77k-face
#: mesh), so the viewpoint-entropy baseline fixes one resolution: this one.
FACE_ID_RESOLUTION = 256
#: Background ("sky") colour of stills and videos (sRGB 0-1): near white.
BACKGROUND = (0.975, 0.975, 0.975)


# --------------------------------------------------------------------------- face ids


def _id_mesh(vertices, faces):
    """One indexed, one-sided primitive; the id shader colours triangle k with k + 1."""
    pyrender = load_pyrender()
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise RenderError(f"need vertices (N, 3) and faces (M, 3), got {v.shape} and {f.shape}")
    if len(f) == 0 or len(v) == 0:
        raise RenderError("the mesh has no faces")
    if f.min() < 0 or f.max() >= len(v):
        raise RenderError("faces index vertices that do not exist")
    if len(f) >= 2**24 - 1:
        raise RenderError(f"{len(f)} faces do not fit a 24-bit id buffer")
    if not np.all(np.isfinite(v)):
        raise RenderError("vertices must be finite")
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                             doubleSided=False)
    prim = pyrender.Primitive(positions=v.astype(np.float32), indices=f.astype(np.uint32),
                              material=mat, mode=4)
    return pyrender.Mesh([prim])


def _decode_ids(rgb: np.ndarray) -> np.ndarray:
    c = rgb.astype(np.int32)
    return c[..., 0] | (c[..., 1] << 8) | (c[..., 2] << 16)


def _bounding_sphere(vertices) -> tuple[np.ndarray, float]:
    v = np.asarray(vertices, float)
    c = (v.min(axis=0) + v.max(axis=0)) / 2
    return c, max(float(np.sqrt(np.max(np.sum((v - c) ** 2, axis=1)))), 1e-6)


def face_id_camera(vertices, view, *, resolution=FACE_ID_RESOLUTION, sphere=None) -> Camera:
    """The orthographic camera :func:`render_face_ids` uses for ``view``.

    It frames the mesh's bounding sphere (centre = centre of the axis-aligned box,
    radius = farthest vertex from it), the same for every view, so pixel counts are
    comparable across views: one pixel is ``2 r / resolution`` metres wide.
    ``sphere=(centre, radius)`` skips recomputing it.
    """
    c, r = sphere if sphere is not None else _bounding_sphere(vertices)
    right, up, back = view_basis(view)
    dist = 2.0 * r
    return Camera(c + back * dist, right, up, back, (int(resolution), int(resolution)),
                  "orthographic", half_height=r, znear=0.5 * r, zfar=3.5 * r)


def _render_ids(mesh, cameras, *, progress=False) -> np.ndarray:
    pyrender = load_pyrender()
    w, h = cameras[0].size
    r = gl_renderer(w, h)
    scene = pyrender.Scene(bg_color=[0.0, 0.0, 0.0, 1.0], ambient_light=[0.0, 0.0, 0.0])
    scene.add(mesh)
    cam_node = scene.add(cameras[0].pyrender_camera(), pose=cameras[0].pose)
    flags = pyrender.RenderFlags.FLAT  # back faces culled: only front faces get ids
    out = np.empty((len(cameras), h, w), np.int32)
    NO_MSAA.on = True
    try:
        for i, cam in enumerate(cameras):
            if i:
                cam_node.camera = cam.pyrender_camera()
                scene.set_pose(cam_node, cam.pose)
            color, _ = r.render(scene, flags=flags)
            out[i] = _decode_ids(color)
    finally:
        NO_MSAA.on = False
    return out


def render_face_ids(vertices, faces, views, *, resolution=FACE_ID_RESOLUTION) -> np.ndarray:
    """Which face each pixel shows, for many orthographic views of one mesh.

    Parameters
    ----------
    vertices : array of shape (N, 3)
        Metres.
    faces : array of shape (M, 3)
        Vertex indices; M < 2²⁴ − 1.
    views : array of shape (V, 3) or (3,)
        Unit vectors from the mesh centre to the camera.
    resolution : int
        Square image side, pixels (default :data:`FACE_ID_RESOLUTION`).

    Returns
    -------
    ndarray of int32, shape (V, resolution, resolution)
        ``0`` = background, ``k + 1`` = face ``k``. Row 0 is the top of the image.

    Notes
    -----
    Framing: :func:`face_id_camera` (the bounding sphere, identical for every view).
    Faces are one-sided: a face is drawn only from the side its counter-clockwise
    normal points to (back faces are culled, so grazing back faces can never win a
    depth tie at a silhouette); the nearest front face wins the depth test. Ids are exact: no
    multisampling, no filtering, no lighting. Measured on 2 cores: 162 views of a
    75k-face mesh at 256² in well under 5 s (``snapshot bench --only "face ids"``: ~2 s).
    """
    views = np.asarray(views, float)
    single = views.ndim == 1
    views = views.reshape(-1, 3)
    if views.shape[0] == 0:
        raise RenderError("no views given")
    mesh = _id_mesh(vertices, faces)
    sphere = _bounding_sphere(vertices)
    cams = [face_id_camera(vertices, v, resolution=resolution, sphere=sphere) for v in views]
    ids = _render_ids(mesh, cams)
    return ids[0] if single else ids


# --------------------------------------------------------------------------- depth


@dataclass(frozen=True)
class DepthMap:
    """An orthographic depth image (a height field seen along ``forward``).

    Attributes
    ----------
    depth : ndarray of float64, shape (H, W)
        Distance in metres from the image plane to the surface along ``forward``; NaN
        where no surface is hit (background).
    face_ids : ndarray of int32, shape (H, W)
        Face seen at each pixel (``k + 1``; 0 = background).
    pixel_size : float
        Metres per pixel, square pixels.
    origin : ndarray of shape (3,)
        World position of the image plane's centre; the plane lies in front of the
        whole mesh, so every depth is positive.
    right, up, forward : ndarray of shape (3,)
        Image x (columns, left to right), image y (rows go *down* = ``-up``) and the
        viewing direction (``forward = -view``).

    Notes
    -----
    Pixel ``(i, j)``'s centre is ``origin + right·(j + ½ − W/2)·s − up·(i + ½ − H/2)·s``
    for pixel size ``s``; its surface point is that plus ``forward·depth[i, j]``. A
    relief height field is ``np.nanmax(depth) - depth`` (0 at the farthest point).
    """

    depth: np.ndarray
    face_ids: np.ndarray
    pixel_size: float
    origin: np.ndarray
    right: np.ndarray
    up: np.ndarray
    forward: np.ndarray

    @property
    def shape(self) -> tuple[int, int]:
        return self.depth.shape

    @property
    def mask(self) -> np.ndarray:
        """True where a surface is seen, shape (H, W)."""
        return self.face_ids > 0

    def pixel_centers(self) -> np.ndarray:
        """World positions of the pixel centres on the image plane, shape (H, W, 3)."""
        h, w = self.depth.shape
        s = self.pixel_size
        xs = (np.arange(w) + 0.5 - w / 2) * s
        ys = (np.arange(h) + 0.5 - h / 2) * s
        return (self.origin + xs[None, :, None] * self.right
                - ys[:, None, None] * self.up)

    def points(self) -> np.ndarray:
        """World surface point at each pixel (NaN for background), shape (H, W, 3)."""
        return self.pixel_centers() + self.depth[..., None] * self.forward


def render_depth(vertices, faces, view, *, resolution=512, extent=None, up=None,
                 margin=0.02) -> DepthMap:
    """Metric orthographic depth of a mesh seen along ``-view``.

    Parameters
    ----------
    vertices : array of shape (N, 3)
        Metres.
    faces : array of shape (M, 3)
    view : array of shape (3,)
        From the mesh towards the viewer.
    resolution : int or (int, int)
        Pixels along the longer side of the framed extent (the other side follows the
        aspect ratio), or an explicit ``(W, H)``.
    extent : float or (float, float), optional
        Half width and half height of the image in metres (one number: square), centred
        on the mesh's projected bounding box. Default: the projected bounding box plus
        ``margin`` on each side.
    up : array of shape (3,), optional
        Up hint (default as :func:`view_basis`).
    margin : float
        Border around the default extent, fraction of its size.

    Returns
    -------
    DepthMap
        ``depth`` in metres from a plane in front of the mesh (NaN = background).

    Notes
    -----
    The id pass (:func:`render_face_ids` machinery) says which face each pixel centre
    sees; depth is then the exact ray-plane distance ``t = n·(v0 − o)/(n·f)`` for that
    face's plane (normal ``n``, a vertex ``v0``), pixel centre ``o`` and direction ``f``.
    """
    v = np.asarray(vertices, float)
    f = np.asarray(faces, np.int64)
    right, upv, back = view_basis(view, up)
    x, y, z = v @ right, v @ upv, v @ back
    cx, cy = (x.min() + x.max()) / 2, (y.min() + y.max()) / 2
    if extent is None:
        hw = max((x.max() - x.min()) / 2, 1e-6) * (1 + 2 * margin)
        hh = max((y.max() - y.min()) / 2, 1e-6) * (1 + 2 * margin)
    else:
        e = np.broadcast_to(np.asarray(extent, float), (2,))
        hw, hh = float(e[0]), float(e[1])
        if not (hw > 0 and hh > 0):
            raise RenderError(f"extent must be positive, got {extent!r}")
    if np.ndim(resolution) == 0:
        n = int(resolution)
        if hw >= hh:
            w, h = n, max(int(round(n * hh / hw)), 1)
        else:
            w, h = max(int(round(n * hw / hh)), 1), n
        # keep pixels square: recompute the half height from the integer height
        s = 2 * hw / w if hw >= hh else 2 * hh / h
        hw, hh = s * w / 2, s * h / 2
    else:
        w, h = (int(t) for t in resolution)
        s = max(2 * hw / w, 2 * hh / h)
        hw, hh = s * w / 2, s * h / 2
    if w < 1 or h < 1 or w > 8192 or h > 8192:
        raise RenderError(f"depth map size must be 1..8192 pixels a side, got {w}x{h}")
    front = float(z.max())
    depth_span = float(z.max() - z.min())
    pad = max(depth_span, hw, hh) * 0.1 + 1e-3
    origin = cx * right + cy * upv + (front + pad) * back
    cam = Camera(origin, right, upv, back, (w, h), "orthographic", half_height=hh,
                 znear=pad * 0.5, zfar=pad + depth_span + pad)
    ids = _render_ids(_id_mesh(v, f), [cam])[0]
    depth = np.full((h, w), np.nan)
    hit = ids > 0
    if np.any(hit):
        k = ids[hit] - 1
        tri = v[f[k]]  # (P, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        ii, jj = np.nonzero(hit)
        o = (origin + ((jj + 0.5 - w / 2) * s)[:, None] * right
             - ((ii + 0.5 - h / 2) * s)[:, None] * upv)
        fwd = -back
        denom = n @ fwd
        with np.errstate(divide="ignore", invalid="ignore"):
            t = np.einsum("pi,pi->p", n, tri[:, 0] - o) / denom
        # faces seen edge-on (denom ~ 0): fall back to the face centroid's depth
        bad = ~np.isfinite(t) | (np.abs(denom) < 1e-12 * np.linalg.norm(n, axis=1))
        t[bad] = (tri[bad].mean(axis=1) - o[bad]) @ fwd
        depth[hit] = t
    else:
        warnings.warn("render_depth: the mesh covers no pixel; depth is all NaN", stacklevel=2)
    return DepthMap(depth, ids, float(s), origin, right, upv, -back)


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
#: Floor and grid colours (sRGB 0-1) and the shadow's darkening of the floor.
FLOOR_COLOR = (0.93, 0.925, 0.915)
GRID_COLOR = (0.74, 0.74, 0.74)
SHADOW_DARKEN = 0.80
#: Direction towards the shadow-casting light in camera terms: mostly overhead, so
#: shadows are short and sit under the feet (they show contact with the floor).
SHADOW_LIGHT = (0.35, 1.0, -0.25)  # (towards camera, up, right)


def _srgb_to_linear(c):
    return np.asarray(c, np.float32) ** 2.2


def _ground_mesh(centre_xz, height):
    """The floor grid at ``height``: lines every :data:`GRID_SPACING` around
    ``centre_xz`` that fade into the floor colour within :data:`GRID_FADE_RADIUS`;
    thin unlit quads (no normals), one mesh.

    The floor itself is not drawn: the image is cleared to the floor colour and the
    sky is a backdrop (:func:`_sky_mesh`) standing on the floor far behind the
    characters. Filling the whole frame with a floor polygon costs more than all the
    bodies on llvmpipe with 4× multisampling; the backdrop covers only what is above
    the horizon, and shows the horizon at the feet even in a horizontal view.
    """
    pyrender = load_pyrender()
    cx, cz = centre_xz
    r = GRID_FADE_RADIUS
    n = int(np.ceil(r / GRID_SPACING))
    k = (np.arange(-n, n + 1) * GRID_SPACING)
    # snap the grid to world multiples of the spacing, so it does not depend on the clip
    cx0, cz0 = np.round(cx / GRID_SPACING) * GRID_SPACING, np.round(cz / GRID_SPACING) * GRID_SPACING
    seg = np.arange(-n, n + 1) * GRID_SPACING
    s0, s1 = seg[:-1], seg[1:]
    hw = GRID_LINE_HALF_WIDTH
    off, a0 = np.meshgrid(k, s0, indexing="ij")
    _, a1 = np.meshgrid(k, s1, indexing="ij")
    off, a0, a1 = off.ravel(), a0.ravel(), a1.ravel()
    along_x = np.stack([np.stack([a0, off - hw], -1), np.stack([a0, off + hw], -1),
                        np.stack([a1, off + hw], -1), np.stack([a1, off - hw], -1)], axis=1)
    along_z = along_x[..., ::-1]
    q = np.concatenate([along_x, along_z]) + [cx0, cz0]  # (Q, 4, 2) as (x, z)
    pos = np.stack([q[..., 0], np.full(q.shape[:2], height + 2e-3), q[..., 1]], -1).reshape(-1, 3)
    dist = np.hypot(pos[:, 0] - cx, pos[:, 2] - cz)
    t = np.clip(dist / r, 0, 1)[:, None] ** 1.5
    grid, floor = _srgb_to_linear(GRID_COLOR), _srgb_to_linear(FLOOR_COLOR)
    col = np.hstack([grid * (1 - t) + floor * t, np.ones((len(pos), 1))]).astype(np.float32)
    b = 4 * np.arange(len(q))
    faces = np.concatenate([np.stack([b, b + 1, b + 2], 1), np.stack([b, b + 2, b + 3], 1)])
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                             metallicFactor=0.0, roughnessFactor=1.0,
                                             doubleSided=True)
    prim = pyrender.Primitive(positions=pos.astype(np.float32), color_0=col,
                              indices=faces.astype(np.uint32), material=mat, mode=4)
    return pyrender.Mesh([prim])


def _sky_mesh(centre, cam: Camera, height):
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
    """
    pyrender = load_pyrender()
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
        if not 0.0 <= elevation < ORTHO_HORIZON_DEG:
            return None
        # bottom edge at the height whose projection equals the floor point's: (c - ground_c
        # + y·dh)·up = 0
        dh = -((c - ground_c) @ cam.up) / (y @ cam.up)
        c = c + y * dh
    w, h = 20 * SKY_DISTANCE, 20 * SKY_DISTANCE
    pos = np.array([c - hr * w, c + hr * w, c + hr * w + y * h, c - hr * w + y * h], np.float32)
    col = np.tile(np.append(_srgb_to_linear(BACKGROUND), 1.0), (4, 1)).astype(np.float32)
    mat = pyrender.MetallicRoughnessMaterial(baseColorFactor=[1.0, 1.0, 1.0, 1.0],
                                             metallicFactor=0.0, roughnessFactor=1.0,
                                             doubleSided=True)
    prim = pyrender.Primitive(positions=pos, color_0=col,
                              indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                              material=mat, mode=4)
    return pyrender.Mesh([prim])


def shadow_vertices(vertices, light, ground):
    """Planar shadow: ``vertices`` (N, 3) projected onto the floor ``y = ground`` along
    the direction ``light`` (towards the light, ``light[1] > 0``); points under the
    floor drop straight down. Returns (N, 3)."""
    d = np.asarray(light, float)
    v = np.asarray(vertices, float)
    h = np.maximum(v[:, 1] - ground, 0.0)
    out = v - (h / d[1])[:, None] * d
    out[:, 1] = ground
    return out


class SceneRenderer:
    """Renders one scene's bodies, floor, shadows and lights, frame after frame.

    Build it once (floor, lights, colours), then call :meth:`render` per frame; the body
    pieces are re-posed (a gather and one matrix product, see :mod:`snapcore.render.body`) and
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
    body : SceneBody, optional
        Default :func:`snapcore.render.bodies.scene_body` (the scene's body kind).
    """

    def __init__(self, scene, *, size=(640, 480), ground=True, shadows=True, body=None):
        from snapcore.render.bodies import scene_body

        pyrender = load_pyrender()
        self.scene = scene
        self.size = check_size(size)
        self.body = body or scene_body(scene)
        self.ground = bool(ground)
        self.shadows = bool(shadows) and self.ground
        self._thread = threading.get_ident()
        # cleared to the floor colour: the floor is everything the sky does not cover
        bg = FLOOR_COLOR if self.ground else BACKGROUND
        self.pscene = pyrender.Scene(bg_color=[*bg, 1.0], ambient_light=[0.30] * 3)
        self._sky_node = None
        self._material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=0.7)
        # projected shadows have faces of both windings: draw them unculled
        self._shadow_material = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[1.0, 1.0, 1.0, 1.0], metallicFactor=0.0, roughnessFactor=1.0,
            doubleSided=True)
        n = len(self.body.characters)
        self._node = None
        self._shadow_node = None
        self._below = False  # camera under the floor (set with the camera)
        self._vcols = np.vstack([self._vertex_colors(i) for i in range(n)])
        self._faces = self.body.faces.astype(np.uint32)
        if self.shadows:
            from snapcore.render.bodies import MixedSceneBody, shadow_body
            from snapcore.render.body import TESSELLATION_COARSE, SceneBody

            # a coarse mannequin, or a glTF character's own mesh (posed once for both)
            self._shadow_body = (shadow_body(self.body, TESSELLATION_COARSE)
                                 if isinstance(self.body, MixedSceneBody)
                                 else SceneBody(scene, tessellation=TESSELLATION_COARSE))
            rgb = np.append(_srgb_to_linear(FLOOR_COLOR) * SHADOW_DARKEN, 1.0)
            self._shadow_rgb = np.tile(rgb, (self._shadow_body.n_vertices, 1)).astype(np.float32)
        if self.ground:
            b = scene.bounds()
            self._grid = _ground_mesh((b[0, [0, 2]] + b[1, [0, 2]]) / 2, scene.ground)
            self.pscene.add(self._grid)
        self._cam_node = None
        self._last_cam = None
        self._light_nodes = []
        self._shadow_dir = np.array([0.0, 1.0, 0.0])

    def _vertex_colors(self, i):
        b = self.body.characters[i]
        c = np.zeros((b.n_vertices, 4), np.float32)
        c[b.faces.ravel()] = np.repeat(b.face_colors, 3, axis=0) / 255.0
        c[:, :3] = c[:, :3] ** 2.2  # colours are sRGB; the shader multiplies in linear light
        return c

    def _set_camera(self, cam: Camera):
        pyrender = load_pyrender()
        # The floor reaches far beyond the characters: extend the depth range so it is
        # not clipped (an orthographic eye can move back freely without changing the
        # image; a perspective one keeps its near plane and sees farther).
        far = 2.0 * SKY_DISTANCE + float(np.ptp(self.scene.bounds()[:, [0, 2]]))
        if cam.projection == "orthographic":
            back = far
            gl_cam = Camera(cam.position + cam.back * back, cam.right, cam.up, cam.back, cam.size,
                            cam.projection, cam.half_height, cam.yfov, cam.znear + back,
                            cam.zfar + back + far)
        else:
            gl_cam = Camera(cam.position, cam.right, cam.up, cam.back, cam.size, cam.projection,
                            cam.half_height, cam.yfov, cam.znear, max(cam.zfar, far))
        if self._cam_node is None:
            self._cam_node = self.pscene.add(gl_cam.pyrender_camera(), pose=gl_cam.pose)
        else:
            self._cam_node.camera = gl_cam.pyrender_camera()
            self.pscene.set_pose(self._cam_node, gl_cam.pose)
        if self.ground:
            if self._sky_node is not None:
                self.pscene.remove_node(self._sky_node)
                self._sky_node = None
            b = self.scene.bounds()
            sky = _sky_mesh((b[0] + b[1]) / 2, cam, self.scene.ground)
            if sky is not None:
                self._sky_node = self.pscene.add(sky)
            # an almost level orthographic view sees the grid edge-on: a row of dashes
            # along the horizon, not a floor; leave it out
            level = (cam.projection == "orthographic"
                     and abs(np.degrees(np.arcsin(np.clip(cam.back[1], -1, 1)))) < ORTHO_HORIZON_DEG)
            # a camera under the floor would see its underside hide the feet; drawn, the
            # grid and the shadows cut through the legs instead: leave them out
            self._below = (cam.back[1] < 0 if cam.projection == "orthographic"
                           else cam.position[1] < self.scene.ground)
            self._grid.is_visible = not (level or self._below)
        for n in self._light_nodes:
            self.pscene.remove_node(n)
        self._light_nodes = []
        y = np.array([0.0, 1.0, 0.0])
        # Lights follow the camera so every view is lit alike: a key light from above
        # the camera's left, a weaker fill from the right, a rim light from behind.
        lights = ((cam.back + 1.4 * y - 0.8 * cam.right, 2.4),
                  (cam.back + 0.2 * y + 1.0 * cam.right, 0.9),
                  (-cam.back + 1.2 * y + 0.3 * cam.right, 1.1))
        for direction, intensity in lights:
            d = direction / np.linalg.norm(direction)  # from the scene towards the light
            m = np.eye(4)
            m[:3, :3] = np.stack(view_basis(d, None if abs(d[1]) < POLE_COS else [1.0, 0, 0]), 1)
            light = pyrender.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=intensity)
            self._light_nodes.append(self.pscene.add(light, pose=m))
        # the shadow light, in world terms: horizontal part from the camera's side
        hb = cam.back - y * (cam.back @ y)
        hb = hb / np.linalg.norm(hb) if np.linalg.norm(hb) > 1e-6 else cam.up
        hr = np.cross(y, hb)
        a, b, c = SHADOW_LIGHT
        d = a * hb + b * y + c * hr
        self._shadow_dir = d / np.linalg.norm(d)
        self._last_cam = cam

    def _update_bodies(self, frame: int):
        # All characters in one mesh and all shadows in another: each draw call costs
        # ~1 ms of Python and GL state in pyrender, the triangles themselves are cheap.
        pyrender = load_pyrender()
        prim = pyrender.Primitive(positions=self.body.vertices(frame).astype(np.float32),
                                  normals=self.body.normals(frame).astype(np.float32),
                                  color_0=self._vcols, indices=self._faces,
                                  material=self._material, mode=4)
        if self._node is not None:
            self.pscene.remove_node(self._node)
        self._node = self.pscene.add(pyrender.Mesh([prim]))
        if self.shadows:
            # a coarse stand-in, and only its faces turned to the light: every closed piece
            # then covers its shadow once (a tenth of the triangles, no overdraw)
            sb = self._shadow_body
            cv = sb.vertices(frame)
            tri = cv[sb.faces]
            lit = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]) @ self._shadow_dir > 0
            sv = shadow_vertices(cv, self._shadow_dir, self.scene.ground + 3e-3)
            sprim = pyrender.Primitive(positions=sv.astype(np.float32), color_0=self._shadow_rgb,
                                       indices=sb.faces[lit].astype(np.uint32),
                                       material=self._shadow_material, mode=4)
            if self._shadow_node is not None:
                self.pscene.remove_node(self._shadow_node)
            self._shadow_node = self.pscene.add(pyrender.Mesh([sprim]))
            self._shadow_node.mesh.is_visible = not self._below

    def render(self, frame: int, camera: Camera) -> np.ndarray:
        """The image of internal frame ``frame`` seen by ``camera``: (H, W, 3) uint8."""
        pyrender = load_pyrender()
        if threading.get_ident() != self._thread:
            raise RenderError("a SceneRenderer must be used on the thread that created it "
                              "(EGL contexts are thread-bound); make one per thread")
        if tuple(camera.size) != self.size:
            raise RenderError(f"camera size {camera.size} differs from the renderer's {self.size}")
        self.body._check(frame)
        if camera is not self._last_cam:
            self._set_camera(camera)
        self._update_bodies(int(frame))
        r = gl_renderer(*self.size)
        color, _ = r.render(self.pscene, flags=pyrender.RenderFlags.NONE)
        return np.ascontiguousarray(color)


def render_still(scene, frame: int, view=None, *, size=None, projection="orthographic",
                 fit="frame", ground=True, shadows=True, camera=None, renderer=None) -> np.ndarray:
    """One frame of a scene as an image.

    Parameters
    ----------
    scene : Scene
    frame : int
        Internal frame (``source frame - scene.frame_offset``).
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
    renderer : SceneRenderer, optional
        Reuse one (same thread, same size) when rendering many stills of a scene.

    Returns
    -------
    ndarray of uint8, shape (H, W, 3)
    """
    if size is None:
        size = renderer.size if renderer is not None else (800, 600)
    size = check_size(size)
    frame = int(frame)
    if not 0 <= frame < scene.n_frames:
        raise RenderError(f"frame {frame} is outside the scene's internal frames "
                          f"0..{scene.n_frames - 1} (source frames {scene.frame_offset}.."
                          f"{scene.frame_offset + scene.n_frames - 1})")
    sr = renderer or SceneRenderer(scene, size=size, ground=ground, shadows=shadows)
    if camera is None:
        if view is None:
            view = default_view(scene)
        if fit == "frame":
            pts = sr.body.vertices(frame)
        elif fit == "motion":
            pts = motion_points(scene, body=sr.body)
        else:
            raise RenderError(f"fit must be 'frame' or 'motion', got {fit!r}")
        camera = fit_camera(pts, view, size=size, projection=projection)
    return sr.render(frame, camera)


def render_mesh(vertices, faces, view, *, size=(512, 512), face_colors=None,
                projection="orthographic") -> np.ndarray:
    """Render any triangle mesh (e.g. a relief) lit like the stills, no floor:
    (H, W, 3) uint8. ``face_colors`` (M, 3|4) uint8, default light grey."""
    pyrender = load_pyrender()
    import trimesh

    size = check_size(size)
    tm = trimesh.Trimesh(np.asarray(vertices, float), np.asarray(faces, np.int64), process=False)
    if face_colors is not None:
        tm.visual.face_colors = face_colors
    else:
        tm.visual.face_colors = [200, 200, 200, 255]
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


def save_png(image: np.ndarray, path) -> None:
    """Write an (H, W, 3|4) uint8 image as PNG."""
    from PIL import Image

    Image.fromarray(np.asarray(image, np.uint8)).save(str(path))


