"""Face-id and depth buffers: which face, and how far, at every pixel of a view.

The viewpoint-entropy baseline (:mod:`snapcore.render.viewpoint_entropy`) counts the
pixels of each face in many views; the relief (:mod:`snapcore.relief`) needs an exact
depth image of one pose. Both come from the same id pass, rendered with the thread's
GL context (:mod:`snapcore.render.gl`).

Face-id buffers
---------------
:func:`render_face_ids` draws the mesh one-sided, with a program of its own (raw GL in
the thread's context, not a pyrender scene): the fragment shader writes the face's index
+ 1 (0 = background), carried by the face's last vertex as a flat attribute, into a
32-bit integer target, single-sampled, with no lighting or blending, so every id is one
face's. Each view is a layer of an array texture and the layers are read back together;
with many views two GL contexts on two threads draw half each. The ids are identical to
the pixel to those of the plain pass (one indexed draw per view, ``gl_PrimitiveID + 1``:
``tests/face_id_reference.py``), and the recorded viewpoint-entropy scores are unchanged.
:func:`render_depth` reuses the id pass and intersects each pixel's ray with the plane of
the face it shows, so depth is exact (float64), free of depth-buffer quantisation.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass

import numpy as np

from snapcore.errors import RenderError
from snapcore.render.camera import Camera, gl_camera_pose, gl_projection, view_basis
from snapcore.render.gl import current_gl_context

__all__ = [
    "DepthMap",
    "render_face_ids",
    "face_id_blocks",
    "face_id_camera",
    "render_depth",
    "FACE_ID_RESOLUTION",
]

#: Default square resolution (pixels) of face-id buffers. The number of faces a view
#: "sees" depends strongly on it (3.2k faces/view at 256² vs 8.9k at 512² for a 77k-face
#: mesh), so the viewpoint-entropy baseline fixes one resolution: this one.
FACE_ID_RESOLUTION = 256


# --------------------------------------------------------------------------- face ids


def _id_mesh(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """The mesh as float64 vertices (N, 3) and int64 faces (M, 3), checked."""
    v = np.asarray(vertices, dtype=np.float64)
    f = np.asarray(faces, dtype=np.int64)
    if v.ndim != 2 or v.shape[1] != 3 or f.ndim != 2 or f.shape[1] != 3:
        raise RenderError(f"need vertices (N, 3) and faces (M, 3), got {v.shape} and {f.shape}")
    if len(f) == 0 or len(v) == 0:
        raise RenderError("the mesh has no faces")
    if f.min() < 0 or f.max() >= len(v):
        raise RenderError("faces index vertices that do not exist")
    if len(f) >= 2**31 - 1:
        raise RenderError(f"{len(f)} faces do not fit a 32-bit id buffer")
    if not np.all(np.isfinite(v)):
        raise RenderError("vertices must be finite")
    return v, f


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
    return Camera(
        c + back * dist,
        right,
        up,
        back,
        (int(resolution), int(resolution)),
        "orthographic",
        half_height=r,
        znear=0.5 * r,
        zfar=3.5 * r,
    )


#: The id pass's shaders: the fragment writes its face's index + 1 into a 32-bit integer
#: target, so ids are exact by construction (no colour encoding, no blending). The id
#: comes from the triangle's provoking (last) vertex as a flat integer attribute, not
#: from ``gl_PrimitiveID``: Mesa's llvmpipe serves ``gl_PrimitiveID`` to a fragment
#: shader by re-assembling every primitive with the id as an extra vertex (its
#: "primitive assembler"), which cost ~30% of the pass, culled triangles included.
_ID_VERTEX = """#version 330 core
layout(location = 0) in vec3 position;
layout(location = 1) in int face_in;
uniform mat4 V;
uniform mat4 P;
flat out int face_id;
void main() {
    gl_Position = P * V * vec4(position, 1.0);
    face_id = face_in;
}
"""
_ID_FRAGMENT = """#version 330 core
flat in int face_id;
out int face;
void main() { face = face_id; }
"""
#: Views drawn per read-back: each view is one layer of an integer array texture, and
#: the layers are read in one call (a pyrender render per view cost ~7 ms of scene set-up
#: and read-back on llvmpipe, more than the drawing). Layers, not tiles of one big
#: image: a tile's offset changes the float rounding of window coordinates, and ids at
#: edges with it; a layer is drawn at the same coordinates as a lone view.
_LAYERS_PER_PASS = 64


def _view_projection(cam: Camera) -> tuple[np.ndarray, np.ndarray]:
    """World → camera and camera → clip matrices (float32) of ``cam``, computed as
    pyrender computes them for a render (the pose through a scene node, then inverted),
    so ids are the same, to the pixel, as the pyrender pass this replaced."""
    return (
        np.linalg.inv(gl_camera_pose(cam)).astype(np.float32),
        gl_projection(cam).astype(np.float32),
    )


def _id_program(renderer):
    """The id program of ``renderer``'s GL context, compiled on first use (kept on the
    renderer, so a new context after :func:`snapcore.render.gl.release_renderer` gets
    its own)."""
    from OpenGL.GL import GL_FRAGMENT_SHADER, GL_VERTEX_SHADER, shaders

    prog = getattr(renderer, "_snap_id_program", None)
    if prog is None:
        prog = shaders.compileProgram(
            shaders.compileShader(_ID_VERTEX, GL_VERTEX_SHADER),
            shaders.compileShader(_ID_FRAGMENT, GL_FRAGMENT_SHADER),
            validate=False,
        )
        renderer._snap_id_program = prog
    return prog


def _unshared_layout(vertices, faces) -> tuple[np.ndarray, np.ndarray]:
    """The mesh laid out for the id pass: three vertices of its own per face.

    Returns positions (3M, 3) float32 (face k's corners, in their order, at rows
    3k..3k+2) and per-vertex ids (3M,) int32 (k + 1 on all three). Drawn as a plain
    triangle list (``glDrawArrays``), face k is the k-th triangle, drawn in its place
    with the same float32 corners as from an index buffer, so it rasterises as before;
    its last (provoking) vertex carries its id to the fragment as a flat attribute.
    An indexed draw with a copy per face of only its last corner gave the same ids at
    ~10% more CPU on llvmpipe (its index splitting and vertex cache cost more than
    shading every corner).
    """
    v = np.asarray(vertices, dtype=np.float32)
    pos = np.take(v, np.asarray(faces).reshape(-1), axis=0)
    ids = np.repeat(np.arange(1, len(faces) + 1, dtype=np.int32), 3)
    return pos, ids


#: GL contexts (threads) that draw the views of one call between them when it has at
#: least :data:`_MIN_VIEWS_PER_THREAD` views each. llvmpipe does a draw's vertex
#: processing, culling and binning on the thread that issues it (~70% of the pass's
#: CPU) and rasterises on its own threads, so one issuing thread leaves a core idle.
#: Every context draws with the same driver and program: the ids do not depend on
#: which one drew a view.
_ID_THREADS = min(2, os.cpu_count() or 1)
_MIN_VIEWS_PER_THREAD = 16
_POOL: dict = {}  # process id -> the helper threads' executor, made on first use


def _helpers():
    """This process's executor for helper draws (each of its threads keeps its GL
    context and compiled program between calls). Keyed by process: a child forked
    after the first call inherits the executor but not its thread, and would wait on
    it forever."""
    pid = os.getpid()
    if pid not in _POOL:
        from concurrent.futures import ThreadPoolExecutor

        _POOL.clear()
        _POOL[pid] = ThreadPoolExecutor(
            max_workers=_ID_THREADS - 1, thread_name_prefix="snapcore-ids"
        )
    return _POOL[pid]


def _render_ids(vertices, faces, cameras) -> np.ndarray:
    """Face ids (0 = none, k + 1 = face k) of one mesh seen by ``cameras`` of one size,
    shape (V, H, W): one draw call per view into a layer of an integer array texture;
    with many views, contiguous runs of them drawn by :data:`_ID_THREADS` threads."""
    w, h = cameras[0].size
    out = np.empty((len(cameras), h, w), np.int32)
    _draw_all(vertices, faces, cameras, out, None)
    return out


def _draw_all(vertices, faces, cameras, out, each_block) -> None:
    """:func:`_render_ids` into ``out``, or, with ``out`` None, each read-back handed to
    ``each_block(first, ids)`` (ids of views ``first ..`` as read, rows bottom-up, on
    the thread that drew them: no (V, H, W) array is made or flipped)."""
    pos, ids = _unshared_layout(vertices, faces)
    parts = max(1, min(_ID_THREADS, len(cameras) // _MIN_VIEWS_PER_THREAD))
    edges = [len(cameras) * i // parts for i in range(parts + 1)]
    runs = [
        (cameras[a:b], None if out is None else out[a:b], each_block, a)
        for a, b in zip(edges[:-1], edges[1:])
    ]
    helpers = [_helpers().submit(_draw_ids, pos, ids, *run) for run in runs[1:]]
    try:
        _draw_ids(pos, ids, *runs[0])
    finally:
        for job in helpers:
            job.result()


def _draw_ids(pos, ids, cameras, out, each_block=None, first=0) -> None:
    """Draw the unshared triangle list ``pos``/``ids`` (:func:`_unshared_layout`) for
    each camera into ``out`` (V, H, W) int32 (or hand each read-back to ``each_block``
    with the index of its first view, ``first`` for the first camera), in this thread's
    GL context."""
    from OpenGL import GL as gl

    w, h = cameras[0].size
    r = current_gl_context(w, h)
    n_views = len(cameras)
    passes = -(-n_views // _LAYERS_PER_PASS)
    layers = -(-n_views // passes)  # the passes' views evened out
    vao = gl.glGenVertexArrays(1)
    vbo, ibo = gl.glGenBuffers(2)
    fbo = gl.glGenFramebuffers(1)
    tex = gl.glGenTextures(1)
    depth = gl.glGenRenderbuffers(1)
    try:
        gl.glBindVertexArray(vao)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, vbo)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, pos.nbytes, pos, gl.GL_STATIC_DRAW)
        gl.glEnableVertexAttribArray(0)
        gl.glVertexAttribPointer(0, 3, gl.GL_FLOAT, gl.GL_FALSE, 0, None)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, ibo)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, ids.nbytes, ids, gl.GL_STATIC_DRAW)
        gl.glEnableVertexAttribArray(1)
        gl.glVertexAttribIPointer(1, 1, gl.GL_INT, 0, None)
        prog = _id_program(r)
        gl.glUseProgram(prog)
        loc_v = gl.glGetUniformLocation(prog, "V")
        loc_p = gl.glGetUniformLocation(prog, "P")
        gl.glBindTexture(gl.GL_TEXTURE_2D_ARRAY, tex)
        gl.glTexImage3D(
            gl.GL_TEXTURE_2D_ARRAY,
            0,
            gl.GL_R32I,
            w,
            h,
            layers,
            0,
            gl.GL_RED_INTEGER,
            gl.GL_INT,
            None,
        )
        gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, depth)
        gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_DEPTH_COMPONENT24, w, h)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, fbo)
        gl.glFramebufferRenderbuffer(
            gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_RENDERBUFFER, depth
        )
        gl.glFramebufferTextureLayer(gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, tex, 0, 0)
        if gl.glCheckFramebufferStatus(gl.GL_FRAMEBUFFER) != gl.GL_FRAMEBUFFER_COMPLETE:
            raise RenderError("the GL driver cannot render into a 32-bit integer target")
        gl.glDrawBuffers(1, [gl.GL_COLOR_ATTACHMENT0])
        # Single-sampled target, no blending: every pixel is one face's id. Back faces
        # are culled (counter-clockwise = front), so only front faces get ids.
        gl.glViewport(0, 0, w, h)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_MULTISAMPLE)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glDepthMask(gl.GL_TRUE)
        gl.glEnable(gl.GL_CULL_FACE)
        gl.glFrontFace(gl.GL_CCW)
        gl.glCullFace(gl.GL_BACK)
        gl.glProvokingVertex(gl.GL_LAST_VERTEX_CONVENTION)  # the flat id: the last corner's
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 4)
        mats = [_view_projection(c) for c in cameras]
        block = np.empty((layers, h, w), np.int32)
        no_face, far = np.zeros(4, np.int32), np.ones(1, np.float32)
        for start in range(0, n_views, layers):
            n = min(layers, n_views - start)
            for k in range(n):  # one draw call per view: a layer and two matrices
                gl.glFramebufferTextureLayer(gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, tex, 0, k)
                gl.glClearBufferiv(gl.GL_COLOR, 0, no_face)
                gl.glClearBufferfv(gl.GL_DEPTH, 0, far)
                gl.glUniformMatrix4fv(loc_v, 1, gl.GL_TRUE, mats[start + k][0])
                gl.glUniformMatrix4fv(loc_p, 1, gl.GL_TRUE, mats[start + k][1])
                gl.glDrawArrays(gl.GL_TRIANGLES, 0, len(pos))
            gl.glGetTexImage(gl.GL_TEXTURE_2D_ARRAY, 0, gl.GL_RED_INTEGER, gl.GL_INT, block)
            if out is None:
                each_block(first + start, block[:n])
            else:
                out[start : start + n] = block[:n, ::-1]  # GL rows run bottom-up
    finally:
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        gl.glBindVertexArray(0)
        gl.glUseProgram(0)
        gl.glDisable(gl.GL_CULL_FACE)
        gl.glDeleteFramebuffers(1, [fbo])
        gl.glDeleteTextures([tex])
        gl.glDeleteRenderbuffers(1, [depth])
        gl.glDeleteBuffers(2, [vbo, ibo])
        gl.glDeleteVertexArrays(1, [vao])


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
    75k-face mesh at 256² in ~1 s (``snapshot bench --only "face ids"``; docs/speed.md).
    """
    single = np.ndim(views) == 1
    v, f, cams = _face_id_cameras(vertices, faces, views, resolution)
    ids = _render_ids(v, f, cams)
    return ids[0] if single else ids


def _face_id_cameras(vertices, faces, views, resolution):
    """The checked mesh and the cameras of :func:`render_face_ids`."""
    views = np.asarray(views, float).reshape(-1, 3)
    if views.shape[0] == 0:
        raise RenderError("no views given")
    v, f = _id_mesh(vertices, faces)
    sphere = _bounding_sphere(vertices)
    cams = [face_id_camera(vertices, u, resolution=resolution, sphere=sphere) for u in views]
    return v, f, cams


def face_id_blocks(vertices, faces, views, each_block, *, resolution=FACE_ID_RESOLUTION) -> None:
    """:func:`render_face_ids` for reductions that ignore the pixels' order (histograms).

    ``each_block(first, ids)`` is called instead of returning the ids: ``ids`` int32 of
    shape (n, resolution, resolution), the ids of views ``first .. first + n - 1`` with
    rows bottom-up (as read back), possibly on a helper thread while other views are
    drawn. No (V, H, W) array is made or flipped. The calls for different blocks may run
    at the same time: ``each_block`` must only write results of its own views.
    """
    v, f, cams = _face_id_cameras(vertices, faces, views, resolution)
    _draw_all(v, f, cams, None, each_block)


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
        return self.origin + xs[None, :, None] * self.right - ys[:, None, None] * self.up

    def points(self) -> np.ndarray:
        """World surface point at each pixel (NaN for background), shape (H, W, 3)."""
        return self.pixel_centers() + self.depth[..., None] * self.forward


def render_depth(
    vertices, faces, view, *, resolution=512, extent=None, up=None, margin=0.02
) -> DepthMap:
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
        side = int(resolution)
        if hw >= hh:
            w, h = side, max(int(round(side * hh / hw)), 1)
        else:
            w, h = max(int(round(side * hw / hh)), 1), side
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
    cam = Camera(
        origin,
        right,
        upv,
        back,
        (w, h),
        "orthographic",
        half_height=hh,
        znear=pad * 0.5,
        zfar=pad + depth_span + pad,
    )
    ids = _render_ids(*_id_mesh(v, f), [cam])[0]
    depth = np.full((h, w), np.nan)
    hit = ids > 0
    if np.any(hit):
        k = ids[hit] - 1
        tri = v[f[k]]  # (P, 3, 3)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        ii, jj = np.nonzero(hit)
        o = (
            origin
            + ((jj + 0.5 - w / 2) * s)[:, None] * right
            - ((ii + 0.5 - h / 2) * s)[:, None] * upv
        )
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
