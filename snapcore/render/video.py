"""Videos of a scene: H.264 MP4s, and optionally the same frames as WebM/VP9.

H.264 plays in Chrome and in most Firefox builds; a Firefox without an H.264 decoder
(Debian's Firefox ESR without system ffmpeg) plays only the WebM/VP9 copy, which
:func:`render_video` encodes from the same rendered frames (``webm=``) with the
``libvpx-vp9`` encoder of the bundled ffmpeg.

:func:`render_video` renders every video frame with one :class:`~snapcore.render.renderer.SceneRenderer`
(one fixed camera that frames the whole motion, so characters do not jump around) and
pipes the frames to the ffmpeg that ships with ``imageio-ffmpeg``: H.264 (libx264),
``yuv420p`` (the pixel format browsers decode), ``+faststart`` (the index at the front,
so playback starts before the file is fully downloaded), a key frame every second
(seeking stays snappy in the study's frame picker).

Frame rate
----------
Motion capture runs at 60-120 fps; videos at a chosen rate (24 by default). Video frame
``k`` shows the motion frame nearest to its time, ``round(k · fps_motion / fps_video)``
(no interpolation between poses). :func:`video_frame_map` gives that mapping, and
:func:`render_video` returns it in *source* frame numbers (``scene.source_frame``), the
numbering every output of the suite uses.
"""

from __future__ import annotations

import os
import queue
import threading
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import RenderError
from snapcore.render.bodies import DEFAULT_BODY, BodyKind, scene_body
from snapcore.render.camera import check_size, default_view, fit_camera, motion_points
from snapcore.render.renderer import SceneRenderer

if TYPE_CHECKING:
    from snapcore.motion.scene import Scene
    from snapcore.render.camera import Camera

__all__ = [
    "render_video",
    "video_frame_map",
    "draw_label",
    "VIDEO_CRF",
    "VIDEO_PRESET",
    "VIDEO_X264_PARAMS",
    "VIDEO_SWS_FLAGS",
    "VIDEO_LIGHTING",
    "VP9_CRF",
]

#: x264 constant-rate factor: 23 is ffmpeg's default, visually clean for flat renders.
VIDEO_CRF = 23
#: x264 preset: "veryfast" keeps encoding well below rendering time on two cores.
VIDEO_PRESET = "veryfast"
#: x264 settings on top of :data:`VIDEO_PRESET` (not of another preset): the one-step
#: sub-pixel refinement and diamond motion search of "superfast", keeping "veryfast"'s
#: macroblock tree. On the salsa pair at 1280x720, ~1.2-1.5 ms less x264 CPU a frame
#: (of ~8), files ~9% larger, PSNR against the rendered frames 0.13 dB lower (45.4 dB);
#: "superfast" itself saved as much but made files 2.9x larger (docs/speed.md).
VIDEO_X264_PARAMS = "subme=1:me=dia"
#: swscale's filter for the rgb24 → yuv420p conversion of H.264 videos (ffmpeg's
#: default: bicubic): each 2x2 block's chroma from one of its pixels. ~0.7 ms less
#: ffmpeg CPU a frame at 1280x720, and decoded (by ffmpeg) closer to the rendered
#: frames: RGB PSNR 39.25 → 40.0 and 38.74 → 39.42 dB on two salsa clips.
VIDEO_SWS_FLAGS = "neighbor"
#: How video frames light the bodies: "vertex" (the default; Gouraud, see
#: :attr:`~snapcore.render.raster.DrawMesh.vertex_lighting`) or "pixel" (as stills:
#: ``SNAPCORE_VIDEO_LIGHTING=pixel``). Per vertex, the 1,000-frame salsa video costs
#: ~8-9 CPU-ms less a 1280x720 frame (of ~33: 23.7 -> 19.1 s); its pixels are 0.04-0.06
#: levels from the per-pixel frame's on average, 0.01-0.02% of them more than 16 apart
#: (the small highlights on fingers), not told apart at 1:1 (docs/speed.md). Video frames
#: already draw the reduced body, so they were never the stills' pixels.
VIDEO_LIGHTING = "pixel" if os.environ.get("SNAPCORE_VIDEO_LIGHTING") == "pixel" else "vertex"
#: libvpx-vp9 constant quality (0-63; 32 looks like x264's 23 on flat renders).
VP9_CRF = 32


def video_frame_map(
    n_frames: int, motion_fps: float, video_fps: float, *, start: int = 0, stop: int | None = None
) -> np.ndarray:
    """Internal motion frame shown by each video frame.

    Parameters
    ----------
    n_frames : int
        Frames of the motion.
    motion_fps, video_fps : float
    start, stop : int
        Internal frame range to cover (``stop`` exclusive; default the whole motion).

    Returns
    -------
    ndarray of int, shape (K,)
        ``K = floor((stop - 1 - start) · video_fps / motion_fps) + 1`` frames; entry ``k``
        is ``start + round(k · motion_fps / video_fps)``.
    """
    stop = n_frames if stop is None else int(stop)
    start = int(start)
    if not (0 <= start < stop <= n_frames):
        raise RenderError(f"frame range {start}:{stop} is outside the motion's 0:{n_frames}")
    if not (video_fps > 0 and motion_fps > 0):
        raise RenderError(
            f"frame rates must be positive, got video {video_fps}, motion {motion_fps}"
        )
    duration = (stop - 1 - start) / motion_fps
    k = np.arange(int(np.floor(duration * video_fps + 1e-9)) + 1)
    return np.minimum(start + np.round(k * motion_fps / video_fps).astype(int), stop - 1)


def draw_label(
    image: np.ndarray, text: str, *, corner: str = "bottom-left", scale: float = 1.0
) -> np.ndarray:
    """``image`` (H, W, 3) uint8 with ``text`` in a small translucent box (a new array)."""
    from PIL import Image, ImageDraw, ImageFont

    h, w = image.shape[:2]
    size = max(int(round(min(h, w) * 0.035 * scale)), 10)
    font = ImageFont.load_default(size=size)
    im = Image.fromarray(image)
    draw = ImageDraw.Draw(im, "RGBA")
    x0, y0, x1, y1 = draw.textbbox((0, 0), text, font=font)
    pad = size // 3
    bw, bh = x1 - x0 + 2 * pad, y1 - y0 + 2 * pad
    m = size // 2
    x = m if "left" in corner else w - m - bw
    y = m if "top" in corner else h - m - bh
    draw.rectangle([x, y, x + bw, y + bh], fill=(255, 255, 255, 190))
    draw.text((x + pad - x0, y + pad - y0), text, fill=(40, 40, 40, 255), font=font)
    return np.asarray(im)


def _video_threads() -> int:
    """1 or 2: ``SNAPCORE_VIDEO_THREADS`` if set to 1 or 2 (to compare the two ways),
    else 2 with two cores or more."""
    asked = os.environ.get("SNAPCORE_VIDEO_THREADS", "").strip()
    if asked in ("1", "2"):
        return int(asked)
    return min(2, os.cpu_count() or 1)


#: Threads (each with its own GL context) that draw a video's frames between them.
#: llvmpipe does a draw's vertex work and binning on the thread that issues it (12-15
#: of a video frame's ~27 GL ms), so one drawing thread leaves the second core idle.
VIDEO_THREADS = _video_threads()
#: Fewer frames than this are drawn on the calling thread alone (a second renderer
#: draws its own background first: one full frame).
_MIN_FRAMES_TWO_THREADS = 8


class _Stopped(Exception):
    """The other drawing thread failed or the frames are no longer wanted."""


class _Turns:
    """Frames posed strictly in order by threads taking turns: ``turn(k)`` is a context
    manager that waits until frames ``0 .. k-1`` are posed. The body posing them keeps
    state between calls (its block of posed frames, the last resolved contacts), so
    each frame is posed with the same calls, in the same order, as on one thread."""

    def __init__(self) -> None:
        self._cond = threading.Condition()
        self._next = 0
        self._stopped = False

    def stop(self) -> None:
        with self._cond:
            self._stopped = True
            self._cond.notify_all()

    @contextmanager
    def turn(self, k: int) -> Iterator[None]:
        with self._cond:
            while self._next != k and not self._stopped:
                self._cond.wait()
            if self._stopped:
                raise _Stopped()
        try:
            yield
        except BaseException:
            self.stop()
            raise
        with self._cond:
            self._next = k + 1
            self._cond.notify_all()


def video_frames(sr: SceneRenderer, frames: np.ndarray, camera: Camera) -> Iterator[np.ndarray]:
    """The pictures of internal frames ``frames`` seen by ``camera``, in order, each
    equal to ``sr.render(index, camera, crop=True)``.

    With :data:`VIDEO_THREADS` = 2 and enough frames, a helper thread with its own GL
    context and its own :class:`SceneRenderer` (the same scene, size, floor and body
    object) draws the odd frames while this thread draws the even ones; both pose the
    shared body in frame order (:class:`_Turns`), and llvmpipe's per-draw work on the
    issuing thread runs on both cores.
    """
    frames = np.asarray(frames)
    if VIDEO_THREADS < 2 or len(frames) < _MIN_FRAMES_TWO_THREADS:
        yield from sr.render_frames(frames, camera)
        return
    from snapcore.render.gl import release_renderer

    turns = _Turns()
    odd: queue.Queue = queue.Queue()  # bounded by the turns: a frame or two ahead

    def draw_odd() -> None:
        try:
            other = SceneRenderer(
                sr.scene,
                size=sr.size,
                ground=sr.ground,
                shadows=sr.shadows,
                body=sr.body,
                floor=sr.floor,
            )
            other.horizon_point = sr.horizon_point
            other.vertex_lighting = sr.vertex_lighting
            mine = frames[1::2]
            for img in other.render_frames(
                mine, camera, turns=(turns.turn(2 * j + 1) for j in range(len(mine)))
            ):
                odd.put(img)
        except BaseException as err:
            turns.stop()
            odd.put(err)
        finally:
            release_renderer()

    helper = threading.Thread(target=draw_odd, name="snapcore-video-odd", daemon=True)
    helper.start()
    try:
        even = frames[0::2]
        for j, img in enumerate(
            sr.render_frames(even, camera, turns=(turns.turn(2 * j) for j in range(len(even))))
        ):
            yield img
            if 2 * j + 1 < len(frames):
                item = odd.get()
                if isinstance(item, BaseException):
                    raise item
                yield item
    except _Stopped:  # the helper failed while this thread waited for its turn
        raise odd.get() from None
    finally:
        turns.stop()
        helper.join()


def render_video(
    scene: Scene,
    path: str | Path,
    *,
    fps: float = 24.0,
    size: tuple[int, int] = (1280, 720),
    view: ArrayLike | None = None,
    projection: str = "orthographic",
    frame_numbers: bool = False,
    progress: bool = True,
    frame_range: tuple[int, int] | None = None,
    ground: bool = True,
    shadows: bool = True,
    crf: int = VIDEO_CRF,
    preset: str = VIDEO_PRESET,
    camera: Camera | None = None,
    webm: str | Path | None = None,
    body: BodyKind = DEFAULT_BODY,
    detail: str = "reduced",
) -> np.ndarray:
    """Render a scene to an H.264 MP4.

    Parameters
    ----------
    scene : Scene
    path : str or Path
        Output file (``.mp4``); its folder must exist.
    fps : float
        Video frame rate; the motion is resampled to it (nearest frame).
    size : (int, int)
        Width and height in pixels, both even (yuv420p halves the chroma resolution).
    view : array of shape (3,), optional
        From the scene towards the camera; default :func:`~snapcore.render.camera.default_view`.
    projection : {"orthographic", "perspective"}
    frame_numbers : bool
        Print the source frame number and time in the bottom-left corner.
    progress : bool
        Show a tqdm progress bar on stderr.
    frame_range : (int, int), optional
        Source frames ``start, stop`` (stop exclusive; the file's own numbers, as
        ``Snapshot.source_frame`` and the returned map) to render; default all.
    ground, shadows : bool
        Floor grid and shadows.
    crf : int
        x264 quality (lower = better, bigger).
    preset : str
        x264 speed preset; with the default, :data:`VIDEO_X264_PARAMS` too.
    camera : Camera, optional
        Use this camera (its size must equal ``size``) instead of fitting one to the
        motion along ``view``.
    webm : str or Path, optional
        Also write the same frames as WebM/VP9 here (same frame count and rate), for
        browsers without H.264.
    body : {"human", "mannequin"}
        What the characters wear (:data:`snapcore.render.bodies.BodyKind`).
    detail : {"reduced", "full"}
        Level of detail of human bodies: the reduced mesh (a third of the triangles,
        the same picture at video sizes, ~40% less time a frame; see
        :mod:`snapcore.render.human_asset`) or the full one.

    Returns
    -------
    ndarray of int, shape (K,)
        For each video frame, the motion frame it shows in *source* numbering
        (``scene.source_frame``).

    Notes
    -----
    The calling thread draws the even frames and, with two cores, a helper thread with
    its own GL context the odd ones (:func:`video_frames`; EGL contexts are
    thread-bound); another thread feeds the frames, in order, to ffmpeg so encoding
    overlaps rendering.

    Examples
    --------
    The first second of the synthetic walk (30 fps) as a 10 fps video shows every third
    motion frame:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from snapcore import render_video
    >>> from snapcore.motion.synth import synth_scene
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     shown = render_video(synth_scene("walk"), Path(folder) / "walk.mp4", fps=10,
    ...                          size=(96, 64), frame_range=(0, 30), progress=False)
    >>> shown.tolist()
    [0, 3, 6, 9, 12, 15, 18, 21, 24, 27]
    """
    import imageio_ffmpeg
    from tqdm import tqdm

    w, h = check_size(size)
    if w % 2 or h % 2:
        raise RenderError(f"video width and height must be even (yuv420p), got {w}x{h}")
    if not (np.isfinite(fps) and 0 < fps <= 240):
        raise RenderError(f"fps must be in (0, 240], got {fps}")
    start, stop = (0, scene.n_frames)
    if frame_range is not None:
        first, end = int(scene.frame_offset), int(scene.frame_offset) + scene.n_frames
        a, b = int(frame_range[0]), int(frame_range[1])
        if not first <= a < b <= end:
            raise RenderError(
                f"frame_range {a}:{b} is not within the scene's source frames {first}:{end}"
            )
        start, stop = a - first, b - first
    frames = video_frame_map(scene.n_frames, scene.fps, fps, start=start, stop=stop)
    path = Path(path)
    if not path.parent.exists():
        raise FileNotFoundError(2, "no such folder", str(path.parent))

    sr = SceneRenderer(
        scene,
        size=(w, h),
        ground=ground,
        shadows=shadows,
        body=scene_body(scene, kind=body, detail=detail),
    )
    sr.vertex_lighting = VIDEO_LIGHTING == "vertex"
    if camera is None:
        if view is None:
            view = default_view(scene)
        camera = fit_camera(
            motion_points(scene, frames=np.arange(start, stop), body=sr.body),
            view,
            size=(w, h),
            projection=projection,
        )

    writer = imageio_ffmpeg.write_frames(
        str(path),
        (w, h),
        pix_fmt_in="rgb24",
        pix_fmt_out="yuv420p",
        fps=float(fps),
        codec="libx264",
        quality=None,
        macro_block_size=2,
        ffmpeg_log_level="error",
        output_params=[
            "-preset",
            preset,
            *(["-x264-params", VIDEO_X264_PARAMS] if preset == VIDEO_PRESET else []),
            "-sws_flags",
            VIDEO_SWS_FLAGS,
            "-crf",
            str(int(crf)),
            "-g",
            str(max(int(round(fps)), 1)),
            "-movflags",
            "+faststart",
        ],
    )
    writer.send(None)  # start ffmpeg
    writers = [writer]
    if webm is not None:
        vp9 = imageio_ffmpeg.write_frames(
            str(webm),
            (w, h),
            pix_fmt_in="rgb24",
            pix_fmt_out="yuv420p",
            fps=float(fps),
            codec="libvpx-vp9",
            quality=None,
            macro_block_size=2,
            ffmpeg_log_level="error",
            output_params=[
                "-b:v",
                "0",
                "-crf",
                str(VP9_CRF),
                "-deadline",
                "realtime",
                "-cpu-used",
                "8",
                "-row-mt",
                "1",
                "-g",
                str(max(int(round(fps)), 1)),
            ],
        )
        vp9.send(None)
        writers.append(vp9)
    q: queue.Queue = queue.Queue(maxsize=6)
    failure: list[BaseException] = []

    def feed() -> None:
        try:
            while True:
                item = q.get()
                if item is None:
                    return
                for wr in writers:
                    wr.send(item)
        except BaseException as err:  # surfaced on the rendering thread
            failure.append(err)
            while q.get() is not None:  # drain so the renderer never blocks
                pass

    feeder = threading.Thread(target=feed, name="snapcore-video-encode", daemon=True)
    feeder.start()
    bar = tqdm(
        total=len(frames),
        desc=f"video {path.name}",
        unit="frame",
        disable=not progress,
        leave=False,
    )
    try:
        # two threads drawing alternate frames, each pipelined: a frame is posed
        # while the one before rasterises
        for f, img in zip(frames, video_frames(sr, frames, camera)):
            if failure:
                break
            if frame_numbers:
                src = int(scene.source_frame(int(f)))
                img = draw_label(img, f"frame {src}   {f / scene.fps:6.2f} s")
            q.put(np.ascontiguousarray(img))
            bar.update(1)
    finally:
        q.put(None)
        feeder.join()
        bar.close()
        for wr in writers:
            try:
                wr.close()
            except Exception as err:
                if not failure:
                    failure.append(err)
    if failure:
        raise RenderError(f"encoding {path} failed: {failure[0]}") from failure[0]
    return np.asarray(scene.source_frame(frames), dtype=np.int64)
