"""Cameras: view directions, camera bases, framing that fits a pose or a whole motion.

Conventions (shared by every renderer of the suite):

- World: metres, Y up. A *view* is a unit vector pointing from the scene centre to the
  camera (the convention of :mod:`snapcore.select.view` and ``snapshot select``).
- Camera basis (:func:`view_basis`): ``right = normalize(up_hint × view)``, ``up =
  view × right``, with ``up_hint`` = world +Y, or −Z when the view is within 0.5° of
  +Y (looking straight down, image-up is −Z) and +Z near −Y.
- Images are row-major ``(H, W[, 3])`` with row 0 at the top; :meth:`Camera.project`
  gives pixel coordinates (x right, y down).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from snapcore.errors import RenderError
from snapcore.motion.facing import scene_facing
from snapcore.render.gl import load_pyrender

__all__ = [
    "gl_camera_pose",
    "gl_projection",
    "RenderError",
    "Camera",
    "view_basis",
    "fit_camera",
    "motion_points",
    "ortho_box",
    "default_view",
    "FRAME_MARGIN",
    "PERSPECTIVE_YFOV_DEG",
    "POLE_COS",
    "DEFAULT_AZIMUTH_DEG",
    "DEFAULT_ELEVATION_DEG",
]

#: Empty border kept around the framed content, as a fraction of the image size.
FRAME_MARGIN = 0.06
#: Vertical field of view of the perspective camera, degrees (a 50 mm lens is ~27°).
PERSPECTIVE_YFOV_DEG = 30.0
#: Views closer than this to ±Y (cosine) use a horizontal up hint (see :func:`view_basis`).
POLE_COS = float(np.cos(np.radians(0.5)))
#: Default 3/4 view: azimuth from the characters' facing direction and elevation, degrees.
DEFAULT_AZIMUTH_DEG = 35.0
DEFAULT_ELEVATION_DEG = 18.0


def view_basis(view, up=None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Orthonormal camera basis for a view direction.

    Parameters
    ----------
    view : array of shape (3,)
        From the scene centre towards the camera (normalised here).
    up : array of shape (3,), optional
        Up hint; default world +Y, or −Z / +Z for views (anti)parallel to +Y.

    Returns
    -------
    right, up, back : ndarray of shape (3,)
        ``back`` is the unit view; the camera looks along ``-back``.
    """
    v = np.asarray(view, dtype=float).reshape(-1)
    n = np.linalg.norm(v) if v.shape == (3,) else 0.0
    if not (np.isfinite(n) and n > 0):
        raise RenderError(f"a view must be a non-zero 3-vector, got {view!r}")
    v = v / n
    if up is None:
        if v[1] > POLE_COS:
            hint = np.array([0.0, 0.0, -1.0])
        elif v[1] < -POLE_COS:
            hint = np.array([0.0, 0.0, 1.0])
        else:
            hint = np.array([0.0, 1.0, 0.0])
    else:
        hint = np.asarray(up, dtype=float)
    right = np.cross(hint, v)
    rn = np.linalg.norm(right)
    if rn < 1e-9:
        raise RenderError(f"the up hint {hint.tolist()} is parallel to the view {v.tolist()}")
    right /= rn
    return right, np.cross(v, right), v


@dataclass(frozen=True)
class Camera:
    """A camera: where it is, where it looks, what it sees.

    Attributes
    ----------
    position : ndarray of shape (3,)
        Eye position, metres (for orthographic cameras: the centre of the image plane).
    right, up, back : ndarray of shape (3,)
        Camera basis; it looks along ``-back`` (``back`` is the view direction).
    size : (int, int)
        Image width and height in pixels.
    projection : {"orthographic", "perspective"}
    half_height : float
        Orthographic: half the image height in metres (half width = half_height·W/H).
    yfov : float
        Perspective: vertical field of view, radians.
    znear, zfar : float
        Clipping distances along the view, metres.
    """

    position: np.ndarray
    right: np.ndarray
    up: np.ndarray
    back: np.ndarray
    size: tuple[int, int]
    projection: str = "orthographic"
    half_height: float = 1.0
    yfov: float = float(np.radians(PERSPECTIVE_YFOV_DEG))
    znear: float = 0.05
    zfar: float = 100.0

    @property
    def pose(self) -> np.ndarray:
        """4×4 camera-to-world matrix (pyrender/OpenGL convention)."""
        m = np.eye(4)
        m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = self.right, self.up, self.back, self.position
        return m

    @property
    def aspect(self) -> float:
        return self.size[0] / self.size[1]

    @property
    def pixel_size(self) -> float:
        """Orthographic: metres per pixel (square pixels)."""
        return 2.0 * self.half_height / self.size[1]

    def pyrender_camera(self):
        pyrender = load_pyrender()
        if self.projection == "orthographic":
            return pyrender.OrthographicCamera(
                xmag=self.half_height * self.aspect,
                ymag=self.half_height,
                znear=self.znear,
                zfar=self.zfar,
            )
        return pyrender.PerspectiveCamera(
            yfov=self.yfov, aspectRatio=self.aspect, znear=self.znear, zfar=self.zfar
        )

    def project(self, points) -> np.ndarray:
        """Pixel coordinates (x right, y down; pixel centres at +0.5) of world points,
        shape (..., 2)."""
        p = np.asarray(points, float) - self.position
        x, y, z = p @ self.right, p @ self.up, -(p @ self.back)
        w, h = self.size
        if self.projection == "orthographic":
            s = self.half_height
        else:
            s = z * np.tan(self.yfov / 2)
        return np.stack([(x / (s * self.aspect) + 1) * w / 2, (1 - y / s) * h / 2], axis=-1)


def ortho_box(camera: Camera, drawn: list[np.ndarray]) -> tuple[np.ndarray, np.ndarray]:
    """Smallest and largest pixel coordinates (x right, y down; shape (2,) each) of the
    points ``drawn`` (arrays of shape (N, 3), metres) seen by orthographic ``camera``:
    :meth:`Camera.project`'s affine map as two float32 matrix-vector products per array
    (0.035 against 0.50 ms for projecting a video frame's bodies and shadows in
    float64, min of 10). Its rounding, ~1e-4 px at coordinates of a few thousand px,
    is far inside a video frame's rectangle margin
    (:data:`snapcore.render.renderer.CROP_PAD_PX`)."""
    w, h = camera.size
    s = camera.half_height
    ax = np.asarray(camera.right, float) * (w / 2 / (s * camera.aspect))
    ay = np.asarray(camera.up, float) * (-h / 2 / s)
    pos = np.asarray(camera.position, float)
    offset = np.array([w / 2 - pos @ ax, h / 2 - pos @ ay])
    lo, hi = np.full(2, np.inf), np.full(2, -np.inf)
    for d in drawn:
        d32 = np.asarray(d, np.float32).reshape(-1, 3)
        if not len(d32):
            continue
        for i, a in enumerate((ax, ay)):
            c = d32 @ a.astype(np.float32)  # a matrix-vector product (BLAS sgemv)
            lo[i], hi[i] = min(lo[i], c.min()), max(hi[i], c.max())
    return lo + offset, hi + offset


# The matrices a pyrender render of a Camera uses, computed here without importing
# pyrender (it imports trimesh, networkx and scipy.spatial: ~0.7 s of start-up), for
# passes that draw with raw GL (the face ids of :mod:`snapcore.render.buffers`). The
# arithmetic is pyrender 0.1.45's and trimesh's operation for operation, so the
# matrices are equal bit for bit (tests/test_render.py compares them).

_QUAT_EPS = np.finfo(float).eps * 4.0  # trimesh.transformations._EPS


def _quaternion_from_rotation(r: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a 3×3 rotation: trimesh's
    ``quaternion_from_matrix`` (not ``isprecise``), the eigenvector of Bar-Itzhack's K."""
    m00, m01, m02 = r[0, 0], r[0, 1], r[0, 2]
    m10, m11, m12 = r[1, 0], r[1, 1], r[1, 2]
    m20, m21, m22 = r[2, 0], r[2, 1], r[2, 2]
    k = np.array(
        [
            [m00 - m11 - m22, 0.0, 0.0, 0.0],
            [m01 + m10, m11 - m00 - m22, 0.0, 0.0],
            [m02 + m20, m12 + m21, m22 - m00 - m11, 0.0],
            [m21 - m12, m02 - m20, m10 - m01, m00 + m11 + m22],
        ]
    )
    k /= 3.0
    w, v = np.linalg.eigh(k)
    q = v[[3, 0, 1, 2], np.argmax(w)]
    if q[0] < 0.0:
        np.negative(q, q)
    return q


def _rotation_from_quaternion(quaternion: np.ndarray) -> np.ndarray:
    """3×3 rotation of a quaternion (w, x, y, z): trimesh's ``quaternion_matrix``."""
    q = np.array(quaternion, dtype=np.float64).reshape((-1, 4))
    n = np.dot(q * q, [1.0] * 4)
    if n[0] < _QUAT_EPS:
        return np.eye(3)
    q *= np.sqrt(2.0 / n[:, None])
    q = (q[:, None, :] * q[:, :, None])[0]
    return np.array(
        [
            [1.0 - q[2, 2] - q[3, 3], q[1, 2] - q[3, 0], q[1, 3] + q[2, 0]],
            [q[1, 2] + q[3, 0], 1.0 - q[1, 1] - q[3, 3], q[2, 3] - q[1, 0]],
            [q[1, 3] - q[2, 0], q[2, 3] + q[1, 0], 1.0 - q[1, 1] - q[2, 2]],
        ]
    )


def gl_camera_pose(cam: Camera) -> np.ndarray:
    """The 4×4 camera-to-world matrix a pyrender scene node holding ``cam`` renders with:
    :attr:`Camera.pose` decomposed into translation, quaternion and scale and composed
    again (``pyrender.Node(matrix=cam.pose).matrix``), float64."""
    return gl_node_matrix(cam.pose)


def gl_node_matrix(m: np.ndarray) -> np.ndarray:
    """The 4×4 matrix a pyrender scene node made with ``matrix=m`` renders with (a
    camera's or a light's pose): ``m`` decomposed into translation, quaternion and
    scale and composed again, float64."""
    m = np.asarray(m, float)
    u = m[:3, :3]
    rotation = u / np.linalg.norm(u.T, axis=1)
    q = _quaternion_from_rotation(rotation)
    scale, translation = np.linalg.norm(m[:3, :3].T, axis=1), m[:3, 3]
    s, r, t = np.eye(4), np.eye(4), np.eye(4)
    s[:3, :3] = np.diag(scale)
    r[:3, :3] = _rotation_from_quaternion(q)
    t[:3, 3] = translation
    return t.dot(r.dot(s))


def gl_projection(cam: Camera) -> np.ndarray:
    """The 4×4 OpenGL projection matrix pyrender uses for ``cam`` at its own size,
    float64 (``cam.pyrender_camera().get_projection_matrix(*cam.size)``)."""
    w, h = cam.size
    n, f = float(cam.znear), float(cam.zfar)
    p = np.zeros((4, 4))
    if cam.projection == "orthographic":
        ymag = float(cam.half_height)
        p[0][0] = 1.0 / (w / h * ymag)
        p[1][1] = 1.0 / ymag
        p[2][2] = 2.0 / (n - f)
        p[2][3] = (f + n) / (n - f)
        p[3][3] = 1.0
        return p
    a, t = float(cam.aspect), np.tan(float(cam.yfov) / 2.0)
    p[0][0] = 1.0 / (a * t)
    p[1][1] = 1.0 / t
    p[3][2] = -1.0
    p[2][2] = (f + n) / (n - f)
    p[2][3] = (2 * f * n) / (n - f)
    return p


def check_size(size) -> tuple[int, int]:
    try:
        w, h = (int(v) for v in size)
    except (TypeError, ValueError):
        raise RenderError(f"size must be (width, height) in pixels, got {size!r}") from None
    if w < 8 or h < 8 or w > 8192 or h > 8192:
        raise RenderError(f"size must be 8..8192 pixels a side, got {w}x{h}")
    return w, h


def fit_camera(
    points,
    view,
    *,
    size=(640, 480),
    projection="orthographic",
    margin=FRAME_MARGIN,
    up=None,
    yfov_deg=PERSPECTIVE_YFOV_DEG,
    half_height=None,
) -> Camera:
    """A camera along ``view`` that frames all ``points``.

    Parameters
    ----------
    points : array of shape (P, 3)
        What must be in the picture (e.g. :func:`motion_points`), metres.
    view : array of shape (3,)
        From the scene centre to the camera.
    size : (int, int)
        Image width and height, pixels.
    projection : {"orthographic", "perspective"}
    margin : float
        Empty border on each side, fraction of the image size.
    up : array of shape (3,), optional
        Up hint for :func:`view_basis`.
    yfov_deg : float
        Perspective vertical field of view.
    half_height : float, optional
        Orthographic only: force this half image height (metres) instead of fitting
        (to give several views one scale, as :func:`snapcore.render.composites.compare_views` does).

    Returns
    -------
    Camera

    Notes
    -----
    Orthographic: the image centre is the centre of the points' extent on the image
    plane and the scale fits the larger of the width and height. Perspective: the camera
    looks at the same centre and backs off along ``view`` to the smallest distance
    ``d`` at which every point is inside the frustum, i.e. ``d ≥ z_i + |x_i|/tan(h/2)``
    and ``d ≥ z_i + |y_i|/tan(v/2)`` for point coordinates ``(x_i, y_i, z_i)`` relative
    to the centre (``z`` towards the camera).
    """
    w, h = check_size(size)
    if projection not in ("orthographic", "perspective"):
        raise RenderError(f"projection must be 'orthographic' or 'perspective', got {projection!r}")
    pts = np.asarray(points, float).reshape(-1, 3)
    pts = pts[np.all(np.isfinite(pts), axis=1)]
    if pts.size == 0:
        raise RenderError("nothing to frame: no finite points")
    right, upv, back = view_basis(view, up)
    x, y, z = pts @ right, pts @ upv, pts @ back
    cx, cy = (x.min() + x.max()) / 2, (y.min() + y.max()) / 2
    zc = (z.min() + z.max()) / 2
    centre = cx * right + cy * upv + zc * back
    aspect = w / h
    fill = max(1.0 - 2.0 * margin, 0.05)
    radius = float(np.max(np.linalg.norm(pts - centre, axis=1))) + 1e-3
    if projection == "orthographic":
        hh = max((y.max() - y.min()) / 2, (x.max() - x.min()) / 2 / aspect, 1e-3) / fill
        if half_height is not None:
            hh = float(half_height)
        dist = radius * 2 + 1.0
        return Camera(
            centre + back * dist,
            right,
            upv,
            back,
            (w, h),
            "orthographic",
            half_height=hh,
            znear=max(dist - radius - 1.0, 1e-3),
            zfar=dist + radius + 1.0,
        )
    yfov = np.radians(yfov_deg)
    tv = np.tan(yfov / 2) * fill
    th = np.tan(yfov / 2) * aspect * fill
    xr, yr, zr = x - cx, y - cy, z - zc
    dist = float(max(np.max(zr + np.abs(xr) / th), np.max(zr + np.abs(yr) / tv), radius * 0.5))
    znear = max(dist - radius, 0.02)
    return Camera(
        centre + back * dist,
        right,
        upv,
        back,
        (w, h),
        "perspective",
        yfov=float(yfov),
        znear=znear,
        zfar=dist + radius + 1.0,
    )


def motion_points(scene, *, frames=None, body=None, max_frames=120) -> np.ndarray:
    """Body-mesh vertices over (a sample of) frames: what a fixed framing must contain.

    Parameters
    ----------
    scene : Scene
    frames : array of int, optional
        Internal frames to cover (default: all, subsampled to ``max_frames``).
    body : SceneBody, optional
        Defaults to :func:`snapcore.render.bodies.scene_body`.
    max_frames : int
        Frames are subsampled evenly to at most this many (the extremes of a motion
        last longer than 1/120 of it, and the joint extremes are added exactly).

    Returns
    -------
    ndarray of shape (P, 3)
    """
    from snapcore.render.bodies import scene_body

    body = body or scene_body(scene)
    if frames is None:
        frames = np.arange(scene.n_frames)
    frames = np.asarray(frames, int).reshape(-1)
    if frames.size > max_frames:
        frames = frames[np.linspace(0, frames.size - 1, max_frames).round().astype(int)]
    verts = body.vertices(frames)[:, ::3].reshape(-1, 3)
    # every joint at every frame catches extremes between the sampled frames; the body
    # around a joint is at most a few cm thicker, which the framing margin absorbs
    joints = np.concatenate([c.positions.reshape(-1, 3) for c in scene.characters])
    return np.vstack([verts, joints])


def default_view(scene, *, azimuth_deg=DEFAULT_AZIMUTH_DEG, elevation_deg=DEFAULT_ELEVATION_DEG):
    """A 3/4 front view of the characters: their mean facing turned by ``azimuth_deg``
    about +Y and raised by ``elevation_deg``; unit vector (3,).

    The facing is the characters' mean facing (:func:`snapcore.motion.facing.scene_facing`);
    a scene without left/right joints is seen from +Z turned by the same angles.
    """
    fwd = scene_facing(scene)
    if np.linalg.norm(fwd) < 1e-6:
        fwd = np.array([0.0, 0.0, 1.0])
    fwd /= np.linalg.norm(fwd)
    a, e = np.radians(azimuth_deg), np.radians(elevation_deg)
    side = np.cross([0.0, 1.0, 0.0], fwd)
    horiz = np.cos(a) * fwd + np.sin(a) * side
    v = np.cos(e) * horiz + np.sin(e) * np.array([0.0, 1.0, 0.0])
    return v / np.linalg.norm(v)
