"""The raster's shading choices that trade a little of the picture for CPU: the
highlight's power by products (:data:`snapcore.render.raster.HIGHLIGHT_BY_SQUARES`)."""

from __future__ import annotations

import threading

import numpy as np
import pytest

pytestmark = pytest.mark.timeout(120)


def _source(shader: int) -> str:
    """A compiled shader's source, from GL (PyOpenGL's own wrapper names a constant
    that does not exist)."""
    import ctypes

    from OpenGL import GL as gl
    from OpenGL.raw.GL.VERSION.GL_2_0 import glGetShaderSource

    n = int(gl.glGetShaderiv(shader, gl.GL_SHADER_SOURCE_LENGTH))
    buf = ctypes.create_string_buffer(n)
    glGetShaderSource(shader, n, None, buf)
    return buf.value.decode()


def _sphere_picture(squares: bool) -> tuple[str, np.ndarray]:
    """The lit program's source and a shiny unit sphere (roughness 0: the strongest highlight) lit from the upper
    left, 256x256, drawn on a thread of its own (programs are compiled per thread's
    context, with the choice in force then)."""
    import trimesh

    from snapcore.render import raster

    ico = trimesh.creation.icosphere(subdivisions=4)
    pos = np.asarray(ico.vertices, np.float32)
    mesh = raster.DrawMesh(
        "body", object(), pos, np.full((len(pos), 4), [0.2, 0.4, 0.8, 1.0], np.float32),
        np.asarray(ico.faces, np.uint32), normals=pos.copy(), roughness=0.0,
    )  # fmt: skip
    view = np.eye(4)
    view[2, 3] = -3.0  # the camera at z = 3, looking down -z
    f, near, far = 1.0 / np.tan(np.radians(25)), 0.1, 10.0
    proj = np.array(
        [[f, 0, 0, 0], [0, f, 0, 0],
         [0, 0, (far + near) / (near - far), 2 * far * near / (near - far)], [0, 0, -1, 0]]
    )  # fmt: skip
    light = raster.Light(np.array([0.5, -0.6, -0.62]) / np.linalg.norm([0.5, -0.6, -0.62]), 2.4)
    out: list = []

    def work() -> None:
        from OpenGL import GL as gl

        from snapcore.render.gl import release_renderer

        raster.HIGHLIGHT_BY_SQUARES = squares
        try:
            program = raster._canvas().programs[True].id
            out.append("".join(_source(sh) for sh in gl.glGetAttachedShaders(program)))
            out.append(
                raster.draw(
                    [mesh],
                    size=(256, 256),
                    view=view,
                    projection=proj,
                    cam_pos=np.array([0.0, 0.0, 3.0]),
                    lights=[light],
                    ambient=0.3,
                    clear=(1.0, 1.0, 1.0),
                )  # fmt: skip
            )
        finally:
            raster.HIGHLIGHT_BY_SQUARES = False
            release_renderer()

    t = threading.Thread(target=work)
    t.start()
    t.join()
    return out[0], out[1]


def test_the_highlight_by_products_is_pow_within_a_level():
    """``x ** 24`` as products against GLSL's ``pow`` (llvmpipe: exp2 and log2
    polynomials): the same picture within one level of 255 where the highlight is
    (fails for a wrong power: x ** 12 is up to 22 levels brighter around the highlight;
    on this sphere the pictures are equal, on the salsa pair a pixel in some frames is
    one level apart), from the products' program (fails if the choice does not reach
    the shader)."""
    (src_pow, pow_), (src_products, products) = _sphere_picture(False), _sphere_picture(True)
    sphere = pow_.min(axis=2) < 255  # the background is white
    # the red channel tops 180 only with the highlight (~126 with diffuse light alone)
    assert pow_[sphere, 0].max() > 180
    assert np.abs(pow_.astype(int) - products.astype(int)).max() <= 1
    assert "#if 0\n        float x = max" in src_pow
    assert "#if 1\n        float x = max" in src_products
