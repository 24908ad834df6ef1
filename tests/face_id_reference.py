"""The face-id pass as it was before issue 41's speed-ups, kept as the tests' reference.

One indexed draw call per view of the mesh as given, the id taken from ``gl_PrimitiveID``
(the face's index within the draw), each view in a fresh single-layer target: the most
direct reading of "which face does each pixel show". ``snapcore.render.buffers`` must
give the same ids at every pixel (``tests/test_face_id_pass.py``); the viewpoint-entropy
scores recorded in ``tests/regression`` were made with this pass.
"""

from __future__ import annotations

import numpy as np

from snapcore.render.buffers import _bounding_sphere, _view_projection, face_id_camera
from snapcore.render.gl import current_gl_context

_VERTEX = """#version 330 core
layout(location = 0) in vec3 position;
uniform mat4 V;
uniform mat4 P;
void main() { gl_Position = P * V * vec4(position, 1.0); }
"""
_FRAGMENT = """#version 330 core
out int face;
void main() { face = gl_PrimitiveID + 1; }
"""


def reference_face_ids(vertices, faces, views, resolution) -> np.ndarray:
    """Face ids (V, H, W) int32, 0 = background, k + 1 = face k, row 0 at the top."""
    from OpenGL import GL as gl
    from OpenGL.GL import shaders

    vertices = np.asarray(vertices, float)
    views = np.asarray(views, float).reshape(-1, 3)
    sphere = _bounding_sphere(vertices)
    cams = [face_id_camera(vertices, v, resolution=resolution, sphere=sphere) for v in views]
    w, h = cams[0].size
    current_gl_context(w, h)
    v = np.ascontiguousarray(vertices, dtype=np.float32)
    f = np.ascontiguousarray(faces, dtype=np.uint32)
    prog = shaders.compileProgram(
        shaders.compileShader(_VERTEX, gl.GL_VERTEX_SHADER),
        shaders.compileShader(_FRAGMENT, gl.GL_FRAGMENT_SHADER),
        validate=False,
    )
    vao = gl.glGenVertexArrays(1)
    vbo, ebo = gl.glGenBuffers(2)
    fbo = gl.glGenFramebuffers(1)
    tex = gl.glGenTextures(1)
    depth = gl.glGenRenderbuffers(1)
    out = np.empty((len(cams), h, w), np.int32)
    try:
        gl.glBindVertexArray(vao)
        gl.glBindBuffer(gl.GL_ARRAY_BUFFER, vbo)
        gl.glBufferData(gl.GL_ARRAY_BUFFER, v.nbytes, v, gl.GL_STATIC_DRAW)
        gl.glEnableVertexAttribArray(0)
        gl.glVertexAttribPointer(0, 3, gl.GL_FLOAT, gl.GL_FALSE, 0, None)
        gl.glBindBuffer(gl.GL_ELEMENT_ARRAY_BUFFER, ebo)
        gl.glBufferData(gl.GL_ELEMENT_ARRAY_BUFFER, f.nbytes, f, gl.GL_STATIC_DRAW)
        gl.glUseProgram(prog)
        loc_v = gl.glGetUniformLocation(prog, "V")
        loc_p = gl.glGetUniformLocation(prog, "P")
        gl.glBindTexture(gl.GL_TEXTURE_2D, tex)
        gl.glTexImage2D(
            gl.GL_TEXTURE_2D, 0, gl.GL_R32I, w, h, 0, gl.GL_RED_INTEGER, gl.GL_INT, None
        )
        gl.glBindRenderbuffer(gl.GL_RENDERBUFFER, depth)
        gl.glRenderbufferStorage(gl.GL_RENDERBUFFER, gl.GL_DEPTH_COMPONENT24, w, h)
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, fbo)
        gl.glFramebufferRenderbuffer(
            gl.GL_FRAMEBUFFER, gl.GL_DEPTH_ATTACHMENT, gl.GL_RENDERBUFFER, depth
        )
        gl.glFramebufferTexture2D(
            gl.GL_FRAMEBUFFER, gl.GL_COLOR_ATTACHMENT0, gl.GL_TEXTURE_2D, tex, 0
        )
        gl.glDrawBuffers(1, [gl.GL_COLOR_ATTACHMENT0])
        gl.glViewport(0, 0, w, h)
        gl.glDisable(gl.GL_BLEND)
        gl.glDisable(gl.GL_MULTISAMPLE)
        gl.glEnable(gl.GL_DEPTH_TEST)
        gl.glDepthFunc(gl.GL_LESS)
        gl.glDepthMask(gl.GL_TRUE)
        gl.glEnable(gl.GL_CULL_FACE)
        gl.glFrontFace(gl.GL_CCW)
        gl.glCullFace(gl.GL_BACK)
        gl.glPixelStorei(gl.GL_PACK_ALIGNMENT, 4)
        image = np.empty((h, w), np.int32)
        for k, cam in enumerate(cams):
            view, proj = _view_projection(cam)
            gl.glClearBufferiv(gl.GL_COLOR, 0, np.zeros(4, np.int32))
            gl.glClearBufferfv(gl.GL_DEPTH, 0, np.ones(1, np.float32))
            gl.glUniformMatrix4fv(loc_v, 1, gl.GL_TRUE, view)
            gl.glUniformMatrix4fv(loc_p, 1, gl.GL_TRUE, proj)
            gl.glDrawElements(gl.GL_TRIANGLES, f.size, gl.GL_UNSIGNED_INT, None)
            gl.glGetTexImage(gl.GL_TEXTURE_2D, 0, gl.GL_RED_INTEGER, gl.GL_INT, image)
            out[k] = image[::-1]
    finally:
        gl.glBindFramebuffer(gl.GL_FRAMEBUFFER, 0)
        gl.glBindVertexArray(0)
        gl.glUseProgram(0)
        gl.glDisable(gl.GL_CULL_FACE)
        gl.glDeleteFramebuffers(1, [fbo])
        gl.glDeleteTextures([tex])
        gl.glDeleteRenderbuffers(1, [depth])
        gl.glDeleteBuffers(2, [vbo, ebo])
        gl.glDeleteVertexArrays(1, [vao])
        gl.glDeleteProgram(prog)
    return out
