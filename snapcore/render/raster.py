"""The scene renderer's drawing: raw OpenGL on the thread's bare EGL context.

:class:`~snapcore.render.renderer.SceneRenderer` describes a picture as a few
:class:`DrawMesh` records (bodies, shadows, floor grid, sky), directional lights and a
camera; :func:`draw` rasterises them the way pyrender's forward pass did, without
importing pyrender (and trimesh, networkx and SciPy's optimiser with it: ~0.5 s of
``snapshot render``'s start-up), and without its per-frame scene bookkeeping:

- the same shaders (:data:`snapcore.render.gl._VERT`, ``_MESH_FRAG``) with the
  ``#define`` substitution pyrender's ``ShaderProgram._load`` makes (attribute
  locations in pyrender's order: position 0, normal, colour, instance matrix);
- the same uniforms in the same precision (float64 matrices rounded to float32 as
  PyOpenGL rounds them; light directions from the light node's matrix after
  pyrender's quaternion round trip, :func:`snapcore.render.camera.gl_node_matrix`);
- the same GL state: 4× multisampled RGBA8 colour and 24-bit depth, depth test
  ``GL_LESS``, blending on with ``(ONE, ZERO)``, back faces culled except for
  double-sided materials, the resolve by a linear blit, an RGB read-back.

Pictures agree with pyrender's to the pixel on the scenes of
``tests/test_raster_parity.py`` (pyrender draws the same records there).

GL objects live in a per-thread :class:`_Canvas` (programs, one vertex array per mesh
*slot*, framebuffers per size), not in the renderer that asks for a picture: a
renderer made per scene leaves nothing behind, and a slot re-uploads a mesh's
constant arrays (colours, indices) only when another mesh used it since
(:attr:`DrawMesh.key`).
"""

from __future__ import annotations

import ctypes
import re
import threading
from collections import OrderedDict
from dataclasses import dataclass

import numpy as np

from snapcore.render.gl import bare_gl_context

__all__ = ["DrawMesh", "Light", "Pending", "draw", "submit", "MAX_LIGHTS"]

#: pyrender's ``MAX_N_LIGHTS``: the size of the shaders' light array.
MAX_LIGHTS = 4
#: Samples per pixel (pyrender's multisampled main framebuffer). llvmpipe has no other
#: multisampled count: asked for 2 (or 1), it makes 4.
SAMPLES = 4
#: The highlight's ``x ** 24`` as products (``x * x * x``, squared three times), not
#: ``pow``: ~1.5 CPU-ms less a 1280x720 frame of the salsa pair (of ~32); a few pixels
#: one level apart (docs/speed.md). Off: the pictures stay pyrender's.
HIGHLIGHT_BY_SQUARES = False
#: Framebuffer sizes kept per thread, each as three sets (two for pipelined frames, one
#: for backgrounds: ~100 MB at 1280x720 with 4x multisampling); a batch alternates
#: two (thumbnails, preview panels).
_KEEP_SIZES = 3


@dataclass
class DrawMesh:
    """One draw call: an indexed triangle mesh with per-vertex colours.

    Attributes
    ----------
    slot : str
        Which of the thread's vertex arrays holds it ("body", "shadow", "grid"...):
        one slot per kind of mesh in a picture.
    key : object
        Identifies the constant arrays (``colors``, and ``indices`` unless
        ``dynamic_indices``) by identity: a slot re-uploads them only when the key
        object changes (the slot holds the key, so it cannot be reused meanwhile).
    positions : ndarray of float32, shape (N, 3)
        Metres, world frame.
    colors : ndarray of float32, shape (N, 4)
        Linear RGBA, 0-1.
    indices : ndarray of uint32, shape (M, 3)
    normals : ndarray of float32, shape (N, 3), optional
        Lit when given (Lambert and a soft highlight); unlit (its colour) without.
    roughness : float
        The material's roughness factor (the highlight's strength is ``1 - roughness``).
    vertex_lighting : bool
        Light it at the vertices and interpolate the colour (Gouraud; only the gamma per
        pixel) instead of per pixel: front faces only. ~9 CPU-ms less a 1280x720 frame
        of the salsa pair; pixels differ a little (docs/speed.md).
    double_sided : bool
        Draw back faces too (no culling).
    visible : bool
    dynamic_indices : bool
        The indices change between pictures (uploaded with every draw).
    static : bool
        The positions too are constant for the key (the floor grid, the sky): uploaded
        only when the key changes.
    """

    slot: str
    key: object
    positions: np.ndarray
    colors: np.ndarray
    indices: np.ndarray
    normals: np.ndarray | None = None
    roughness: float = 1.0
    vertex_lighting: bool = False
    double_sided: bool = False
    visible: bool = True
    dynamic_indices: bool = False
    static: bool = False


@dataclass(frozen=True)
class Light:
    """A directional light: ``direction`` (3,) float64 from the light into the scene
    (``-matrix[:3, 2]`` of its node), white, ``intensity``."""

    direction: np.ndarray
    intensity: float


def _program_source(text: str, defines: dict[str, int]) -> str:
    """``text`` with pyrender's define handling (``ShaderProgram._load``): ``#ifdef X``
    becomes ``#if 1`` or ``#if 0``, then every name is replaced by its value."""

    def ifdef(m: re.Match) -> str:
        return "#if 1" if m.group(1) in defines else "#if 0"

    def ifndef(m: re.Match) -> str:
        return "#if 0" if m.group(1) in defines else "#if 1"

    text = re.sub(r"#ifdef\s+([a-zA-Z_][a-zA-Z_0-9]*)\s*$", ifdef, text, flags=re.MULTILINE)
    text = re.sub(r"#ifndef\s+([a-zA-Z_][a-zA-Z_0-9]*)\s*$", ifndef, text, flags=re.MULTILINE)
    for name, value in defines.items():
        text = text.replace(name, str(value))
    return text


class _Program:
    """The mesh program for lit (with normals) or unlit primitives, and its uniforms;
    lit ones per pixel or, with ``vertex_lighting``, per vertex."""

    _NAMES = (
        "M",
        "V",
        "P",
        "cam_pos",
        "ambient_light",
        "n_directional_lights",
        "material.base_color_factor",
        "material.roughness_factor",
    )

    def __init__(self, lit: bool, vertex_lighting: bool = False) -> None:
        from OpenGL import GL as gl
        from OpenGL.GL import shaders

        from snapcore.render.gl import _MESH_FRAG, _VERT

        # pyrender's attribute locations: position 0, then normal, colour, instance matrix
        defines = {"NORMAL_LOC": 1, "COLOR_0_LOC": 2, "INST_M_LOC": 3} if lit else {}
        if not lit:
            defines = {"COLOR_0_LOC": 1, "INST_M_LOC": 2}
        defines.update(MAX_DIRECTIONAL_LIGHTS=MAX_LIGHTS, MAX_SPOT_LIGHTS=MAX_LIGHTS)
        defines["MAX_POINT_LIGHTS"] = MAX_LIGHTS
        defines["USE_METALLIC_MATERIAL"] = 1
        if HIGHLIGHT_BY_SQUARES:
            defines["HIGHLIGHT_BY_SQUARES"] = 1
        if lit and vertex_lighting:
            defines["VERTEX_LIGHTING"] = 1
        self.lit = lit
        self.color_loc = defines["COLOR_0_LOC"]
        self.inst_loc = defines["INST_M_LOC"]
        vao = gl.glGenVertexArrays(1)  # PyOpenGL validates programs against a bound VAO
        gl.glBindVertexArray(vao)
        self.id = shaders.compileProgram(
            shaders.compileShader(_program_source(_VERT, defines), gl.GL_VERTEX_SHADER),
            shaders.compileShader(_program_source(_MESH_FRAG, defines), gl.GL_FRAGMENT_SHADER),
        )
        gl.glBindVertexArray(0)
        gl.glDeleteVertexArrays(1, [vao])
        self.loc = {n: gl.glGetUniformLocation(self.id, n) for n in self._NAMES}
        self.light_loc = [
            tuple(
                gl.glGetUniformLocation(self.id, f"directional_lights[{i}].{field}")
                for field in ("direction", "color", "intensity")
            )
            for i in range(MAX_LIGHTS)
        ]


class _Slot:
    """A vertex array with its buffers (positions, normals, colours, indices, the
    identity instance matrix), grown as needed and rewritten in place."""

    def __init__(self) -> None:
        from OpenGL import GL as gl

        self.vao = gl.glGenVertexArrays(1)
        self.pos, self.nrm, self.col, self.ebo, self.inst = gl.glGenBuffers(5)
        self.capacity = {b: 0 for b in (self.pos, self.nrm, self.col, self.ebo)}
        self.key: object = None
        self.layout: tuple[int, int] | None = None  # (colour location, instance location)
        self.n_indices = 0
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self.inst)
        eye = np.eye(4, dtype=np.float32).ravel()
        gl.glBufferData(gl.GL_ARRAY_BUFFER, eye.nbytes, eye, gl.GL_STATIC_DRAW)

    def _put(self, target: int, buf: int, data: np.ndarray) -> None:
        from OpenGL import GL as gl

        gl.glBindBuffer(target, buf)
        if data.nbytes > self.capacity[buf]:
            gl.glBufferData(target, data.nbytes, data, gl.GL_DYNAMIC_DRAW)
            self.capacity[buf] = data.nbytes
        else:
            gl.glBufferSubData(target, 0, data.nbytes, data)

    def load(self, mesh: DrawMesh, program: _Program) -> None:
        """Upload ``mesh`` (positions and normals always; colours and indices when its
        key or layout changed, or indices every time if dynamic)."""
        from OpenGL import GL as gl

        gl.glBindVertexArray(self.vao)
        f32 = np.float32
        layout = (program.color_loc, program.inst_loc)
        fresh = mesh.key is not self.key or layout != self.layout
        if fresh or not mesh.static:
            self._put(gl.GL_ARRAY_BUFFER, self.pos, np.ascontiguousarray(mesh.positions, f32))
        if fresh:
            self._put(gl.GL_ARRAY_BUFFER, self.col, np.ascontiguousarray(mesh.colors, f32))
        if mesh.normals is not None:
            self._put(gl.GL_ARRAY_BUFFER, self.nrm, np.ascontiguousarray(mesh.normals, f32))
        if fresh or mesh.dynamic_indices:
            idx = np.ascontiguousarray(mesh.indices, np.uint32)
            self._put(gl.GL_ELEMENT_ARRAY_BUFFER, self.ebo, idx)
            self.n_indices = idx.size
        if layout != self.layout:
            for loc in range(8):
                gl.glDisableVertexAttribArray(loc)
            attributes = [(0, self.pos, 3), (program.color_loc, self.col, 4)]
            if program.lit:
                attributes.append((1, self.nrm, 3))
            for loc, buf, size in attributes:
                gl.glBindBuffer(gl.GL_ARRAY_BUFFER, buf)
                gl.glVertexAttribPointer(loc, size, gl.GL_FLOAT, gl.GL_FALSE, 0, None)
                gl.glEnableVertexAttribArray(loc)
            gl.glBindBuffer(gl.GL_ARRAY_BUFFER, self.inst)
            for i in range(4):
                loc = program.inst_loc + i
                gl.glVertexAttribPointer(
                    loc, 4, gl.GL_FLOAT, gl.GL_FALSE, 64, ctypes.c_void_p(16 * i)
                )
                gl.glEnableVertexAttribArray(loc)
                gl.glVertexAttribDivisor(loc, 1)
            self.layout = layout
        self.key = mesh.key


class _Framebuffers:
    """pyrender's offscreen targets at one size: 4× multisampled RGBA8 + depth24, and a
    single-sampled RGBA8 one the multisampled one is resolved into."""

    def __init__(self, w: int, h: int) -> None:
        from OpenGL import GL as gl

        self.size = (w, h)
        self.bg_fb: int | None = None  # the kept background (see keep)
        self.bg_rb: list[int] = []
        self.bg_key: object = None
        self.rb = list(gl.glGenRenderbuffers(3))
        self.fb_ms, self.fb = gl.glGenFramebuffers(2)
        for rb, fmt, samples in zip(
            self.rb, (gl.GL_RGBA, gl.GL_DEPTH_COMPONENT24, gl.GL_RGBA), (SAMPLES, SAMPLES, 0)
        ):
            gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, rb)
            if samples:
                gl.glRenderbufferStorageMultisample(gl.GL_RENDERBUFFER, samples, fmt, w, h)
            else:
                gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, fmt, w, h)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self.fb_ms)
        gl.glFramebufferRenderbuffer(
            gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_RENDERBUFFER, self.rb[0]
        )
        gl.glFramebufferRenderbuffer(
            gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_RENDERBUFFER, self.rb[1]
        )
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self.fb)
        gl.glFramebufferRenderbuffer(
            gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_RENDERBUFFER, self.rb[2]
        )
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)

    def keep(self, key: object) -> None:
        """Copy the multisampled colour and depth (every sample) into a second
        multisampled framebuffer, for :meth:`restore`, under ``key``."""
        from OpenGL import GL as gl

        w, h = self.size
        if self.bg_fb is None:
            self.bg_rb = list(gl.glGenRenderbuffers(2))
            for rb, fmt in zip(self.bg_rb, (gl.GL_RGBA, gl.GL_DEPTH_COMPONENT24)):
                gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, rb)
                gl.glRenderbufferStorageMultisample(gl.GL_RENDERBUFFER, SAMPLES, fmt, w, h)
            self.bg_fb = gl.glGenFramebuffers(1)
            gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, self.bg_fb)
            for att, rb in zip((gl.GL_COLOR_ATTACHMENT0, gl.GL_DEPTH_ATTACHMENT), self.bg_rb):
                gl.glFramebufferRenderbuffer(gl.GL_FRAMEBUFFER, att, gl.GL_RENDERBUFFER, rb)
        self._copy(self.fb_ms, self.bg_fb, (0, 0, w, h))
        self.bg_key = key

    def restore(self, key: object, rect: tuple[int, int, int, int], into: _Framebuffers) -> bool:
        """Put the samples kept under ``key`` back into ``rect`` (x, y from the bottom,
        w, h) of ``into``'s multisampled framebuffer (same size); False if another
        picture is kept."""
        if self.bg_fb is None or self.bg_key is not key:
            return False
        self._copy(self.bg_fb, into.fb_ms, rect)
        return True

    @staticmethod
    def _copy(src: int, dst: int, rect: tuple[int, int, int, int]) -> None:
        # multisampled to multisampled with the same sample count and rectangle: the
        # samples are copied as they are (no resolve, no filtering)
        from OpenGL import GL as gl

        x, y, w, h = rect
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, src)
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, dst)
        gl.glBlitFramebuffer(
            x, y, x + w, y + h, x, y, x + w, y + h,
            gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT, gl.GL_NEAREST,
        )  # fmt: skip

    def delete(self) -> None:
        from OpenGL import GL as gl

        gl.glDeleteFramebuffers(2, [self.fb_ms, self.fb])
        gl.glDeleteRenderbuffers(3, self.rb)
        if self.bg_fb is not None:
            gl.glDeleteFramebuffers(1, [self.bg_fb])
            gl.glDeleteRenderbuffers(2, self.bg_rb)


class _Canvas:
    """A thread's GL objects for :func:`draw`, in its bare context."""

    def __init__(self, ctx: object) -> None:
        self.ctx = ctx
        self.programs = {lit: _Program(lit) for lit in (True, False)}
        self._vertex_lit: _Program | None = None  # compiled when first asked for
        self.slots: dict[str, _Slot] = {}
        self.fbs: OrderedDict[tuple[int, int, int], _Framebuffers] = OrderedDict()
        #: per size, the framebuffers whose kept samples frames restore
        self.kept: dict[tuple[int, int], _Framebuffers] = {}

    def framebuffers(self, w: int, h: int, buffer: int) -> _Framebuffers:
        fb = self.fbs.pop((w, h, buffer), None)
        if fb is None:
            fb = _Framebuffers(w, h)
            while len(self.fbs) >= _KEEP_SIZES * 3:
                old = self.fbs.popitem(last=False)[1]
                if self.kept.get(old.size) is old:
                    del self.kept[old.size]
                old.delete()
        self.fbs[(w, h, buffer)] = fb
        return fb

    def program(self, mesh: DrawMesh) -> _Program:
        if mesh.normals is None or not mesh.vertex_lighting:
            return self.programs[mesh.normals is not None]
        if self._vertex_lit is None:
            self._vertex_lit = _Program(True, vertex_lighting=True)
        return self._vertex_lit

    def slot(self, name: str) -> _Slot:
        if name not in self.slots:
            self.slots[name] = _Slot()
        return self.slots[name]


_THREAD = threading.local()


def _canvas() -> _Canvas:
    ctx = bare_gl_context()
    canvas = getattr(_THREAD, "canvas", None)
    if canvas is None or canvas.ctx is not ctx:  # first use, or a new context
        canvas = _Canvas(ctx)
        _THREAD.canvas = canvas
    return canvas


def draw(meshes: list[DrawMesh], **kwargs) -> np.ndarray:
    """:func:`submit` and wait: the picture, (H, W, 3) uint8 (see :func:`submit`)."""
    return submit(meshes, **kwargs).read()


def submit(
    meshes: list[DrawMesh],
    *,
    size: tuple[int, int],
    view: np.ndarray,
    projection: np.ndarray,
    cam_pos: np.ndarray,
    lights: list[Light],
    ambient: float,
    clear: tuple[float, float, float],
    window: tuple[int, int, int, int] | None = None,
    keep: object = None,
    background: tuple[object, int] | None = None,
    buffer: int = 0,
) -> Pending:
    """Rasterise ``meshes`` into an RGB image, as pyrender's forward pass would;
    :meth:`Pending.read` of the result waits for it and reads it back.

    Parameters
    ----------
    meshes : list of DrawMesh
        Drawn in this order (depth-tested; order matters only at exact depth ties).
    size : (int, int)
        Width and height, pixels.
    view, projection : ndarray of float64, shape (4, 4)
        World → camera and camera → clip matrices.
    cam_pos : ndarray, shape (3,)
        The camera's position (metres; for the highlight).
    lights : list of Light
        At most :data:`MAX_LIGHTS`.
    ambient : float
        Ambient light, the same in each channel.
    clear : (r, g, b)
        The colour every pixel starts with (sRGB 0-1, written as is).
    window : (x0, y0, width, height), optional
        Draw, resolve and read back only this rectangle of the picture (pixels, row 0
        at the top), through a scissor: the same viewport and matrices, so its pixels
        are the full picture's, bit for bit; llvmpipe skips the tiles outside it.
    keep : object, optional
        Keep this picture's samples (colour and depth, multisampled) under this key.
    background : (key, n), optional
        The first ``n`` meshes are the picture kept under ``key``: if it is still kept
        (same size), its samples are copied into the window instead of clearing and
        drawing those meshes again (the same samples: exact), else they are drawn.
    buffer : int
        Which of the thread's framebuffers and vertex buffers of this size to use
        (0-2): a picture not yet read back keeps its own while the next is submitted.

    Returns
    -------
    Pending
        Its ``read()``: ndarray of uint8, shape (H, W, 3), or (height, width, 3) with
        ``window``; row 0 at the top.
    """
    from OpenGL import GL as gl

    w, h = int(size[0]), int(size[1])
    canvas = _canvas()
    fb = canvas.framebuffers(w, h, buffer)
    gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, fb.fb_ms)
    gl.glViewport(0, 0, w, h)
    gl.glEnable(gl.GL_DEPTH_TEST)
    gl.glDepthMask(gl.GL_TRUE)
    gl.glDepthFunc(gl.GL_LESS)
    gl.glDepthRange(0.0, 1.0)
    if window is None:
        rx, ry, rw, rh = 0, 0, w, h
        gl.glDisable(gl.GL_SCISSOR_TEST)
    else:
        x0, y0, rw, rh = (int(v) for v in window)
        rx, ry = x0, h - y0 - rh  # GL rows run bottom-up
        gl.glEnable(gl.GL_SCISSOR_TEST)
        gl.glScissor(rx, ry, rw, rh)
    kept = canvas.kept.get((w, h))
    if (
        background is not None
        and kept is not None
        and kept.restore(background[0], (rx, ry, rw, rh), into=fb)
    ):
        meshes = meshes[background[1] :]
        gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, fb.fb_ms)
    else:
        gl.glClearColor(*(float(np.float32(c)) for c in clear), 1.0)
        gl.glClear(gl.GL_COLOR_BUFFER_BIT | gl.GL_DEPTH_BUFFER_BIT)
    gl.glEnable(gl.GL_MULTISAMPLE)
    gl.glEnable(gl.GL_BLEND)
    gl.glBlendFunc(gl.GL_ONE, gl.GL_ZERO)
    gl.glPolygonMode(gl.GL_FRONT_AND_BACK, gl.GL_FILL)
    gl.glFrontFace(gl.GL_CCW)
    gl.glCullFace(gl.GL_BACK)
    f32 = np.float32
    eye = np.eye(4, dtype=f32)
    v32, p32 = np.asarray(view, f32), np.asarray(projection, f32)
    cam32 = np.asarray(cam_pos, f32)
    amb = np.full(3, ambient, f32)
    for mesh in meshes:
        if not mesh.visible or len(mesh.indices) == 0:
            continue
        program = canvas.program(mesh)
        gl.glUseProgram(program.id)
        loc = program.loc
        gl.glUniformMatrix4fv(loc["V"], 1, gl.GL_TRUE, v32)
        gl.glUniformMatrix4fv(loc["P"], 1, gl.GL_TRUE, p32)
        gl.glUniformMatrix4fv(loc["M"], 1, gl.GL_TRUE, eye)
        gl.glUniform3fv(loc["cam_pos"], 1, cam32)
        if program.lit:
            gl.glUniform3fv(loc["ambient_light"], 1, amb)
            gl.glUniform1i(loc["n_directional_lights"], len(lights))
            for (l_dir, l_col, l_int), light in zip(program.light_loc, lights):
                gl.glUniform3fv(l_dir, 1, np.asarray(light.direction, f32))
                gl.glUniform3fv(l_col, 1, np.ones(3, f32))
                gl.glUniform1f(l_int, float(light.intensity))
            gl.glUniform1f(loc["material.roughness_factor"], float(mesh.roughness))
        gl.glUniform4fv(loc["material.base_color_factor"], 1, np.ones(4, f32))
        slot = canvas.slot(f"{mesh.slot}/{buffer}")
        slot.load(mesh, program)
        if mesh.double_sided:
            gl.glDisable(gl.GL_CULL_FACE)
        else:
            gl.glEnable(gl.GL_CULL_FACE)
        gl.glDrawElementsInstanced(gl.GL_TRIANGLES, slot.n_indices, gl.GL_UNSIGNED_INT, None, 1)
    gl.glBindVertexArray(0)
    gl.glUseProgram(0)
    gl.glDisable(gl.GL_SCISSOR_TEST)
    if keep is not None:
        fb.keep(keep)
        canvas.kept[(w, h)] = fb
    # resolve (a linear blit) in the same flush, so a later picture's commands need
    # not finish before this one can be read
    gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, fb.fb_ms)
    gl.glBindFramebuffer(gl.GL_DRAW_FRAMEBUFFER, fb.fb)
    x1, y1 = rx + rw, ry + rh
    gl.glBlitFramebuffer(rx, ry, x1, y1, rx, ry, x1, y1, gl.GL_COLOR_BUFFER_BIT, gl.GL_LINEAR)
    gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
    gl.glFlush()  # llvmpipe's threads start on the fragments now
    return Pending(canvas, fb, (rx, ry, rw, rh))


class Pending:
    """A picture submitted by :func:`submit`, rasterised by llvmpipe's threads while
    the caller does other work (posing the next frame); :meth:`read` waits for it."""

    def __init__(self, canvas: _Canvas, fb: _Framebuffers, rect: tuple[int, int, int, int]):
        self._canvas, self._fb, self._rect = canvas, fb, rect

    def read(self) -> np.ndarray:
        """Wait for the resolved picture and read it back: (H, W, 3) uint8, row 0 at
        the top (a view of an RGBA array)."""
        from OpenGL import GL as gl

        if _canvas() is not self._canvas:
            raise RuntimeError("internal: a picture read back in another GL context")
        fb = self._fb
        rx, ry, rw, rh = self._rect
        gl.glBindFramebuffer(gl.GL_READ_FRAMEBUFFER, fb.fb)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 1)
        # RGBA: the renderbuffer's own layout, copied without a per-pixel conversion
        out = np.empty((rh, rw, 4), np.uint8)
        gl.glReadPixels(rx, ry, rw, rh, gl.GL_RGBA, gl.GL_UNSIGNED_BYTE, out)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        return out[::-1, :, :3]
