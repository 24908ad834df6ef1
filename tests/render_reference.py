"""The reference for the raw-GL scene renderer (:mod:`snapcore.render.raster`): the
same picture drawn by pyrender, as ``SceneRenderer`` drew it before issue 41.

A :class:`~snapcore.render.renderer.SceneRenderer`'s meshes (its ``draw_list``) become
pyrender primitives with the materials the renderer gave them then (metallic 0,
roughness 0.7 for bodies; roughness 1, double-sided for the unlit floor grid, sky and
shadows), its lights are made as it made them (pyrender ``DirectionalLight`` nodes with
the pose built from the light's direction), and pyrender renders the scene in the
thread's pyrender context (:func:`snapcore.render.gl.gl_renderer`, the patched
shaders of :mod:`snapcore.render.gl`).
"""

from __future__ import annotations

import numpy as np

from snapcore.render.camera import POLE_COS, Camera, view_basis
from snapcore.render.gl import gl_renderer, load_pyrender


def _lights(cam: Camera):
    """The old renderer's three lights: (pose, intensity) following the camera."""
    y = np.array([0.0, 1.0, 0.0])
    out = []
    for direction, intensity in (
        (cam.back + 1.4 * y - 0.8 * cam.right, 2.4),
        (cam.back + 0.2 * y + 1.0 * cam.right, 0.9),
        (-cam.back + 1.2 * y + 0.3 * cam.right, 1.1),
    ):
        d = direction / np.linalg.norm(direction)
        m = np.eye(4)
        m[:3, :3] = np.stack(view_basis(d, None if abs(d[1]) < POLE_COS else [1.0, 0, 0]), 1)
        out.append((m, intensity))
    return out


def pyrender_picture(sr, camera: Camera, gl_cam: Camera, *, bodies: bool = True) -> np.ndarray:
    """``sr``'s last posed frame seen by ``gl_cam`` (its full GL camera or a crop of it),
    drawn by pyrender; ``camera`` is the user's camera the lights follow. (H, W, 3) uint8."""
    pyrender = load_pyrender()
    bg = [0.93, 0.925, 0.915] if sr.ground else [0.975, 0.975, 0.975]
    ps = pyrender.Scene(bg_color=[*bg, 1.0], ambient_light=[0.30] * 3)
    for mesh in sr.draw_list(bodies):
        lit = mesh.normals is not None
        mat = pyrender.MetallicRoughnessMaterial(
            baseColorFactor=[1.0, 1.0, 1.0, 1.0],
            metallicFactor=0.0,
            roughnessFactor=0.7 if lit else 1.0,
            doubleSided=not lit,
        )
        prim = pyrender.Primitive(
            positions=mesh.positions,
            normals=mesh.normals,
            color_0=mesh.colors,
            indices=mesh.indices,
            material=mat,
            mode=4,
        )
        node = ps.add(pyrender.Mesh([prim]))
        node.mesh.is_visible = mesh.visible
    for m, intensity in _lights(camera):
        ps.add(pyrender.DirectionalLight(color=[1.0, 1.0, 1.0], intensity=intensity), pose=m)
    ps.add(gl_cam.pyrender_camera(), pose=gl_cam.pose)
    color, _ = gl_renderer(*gl_cam.size).render(ps, flags=pyrender.RenderFlags.NONE)
    return np.ascontiguousarray(color)
