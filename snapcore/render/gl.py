"""The offscreen OpenGL context: pyrender on Mesa EGL, one renderer per thread.

Measured on two cores: Mesa's EGL (llvmpipe) renders a 20k-face scene at 640×480 at
~25 fps where OSMesa manages ~2 (../shared/PLATFORM-NOTES.md), so ``PYOPENGL_PLATFORM``
defaults to ``egl`` here, before OpenGL loads. Everything that touches pyrender's
internals lives in this module, applied once in :func:`load_pyrender`:

- the NumPy-2 shim (pyrender 0.1.45 uses ``np.infty``);
- a colour-only framebuffer read (pyrender always reads and linearises depth too);
- EGL context deletion that leaves the process-wide display up (pyrender terminates
  it, which breaks every other thread's context);
- cheaper shaders (:data:`_MESH_FRAG`) under pyrender's uniform names;
- no interactive viewer (:func:`_stub_viewer`: pyglet is not imported).

Threads: an EGL context works only on the thread that created it, and a pyrender mesh
stays bound to its first context. :func:`gl_renderer` keeps one renderer per thread;
the face-id pass (:mod:`snapcore.render.buffers`) draws with raw GL calls in the same
context.
"""

from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")  # before anything imports OpenGL

import threading  # noqa: E402

import numpy as np  # noqa: E402

from snapcore.errors import RenderError  # noqa: E402

__all__ = ["gl_renderer", "current_gl_context", "release_renderer"]

_PYRENDER = None
_THREAD = threading.local()


def load_pyrender():
    """Import pyrender once, with the NumPy-2 shim and the patches below."""
    global _PYRENDER
    if _PYRENDER is None:
        if not hasattr(np, "infty"):
            np.infty = np.inf  # noqa: NPY201 -- pyrender 0.1.45 uses np.infty, gone in NumPy 2
        _stub_viewer()
        try:
            import pyrender
            import pyrender.renderer as prr
        except Exception as err:  # ImportError, or a GL loader error naming the library
            raise RenderError(
                f"cannot load pyrender/OpenGL ({err}); headless rendering needs Mesa EGL "
                "(apt-get install libegl1 libegl-mesa0 libgl1-mesa-dri) and "
                "PYOPENGL_PLATFORM=egl"
            ) from err
        # EGL displays are shared by every context in the process: pyrender's
        # delete_context() terminates the display, which would invalidate the other
        # threads' contexts. Destroy the context only.
        try:
            from pyrender.platforms import egl as _egl
        except ImportError:  # another platform (OSMesa): nothing shared to protect
            _egl = None

        def _delete_context(self):
            from OpenGL.EGL import eglDestroyContext

            if self._egl_display is not None and self._egl_context is not None:
                eglDestroyContext(self._egl_display, self._egl_context)
            self._egl_context = None

        if _egl is not None:
            _egl.EGLPlatform.delete_context = _delete_context
        prr.Renderer._read_main_framebuffer = _read_colour_only(prr.Renderer._read_main_framebuffer)
        _PYRENDER = pyrender
    return _PYRENDER


def _stub_viewer() -> None:
    """Put a stand-in for ``pyrender.viewer`` in :data:`sys.modules` before pyrender loads.

    pyrender's ``__init__`` imports its interactive viewer, which imports pyglet (its X11
    window, GLX and tkinter bindings) and imageio: ~0.1-0.25 s of every ``snapshot
    render``'s start-up, for a window this package never opens (it renders offscreen).
    """
    import sys
    import types

    if "pyrender.viewer" in sys.modules:
        return
    stub = types.ModuleType("pyrender.viewer", "Stand-in: snapcore renders offscreen only.")

    class Viewer:
        def __init__(self, *args, **kwargs):
            raise RenderError("pyrender's interactive viewer is not loaded (offscreen only)")

    stub.Viewer = Viewer  # type: ignore[attr-defined]
    sys.modules["pyrender.viewer"] = stub


# Shaders. pyrender's physically based shader costs ~1 µs per pixel on llvmpipe (a
# 1280×720 frame took ~0.6 s); these replace it with Lambert diffuse + a soft
# Blinn-Phong highlight under the same uniform names pyrender sets (so pyrender's
# renderer drives them unchanged), ~5× cheaper. Primitives without normals are drawn
# unlit in their vertex colour (the floor grid and the shadows). Colours are linear; output is
# gamma-encoded (1/2.2) like pyrender's. (The exact id pass has its own program:
# :mod:`snapcore.render.buffers`.)
#: The lighting (uniforms and a function of the linear base colour, unit normal and
#: world position), shared by the per-pixel shader below and the per-vertex one.
_LIGHTING = """struct DirectionalLight { vec3 direction; vec3 color; float intensity; };
struct Material { vec4 base_color_factor; float roughness_factor; };
uniform Material material;
uniform DirectionalLight directional_lights[MAX_DIRECTIONAL_LIGHTS];
uniform int n_directional_lights;
uniform vec3 ambient_light;
uniform vec3 cam_pos;
vec3 shade(vec3 base, vec3 n, vec3 p) {
    vec3 e = normalize(cam_pos - p);
    float shine = 1.0 - material.roughness_factor;
    vec3 c = ambient_light * base;
    for (int i = 0; i < n_directional_lights; i++) {
        vec3 l = -directional_lights[i].direction;
        float d = max(dot(n, l), 0.0);
        vec3 h = normalize(l + e);
#ifdef HIGHLIGHT_BY_SQUARES
        float x = max(dot(n, h), 0.0), x3 = x * x * x, x6 = x3 * x3, x12 = x6 * x6;
        float s = shine * 0.5 * (x12 * x12) * step(0.0, d);
#else
        float s = shine * 0.5 * pow(max(dot(n, h), 0.0), 24.0) * step(0.0, d);
#endif
        c += directional_lights[i].color * directional_lights[i].intensity * 0.32
             * (base * d + vec3(s));
    }
    return c;
}
"""

_VERT = (
    """#version 330 core
layout(location = 0) in vec3 position;
#ifdef NORMAL_LOC
layout(location = NORMAL_LOC) in vec3 normal;
#endif
#ifdef COLOR_0_LOC
layout(location = COLOR_0_LOC) in vec4 color_0;
#endif
layout(location = INST_M_LOC) in mat4 inst_m;
uniform mat4 M;
uniform mat4 V;
uniform mat4 P;
out vec3 frag_position;
out vec3 frag_normal;
out vec4 vcolor;
#ifdef VERTEX_LIGHTING
"""
    + _LIGHTING
    + """out vec3 vertex_lit;
#endif
void main() {
    mat4 MI = M * inst_m;
    vec4 wp = MI * vec4(position, 1.0);
    gl_Position = P * V * wp;
    frag_position = wp.xyz;
#ifdef NORMAL_LOC
    frag_normal = mat3(MI) * normal;
#else
    frag_normal = vec3(0.0, 1.0, 0.0);
#endif
#ifdef COLOR_0_LOC
    vcolor = color_0;
#else
    vcolor = vec4(1.0);
#endif
#ifdef VERTEX_LIGHTING
    // front faces only (the bodies are culled): a vertex cannot know the side it is seen from
    vertex_lit = shade(material.base_color_factor.rgb * vcolor.rgb, normalize(frag_normal), wp.xyz);
#endif
}
"""
)
_MESH_FRAG = (
    """#version 330 core
"""
    + _LIGHTING
    + """in vec3 frag_position;
in vec3 frag_normal;
in vec4 vcolor;
#ifdef VERTEX_LIGHTING
in vec3 vertex_lit;
#endif
out vec4 frag_color;
void main() {
    vec3 base = material.base_color_factor.rgb * vcolor.rgb;
#ifndef NORMAL_LOC
    // no normals: unlit geometry (floor grid, shadows), drawn in its own colour
    frag_color = vec4(pow(clamp(base, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
    return;
#endif
#ifdef VERTEX_LIGHTING
    // lit at the vertices (see _VERT), interpolated; only the gamma per pixel
    frag_color = vec4(pow(clamp(vertex_lit, 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
    return;
#endif
    vec3 n = normalize(frag_normal);
    if (!gl_FrontFacing) n = -n;
    frag_color = vec4(pow(clamp(shade(base, n, frag_position), 0.0, 1.0), vec3(1.0 / 2.2)), 1.0);
}
"""
)
_SHADER_DIR = None


def _shader_dir() -> str:
    """A folder holding the shaders above (written once per process)."""
    global _SHADER_DIR
    if _SHADER_DIR is None:
        import atexit
        import shutil
        import tempfile

        d = tempfile.mkdtemp(prefix="snapcore-shaders-")
        atexit.register(shutil.rmtree, d, True)
        for name, text in (("mesh.vert", _VERT), ("mesh.frag", _MESH_FRAG)):
            with open(os.path.join(d, name), "w") as fh:
                fh.write(text)
        _SHADER_DIR = d
    return _SHADER_DIR


def _read_colour_only(read_both):
    """Wrap pyrender's framebuffer read: our passes never use its depth image, whose read
    and linearisation cost ~5 ms a frame at 1280×720 — read (and flip) colour only."""
    import ctypes  # noqa: F401  (PyOpenGL needs it loaded for glReadPixels)

    from OpenGL.GL import (
        GL_COLOR_BUFFER_BIT,
        GL_DRAW_FRAMEBUFFER,
        GL_LINEAR,
        GL_READ_FRAMEBUFFER,
        GL_RGB,
        GL_UNSIGNED_BYTE,
        glBindFramebuffer,
        glBlitFramebuffer,
        glReadPixels,
    )

    def read(self, scene, flags):
        if flags & 1:  # RenderFlags.DEPTH_ONLY: leave pyrender's path alone
            return read_both(self, scene, flags)
        w, h = self._main_fb_dims
        glBindFramebuffer(GL_READ_FRAMEBUFFER, self._main_fb_ms)
        glBindFramebuffer(GL_DRAW_FRAMEBUFFER, self._main_fb)
        glBlitFramebuffer(0, 0, w, h, 0, 0, w, h, GL_COLOR_BUFFER_BIT, GL_LINEAR)
        glBindFramebuffer(GL_READ_FRAMEBUFFER, self._main_fb)
        buf = glReadPixels(0, 0, w, h, GL_RGB, GL_UNSIGNED_BYTE)
        return np.frombuffer(buf, np.uint8).reshape(h, w, 3)[::-1], None

    return read


#: Every thread's renderer, held here (not only in thread-local storage) so that a
#: finished thread's renderer is never freed by the garbage collector: pyrender's
#: ``__del__`` would make that context current on whichever thread collects it, possibly
#: in the middle of that thread's own frame. Dead threads' renderers are freed by the
#: next thread that creates one (see :func:`_sweep_dead`).
_RENDERERS: dict = {}
_RENDERERS_LOCK = threading.Lock()


def _free(r) -> None:
    """Delete a renderer's GL objects and its context (the display stays up)."""
    try:
        r._platform.make_current()
        r._renderer.delete()
        r._platform.delete_context()
    except Exception:  # a context that is already gone: nothing left to free
        pass
    r._renderer = None
    r._platform = None


def _sweep_dead() -> None:
    with _RENDERERS_LOCK:
        victims = [_RENDERERS.pop(t) for t in list(_RENDERERS) if not t.is_alive()]
        raw = [_RAW_CONTEXTS.pop(t) for t in list(_RAW_CONTEXTS) if not t.is_alive()]
    for r in victims:
        _free(r)
    for ctx in raw:
        _free_raw(ctx)


def _free_raw(ctx) -> None:
    """Delete a bare context (its GL objects go with it; the display stays up)."""
    try:
        ctx.delete()
    except Exception:  # a context that is already gone: nothing left to free
        pass


def gl_renderer(width: int, height: int):
    """This thread's pyrender ``OffscreenRenderer``, resized to ``width`` × ``height``.

    One EGL context per thread (contexts are thread-bound); created on first use.
    """
    pyrender = load_pyrender()
    width, height = int(width), int(height)
    if width < 1 or height < 1 or width > 8192 or height > 8192:
        raise RenderError(f"image size must be 1..8192 pixels a side, got {width}x{height}")
    r = getattr(_THREAD, "renderer", None)
    if r is None:
        _sweep_dead()
        try:
            r = pyrender.OffscreenRenderer(width, height)
        except Exception as err:
            raise RenderError(
                f"cannot create an offscreen OpenGL context ({type(err).__name__}: {err}); "
                "is Mesa EGL installed and PYOPENGL_PLATFORM=egl?"
            ) from err
        from pyrender.shader_program import ShaderProgramCache

        r._renderer._program_cache = ShaderProgramCache(shader_dir=_shader_dir())
        _THREAD.renderer = r
        with _RENDERERS_LOCK:
            _RENDERERS[threading.current_thread()] = r
    r.viewport_width, r.viewport_height = width, height
    return r


class _EGLContext:
    """A bare EGL context (OpenGL 4.1 core, no surface) for raw GL passes, made as
    pyrender's ``EGLPlatform`` makes its own (same device, config and attributes) but
    without importing pyrender. Deleting it leaves the display up (see the module
    docstring)."""

    def __init__(self) -> None:
        import ctypes

        from OpenGL import EGL as egl
        from OpenGL import arrays

        display = None
        query = egl.eglGetProcAddress("eglQueryDevicesEXT")
        get_display = egl.eglGetProcAddress("eglGetPlatformDisplayEXT")
        if query is not None and get_display is not None:
            # pyrender's default device: the first one the device extension lists
            device_t = _opaque_pointer("EGLDeviceEXT")
            query_devices = ctypes.CFUNCTYPE(egl.EGLBoolean)(query)
            query_devices.argtypes = (egl.EGLint, ctypes.POINTER(device_t), ctypes.c_void_p)
            count = egl.EGLint()
            if query_devices(0, None, ctypes.byref(count)) and count.value > 0:
                devices = (device_t * count.value)()
                if query_devices(count.value, devices, ctypes.byref(count)) and count.value:
                    platform_display = ctypes.CFUNCTYPE(egl.EGLDisplay)(get_display)
                    display = platform_display(_EGL_PLATFORM_DEVICE_EXT, devices[0], None)
        if display is None:
            saved = os.environ.pop("DISPLAY", None)  # offscreen even under X, like pyrender
            try:
                display = egl.eglGetDisplay(egl.EGL_DEFAULT_DISPLAY)
            finally:
                if saved is not None:
                    os.environ["DISPLAY"] = saved
        config_attributes = arrays.GLintArray.asArray(
            [
                egl.EGL_SURFACE_TYPE, egl.EGL_PBUFFER_BIT,
                egl.EGL_BLUE_SIZE, 8,
                egl.EGL_RED_SIZE, 8,
                egl.EGL_GREEN_SIZE, 8,
                egl.EGL_DEPTH_SIZE, 24,
                egl.EGL_COLOR_BUFFER_TYPE, egl.EGL_RGB_BUFFER,
                egl.EGL_RENDERABLE_TYPE, egl.EGL_OPENGL_BIT,
                egl.EGL_CONFORMANT, egl.EGL_OPENGL_BIT,
                egl.EGL_NONE,
            ]
        )  # fmt: skip
        context_attributes = arrays.GLintArray.asArray(
            [
                egl.EGL_CONTEXT_MAJOR_VERSION, 4,
                egl.EGL_CONTEXT_MINOR_VERSION, 1,
                egl.EGL_CONTEXT_OPENGL_PROFILE_MASK, egl.EGL_CONTEXT_OPENGL_CORE_PROFILE_BIT,
                egl.EGL_NONE,
            ]
        )  # fmt: skip
        major, minor, n_configs = ctypes.c_long(), ctypes.c_long(), ctypes.c_long()
        configs = (egl.EGLConfig * 1)()
        if not egl.eglInitialize(display, major, minor):
            raise RuntimeError("eglInitialize failed")
        if not egl.eglChooseConfig(display, config_attributes, configs, 1, n_configs):
            raise RuntimeError("eglChooseConfig found no RGB pbuffer config with depth")
        if not egl.eglBindAPI(egl.EGL_OPENGL_API):
            raise RuntimeError("eglBindAPI(EGL_OPENGL_API) failed")
        context = egl.eglCreateContext(display, configs[0], egl.EGL_NO_CONTEXT, context_attributes)
        if not context:
            raise RuntimeError("eglCreateContext failed (OpenGL 4.1 core)")
        self._display, self._context = display, context
        self.make_current()

    def make_current(self) -> None:
        import ctypes

        from OpenGL import EGL as egl

        # already current (the usual case: every draw and read-back asks): skip the
        # call, which flushes the context's pending work (~0.2 ms a picture measured)
        current = ctypes.cast(egl.eglGetCurrentContext(), ctypes.c_void_p).value
        if current is not None and current == ctypes.cast(self._context, ctypes.c_void_p).value:
            return
        if not egl.eglMakeCurrent(
            self._display, egl.EGL_NO_SURFACE, egl.EGL_NO_SURFACE, self._context
        ):
            raise RenderError("eglMakeCurrent failed")

    def delete(self) -> None:
        from OpenGL import EGL as egl

        if self._context is not None:
            egl.eglDestroyContext(self._display, self._context)
        self._context = None


_EGL_PLATFORM_DEVICE_EXT = 0x313F


def _opaque_pointer(name: str):
    from OpenGL._opaque import opaque_pointer_cls

    return opaque_pointer_cls(name)


#: Every thread's bare context (see :data:`_RENDERERS` for why they are held here).
_RAW_CONTEXTS: dict = {}


def current_gl_context(width: int, height: int):
    """Make a GL context of this thread current for raw GL calls (a pass that draws
    without pyrender, e.g. the face ids of :mod:`snapcore.render.buffers`); return an
    object that identifies the context (objects compiled in it stay valid while it lives).

    The thread's pyrender renderer's context if it has one; else a bare EGL context
    (:class:`_EGLContext`), so that a command that only draws face ids (``snapshot
    select``'s viewpoint-entropy baseline) never imports pyrender and trimesh (~0.7 s).
    Other GL platforms (``PYOPENGL_PLATFORM=osmesa``) use pyrender's context.
    """
    r = getattr(_THREAD, "renderer", None)
    if r is None and os.environ.get("PYOPENGL_PLATFORM") == "egl":
        return _raw_context()
    r = gl_renderer(width, height)
    r._platform.make_current()
    return r


def release_renderer() -> None:
    """Free this thread's offscreen renderer and its EGL context (e.g. before a worker
    thread ends); the next render on this thread makes a new one."""
    r = getattr(_THREAD, "renderer", None)
    if r is not None:
        _THREAD.renderer = None
        with _RENDERERS_LOCK:
            _RENDERERS.pop(threading.current_thread(), None)
        _free(r)
    ctx = getattr(_THREAD, "raw_context", None)
    if ctx is not None:
        _THREAD.raw_context = None
        with _RENDERERS_LOCK:
            _RAW_CONTEXTS.pop(threading.current_thread(), None)
        _free_raw(ctx)


def bare_gl_context():
    """Make this thread's bare EGL context (:class:`_EGLContext`) current and return
    it, made on first use: the context of the raw-GL scene renderer
    (:mod:`snapcore.render.raster`), which never shares pyrender's, so it works the
    same whether or not the thread also has a pyrender renderer. Other GL platforms
    (``PYOPENGL_PLATFORM=osmesa``) get :func:`current_gl_context`'s.
    """
    if os.environ.get("PYOPENGL_PLATFORM") != "egl":
        return current_gl_context(8, 8)
    return _raw_context()


def _raw_context() -> _EGLContext:
    """This thread's bare EGL context, made on first use, made current."""
    ctx = getattr(_THREAD, "raw_context", None)
    if ctx is None:
        _sweep_dead()
        try:
            ctx = _EGLContext()
        except Exception as err:
            raise RenderError(
                f"cannot create an offscreen OpenGL context ({type(err).__name__}: {err});"
                " is Mesa EGL installed (apt-get install libegl1 libegl-mesa0"
                " libgl1-mesa-dri)?"
            ) from err
        _THREAD.raw_context = ctx
        with _RENDERERS_LOCK:
            _RAW_CONTEXTS[threading.current_thread()] = ctx
    ctx.make_current()
    return ctx
