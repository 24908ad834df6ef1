"""Videos, contact sheets, view comparisons and the render/video/sheet commands."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner

from snapcore.cli.main import cli
from snapcore.errors import RenderError
from snapcore.motion import synth
from snapcore.render.video import render_video, video_frame_map

pytestmark = pytest.mark.timeout(300)


@pytest.fixture(scope="module")
def walk():
    return synth.synth_scene("walk", fps=30)


def _probe(path):
    """(metadata, number of frames, first frame) decoded with imageio-ffmpeg."""
    import imageio_ffmpeg

    gen = imageio_ffmpeg.read_frames(str(path))
    meta = next(gen)
    frames = [np.frombuffer(f, np.uint8) for f in gen]
    return meta, len(frames), frames


def test_frame_map_resamples_by_nearest_time():
    """60 fps motion at 24 fps: frame k shows motion frame round(2.5 k)."""
    m = video_frame_map(61, 60.0, 24.0)
    assert len(m) == 25  # one second: floor(1.0 · 24) + 1
    np.testing.assert_array_equal(m[:5], [0, 2, 5, 8, 10])  # round half to even at 2.5·1
    assert m[-1] == 60
    sub = video_frame_map(300, 120.0, 30.0, start=100, stop=141)
    np.testing.assert_array_equal(sub, np.arange(100, 141, 4))
    with pytest.raises(RenderError):
        video_frame_map(10, 30.0, 24.0, start=5, stop=20)


def test_video_decodes_to_the_expected_frames_size_fps_and_codec(walk, tmp_path):
    """An H.264 yuv420p MP4 with floor(duration · fps) + 1 frames of the asked size."""
    path = tmp_path / "walk.mp4"
    fmap = render_video(walk, path, fps=24, size=(160, 96), progress=False)
    expect = int(np.floor((walk.n_frames - 1) / walk.fps * 24 + 1e-9)) + 1  # 3 s → 73
    assert len(fmap) == expect == 73
    meta, n, frames = _probe(path)
    assert n == expect
    assert meta["size"] == (160, 96)
    assert abs(meta["fps"] - 24) < 1e-6
    assert meta["codec"].startswith("h264")
    assert meta["pix_fmt"].startswith("yuv420p")
    # faststart: the index ("moov") comes before the media data ("mdat")
    head = path.read_bytes()
    assert 0 < head.find(b"moov") < head.find(b"mdat")
    # source numbering, monotone, within the scene
    assert fmap[0] == walk.source_frame(0) and fmap[-1] == walk.source_frame(walk.n_frames - 1)
    assert np.all(np.diff(fmap) >= 0)
    # the character is in the picture: frames are not blank
    img = frames[0].reshape(96, 160, 3)
    assert img.std() > 5


def test_video_frame_range_and_numbers(walk, tmp_path):
    """A sub-range at the motion's own rate has one video frame per motion frame; the
    frame-number label changes the pixels in its corner only."""
    a, b = tmp_path / "a.mp4", tmp_path / "b.mp4"
    fa = render_video(walk, a, fps=walk.fps, size=(128, 96), frame_range=(10, 20), progress=False)
    fb = render_video(
        walk,
        b,
        fps=walk.fps,
        size=(128, 96),
        frame_range=(10, 20),
        progress=False,
        frame_numbers=True,
    )
    np.testing.assert_array_equal(fa, walk.source_frame(np.arange(10, 20)))
    np.testing.assert_array_equal(fa, fb)
    _, n, fa_frames = _probe(a)
    _, _, fb_frames = _probe(b)
    assert n == 10
    da = fa_frames[0].reshape(96, 128, 3).astype(int)
    db = fb_frames[0].reshape(96, 128, 3).astype(int)
    diff = np.abs(da - db).sum(axis=2) > 30
    assert diff[60:, :64].sum() > 20  # the label, bottom-left
    assert diff[:30, 64:].sum() == 0  # nothing else changed


def test_video_rejects_odd_sizes(walk, tmp_path):
    with pytest.raises(RenderError, match="even"):
        render_video(walk, tmp_path / "x.mp4", size=(101, 64), progress=False)


def test_contact_sheet_and_view_comparison_layout(walk):
    """Panels of the asked size side by side (plus gaps and captions); one scale in every
    comparison panel, so the same pose seen from +Z and -Z has mirror silhouettes of
    equal area."""
    from snapcore.render.composites import PANEL_GAP, compare_views, contact_sheet
    from snapcore.render.renderer import BACKGROUND

    img = contact_sheet(walk, [0, 30, 60], size=(120, 140), entropy=[1.0, 2.0, 3.0])
    assert img.shape[1] == 3 * 120 + 4 * PANEL_GAP and img.shape[0] > 140
    cmp = compare_views(
        walk,
        30,
        {"front": [0, 0.2, 1], "back": [0, 0.2, -1]},
        size=(120, 140),
        labels=False,
        ground=False,
    )
    assert cmp.shape == (140 + 2 * PANEL_GAP, 2 * 120 + 3 * PANEL_GAP, 3)
    bg = np.round(np.asarray(BACKGROUND) * 255)
    g = PANEL_GAP
    panels = [cmp[g : g + 140, g : g + 120], cmp[g : g + 140, 2 * g + 120 : 2 * g + 240]]
    areas = [(np.abs(p.astype(int) - bg).sum(axis=2) > 12).sum() for p in panels]
    assert abs(areas[0] - areas[1]) / max(areas) < 0.05
    with pytest.raises(RenderError):
        contact_sheet(walk, [walk.n_frames])


# ----------------------------------------------------------------------------- CLI


@pytest.fixture(scope="module")
def walk_bvh(tmp_path_factory):
    from snapcore.motion.bvh import write_bvh

    p = tmp_path_factory.mktemp("bvh") / "walk.bvh"
    write_bvh(synth.humanoid_document("walk", seconds=2.0, fps=30), p)
    return p


def test_cli_render_writes_a_png_of_the_asked_size(walk_bvh, tmp_path):
    from PIL import Image

    out = tmp_path / "pose.png"
    r = CliRunner().invoke(
        cli,
        [
            "render",
            str(walk_bvh),
            "--frame",
            "12",
            "--view",
            "1,0.3,0.5",
            "-o",
            str(out),
            "--size",
            "160x120",
        ],
    )
    assert r.exit_code == 0, r.output
    assert Image.open(out).size == (160, 120)


def test_cli_render_bad_frame_is_one_line_exit_2(walk_bvh, tmp_path):
    r = CliRunner().invoke(
        cli,
        [
            "render",
            str(walk_bvh),
            "--frame",
            "999",
            "-o",
            str(tmp_path / "x.png"),
            "--view",
            "0,0,1",
        ],
    )
    assert r.exit_code == 2
    assert "frame 999 is not in this scene" in r.output
    assert "Traceback" not in r.output


def test_cli_video_writes_mp4_and_frame_map(walk_bvh, tmp_path):
    out, fm = tmp_path / "walk.mp4", tmp_path / "map.json"
    r = CliRunner().invoke(
        cli,
        [
            "video",
            str(walk_bvh),
            "-o",
            str(out),
            "--fps",
            "10",
            "--size",
            "128x96",
            "--quiet",
            "--frame-map",
            str(fm),
            "--view",
            "0,0,1",
        ],
    )
    assert r.exit_code == 0, r.output
    from snapcore.motion.bvh import read_bvh

    doc = json.loads(fm.read_text())
    meta, n, _ = _probe(out)
    f = read_bvh(walk_bvh).motion.shape[0]  # 30 fps file, no lead-in to cut
    assert n == len(doc["source_frames"]) == int(np.floor((f - 1) / 30 * 10 + 1e-9)) + 1
    assert abs(meta["fps"] - 10) < 1e-6 and doc["source_frames"][0] == 0


def test_cli_sheet_frames_and_views(walk_bvh, tmp_path):
    from PIL import Image

    a, b = tmp_path / "a.png", tmp_path / "b.png"
    r = CliRunner().invoke(
        cli,
        [
            "sheet",
            str(walk_bvh),
            "-o",
            str(a),
            "--frames",
            "5,25",
            "--size",
            "96x120",
            "--view",
            "0,0.2,1",
        ],
    )
    assert r.exit_code == 0, r.output
    assert Image.open(a).size[0] == 2 * 96 + 3 * 8
    r = CliRunner().invoke(
        cli,
        [
            "sheet",
            str(walk_bvh),
            "-o",
            str(b),
            "--frame",
            "10",
            "--views",
            "front=0,0,1",
            "--views",
            "side=1,0,0",
            "--views",
            "top=0,1,0",
            "--size",
            "96x120",
        ],
    )
    assert r.exit_code == 0, r.output
    assert Image.open(b).size[0] == 3 * 96 + 4 * 8


@pytest.mark.slow
def test_readme_images_command(motions_dir, tmp_path):
    """`python -m snapcore.cli.readme_images OUT` writes the contact sheet (three panels)
    and the three-view comparison of the README."""
    from PIL import Image

    from snapcore.cli.readme_images import PANEL, main
    from snapcore.render.composites import PANEL_GAP

    assert main([str(tmp_path)]) == 0
    sheet = Image.open(tmp_path / "contact_sheet.png")
    views = Image.open(tmp_path / "three_views.png")
    assert sheet.size[0] == 3 * PANEL[0] + 4 * PANEL_GAP
    assert views.size[0] == 3 * PANEL[0] + 4 * PANEL_GAP  # ours, viewpoint entropy, motion area


def test_contact_sheet_puts_the_floor_on_one_row():
    """Panels of a jump at one scale, each moved so the floor point under its pose is on
    the same image row (the airborne pose then stands higher than the crouch), and every
    pose still inside its panel."""
    from snapcore.render.bodies import scene_body  # the body the renderer draws
    from snapcore.render.composites import common_cameras, floor_aligned

    scene = synth.synth_scene("jump", fps=30)
    body = scene_body(scene)
    frames = [5, 30, 45]  # standing, crouched, in the air
    view = np.array([1.0, 0.3, 0.2]) / np.linalg.norm([1.0, 0.3, 0.2])
    pts = [body.vertices(f) for f in frames]
    cams = common_cameras(pts, [view] * 3, size=(160, 200))
    feet = []
    for f in frames:
        foot = scene.characters[0].positions[f, 0].copy()
        foot[1] = scene.ground
        feet.append(foot)
    aligned = floor_aligned(cams, pts, feet)
    # image-plane height of each floor point relative to its camera centre: equal
    rows = [float((ft - c.position) @ c.up) for ft, c in zip(feet, aligned)]
    assert max(rows) - min(rows) < 1e-9
    assert len({c.half_height for c in aligned}) == 1  # one scale
    assert aligned[0].half_height >= max(c.half_height for c in cams) - 1e-12
    for p, c in zip(pts, aligned):  # every vertex inside its panel
        y = (p - c.position) @ c.up
        assert np.abs(y).max() <= c.half_height
    # before aligning, the floor rows differed (the test would pass vacuously otherwise)
    before = [float((ft - c.position) @ c.up) for ft, c in zip(feet, cams)]
    assert max(before) - min(before) > 0.05


def test_hand_picked_frames_are_not_captioned_as_ranked(walk, monkeypatch):
    """Captions start with #1, #2... for the top-k poses, but not for frames picked by
    hand (a rank there would claim an order nobody computed)."""
    import snapcore.render.composites as sheets

    seen = []
    monkeypatch.setattr(
        sheets, "tile_panels", lambda panels, captions, **kw: seen.append(captions) or panels[0]
    )
    sheets.contact_sheet(walk, [5, 25], size=(64, 80))
    sheets.contact_sheet(walk, [5, 25], size=(64, 80), ranked=False)
    first = walk.source_frame(5)
    assert [c[0] for c in seen[0]][0] == f"#1   frame {first}"
    assert [c[0] for c in seen[1]][0] == f"frame {first}"


def test_webm_copy_has_the_same_frames(walk, tmp_path):
    """webm=: a VP9 WebM beside the MP4 with the same frame count, size and rate, and
    pictures that match the MP4's (browsers without H.264 play it instead)."""
    mp4, webm = tmp_path / "walk.mp4", tmp_path / "walk.webm"
    fmap = render_video(walk, mp4, fps=12, size=(160, 96), progress=False, webm=webm)
    m_meta, m_n, m_frames = _probe(mp4)
    w_meta, w_n, w_frames = _probe(webm)
    assert w_meta["codec"].startswith("vp9") and webm.read_bytes()[:4] == b"\x1a\x45\xdf\xa3"
    assert w_n == m_n == len(fmap) and w_meta["size"] == (160, 96)
    assert abs(w_meta["fps"] - 12) < 1e-6
    for k in (0, m_n // 2, m_n - 1):  # same pictures up to compression noise
        diff = np.abs(m_frames[k].astype(float) - w_frames[k].astype(float)).mean()
        assert diff < 4, (k, diff)


def _salsa_pair(motions_dir):
    """The Daz salsa pair at 60 fps (the test is skipped without it)."""
    import warnings

    from snapcore.motion.load import load_scene

    paths = [
        motions_dir / f for f in ("two_person/60_01_scaled.bvh", "two_person/61_01_scaled.bvh")
    ]
    if not all(p.exists() for p in paths):
        pytest.skip("the salsa pair is not in the shared data")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the salsa unit is fitted, which warns
        return load_scene(paths, fps=60)


def _frames_sent_to_the_encoder(monkeypatch) -> list[np.ndarray]:
    """A list that receives a copy of every frame ``render_video`` pipes to the encoder
    (imageio-ffmpeg's writer replaced: nothing is encoded)."""
    import imageio_ffmpeg

    sent: list[np.ndarray] = []

    def fake_writer(*args, **kwargs):
        while True:
            frame = yield
            if frame is not None:
                sent.append(np.array(frame, copy=True))

    monkeypatch.setattr(imageio_ffmpeg, "write_frames", fake_writer)
    return sent


def test_frames_piped_to_the_encoder_are_the_frames_rendered_one_by_one(motions_dir, monkeypatch):
    """A video's frames, drawn by two threads taking alternate frames (each with its own
    GL context and renderer, posing one body in turn), reach the encoder in order, each
    exactly the frame one renderer draws alone (fails if a frame is lost, doubled or
    out of order). The salsa pair's human bodies: one body object, whose posing keeps
    state between frames (a block of skinned frames, the last contacts resolved)."""

    from snapcore.render import video
    from snapcore.render.bodies import scene_body
    from snapcore.render.camera import default_view, fit_camera, motion_points
    from snapcore.render.renderer import SceneRenderer

    scene = _salsa_pair(motions_dir)
    if video.VIDEO_THREADS < 2:
        pytest.skip("one core: one drawing thread")
    sent = _frames_sent_to_the_encoder(monkeypatch)
    size, start, n = (320, 180), 880, 23
    off = scene.frame_offset
    shown = video.render_video(
        scene, "/tmp/unused.mp4", fps=scene.fps, size=size,
        frame_range=(off + start, off + start + n), progress=False,
    )  # fmt: skip
    assert len(sent) == len(shown) == n
    body = scene_body(scene, kind="human", detail="reduced")
    frames = np.arange(start, start + n)
    cam = fit_camera(motion_points(scene, frames=frames, body=body), default_view(scene), size=size)
    ref = SceneRenderer(scene, size=size, body=body)
    ref.vertex_lighting = video.VIDEO_LIGHTING == "vertex"  # lit as the video's frames are
    for k, f in enumerate(frames):
        assert np.array_equal(sent[k], ref.render(int(f), cam, crop=True)), k
    assert not np.array_equal(sent[0], sent[-1])  # the dancers moved


def test_video_frames_helper_failure_surfaces_and_no_thread_is_left(walk, monkeypatch):
    """An error on the helper thread drawing the odd frames is raised on the caller's
    thread (not a hang waiting for its turn), and stopping early ends the helper."""
    import threading

    from snapcore.render import video
    from snapcore.render.camera import fit_camera, motion_points
    from snapcore.render.renderer import SceneRenderer

    if video.VIDEO_THREADS < 2:
        pytest.skip("one core: one drawing thread")
    sr = SceneRenderer(walk, size=(96, 64))
    cam = fit_camera(motion_points(walk), [1.0, 0.5, 1.0], size=(96, 64))
    frames = video.video_frames(sr, np.arange(30), cam)
    for k, _ in enumerate(frames):
        if k == 5:
            break
    frames.close()
    assert not [t for t in threading.enumerate() if t.name == "snapcore-video-odd"]
    init = SceneRenderer.__init__

    def fail_on_helper(self, *args, **kwargs):
        if threading.current_thread().name == "snapcore-video-odd":
            raise ValueError("helper failed")
        init(self, *args, **kwargs)

    monkeypatch.setattr(SceneRenderer, "__init__", fail_on_helper)
    with pytest.raises(ValueError, match="helper failed"):
        list(video.video_frames(sr, np.arange(30), cam))
    assert not [t for t in threading.enumerate() if t.name == "snapcore-video-odd"]


def _encode(frames, path, fps, params):
    """``frames`` (list of (H, W, 3) uint8) as an H.264 MP4 with x264 ``params``."""
    import imageio_ffmpeg

    h, w = frames[0].shape[:2]
    writer = imageio_ffmpeg.write_frames(
        str(path), (w, h), pix_fmt_in="rgb24", pix_fmt_out="yuv420p", fps=fps,
        codec="libx264", quality=None, macro_block_size=2, ffmpeg_log_level="error",
        output_params=params,
    )  # fmt: skip
    writer.send(None)
    for f in frames:
        writer.send(np.ascontiguousarray(f))
    writer.close()


def _psnr(path, frames):
    """PSNR (dB) of the decoded video against ``frames``, over all pixels and channels."""
    _, n, decoded = _probe(path)
    assert n == len(frames)
    ref = np.stack(frames).astype(float)
    mse = ((np.stack(decoded).reshape(ref.shape) - ref) ** 2).mean()
    return 10 * np.log10(255.0**2 / mse)


def test_video_encoder_settings_keep_the_quality_and_size(motions_dir, walk, tmp_path):
    """The encoder settings videos use (``VIDEO_PRESET`` with ``VIDEO_X264_PARAMS``, a
    cheaper motion search than the preset's, and ``VIDEO_SWS_FLAGS``, chroma taken
    from one pixel of four) against the preset alone, on 90 frames of the salsa pair
    drawn as videos draw them: the decoded frames' PSNR against the rendered frames at
    most 0.3 dB lower, the file at most 20% larger (measured on 200 frames of the
    bench's 1280x720 clip: PSNR 38.79 → 39.42 dB, 11% larger). Fails on a setting that trades
    quality or size for speed beyond that (``superfast``: 2.9x the bytes), or if
    ``render_video`` does not hand the settings to x264 (which writes its options into
    the stream) or the conversion's filter to ffmpeg."""

    import imageio_ffmpeg

    from snapcore.render import video
    from snapcore.render.bodies import scene_body
    from snapcore.render.camera import default_view, fit_camera, motion_points
    from snapcore.render.renderer import SceneRenderer

    path = tmp_path / "walk.mp4"
    render_video(walk, path, fps=24, size=(160, 96), frame_range=(0, 30), progress=False)
    stream = path.read_bytes()
    for option in video.VIDEO_X264_PARAMS.split(":"):
        assert f" {option} ".encode() in stream  # x264's options in the stream
    sent: list[list[str]] = []

    def fake_writer(*args, **kwargs):
        sent.append(list(kwargs["output_params"]))
        while True:
            yield

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(imageio_ffmpeg, "write_frames", fake_writer)
        render_video(walk, path, fps=24, size=(160, 96), frame_range=(0, 3), progress=False)
    assert sent[0][sent[0].index("-sws_flags") + 1] == video.VIDEO_SWS_FLAGS
    scene = _salsa_pair(motions_dir)
    size, indices = (640, 360), np.arange(600, 690)
    body = scene_body(scene, kind="human", detail="reduced")
    cam = fit_camera(
        motion_points(scene, frames=indices, body=body), default_view(scene), size=size
    )
    frames = list(video.video_frames(SceneRenderer(scene, size=size, body=body), indices, cam))
    common = ["-preset", video.VIDEO_PRESET, "-crf", str(video.VIDEO_CRF), "-g", "60"]
    new, old = tmp_path / "new.mp4", tmp_path / "old.mp4"
    ours = ["-x264-params", video.VIDEO_X264_PARAMS, "-sws_flags", video.VIDEO_SWS_FLAGS]
    _encode(frames, new, scene.fps, common + ours)
    _encode(frames, old, scene.fps, common)
    assert b" subme=2 " in old.read_bytes()  # veryfast's own
    psnr_new, psnr_old = _psnr(new, frames), _psnr(old, frames)
    size_new, size_old = new.stat().st_size, old.stat().st_size
    assert psnr_new >= psnr_old - 0.3, (psnr_new, psnr_old)
    assert size_new <= 1.2 * size_old, (size_new, size_old)


def test_vertex_lighting_of_video_frames_stays_within_its_tolerance(motions_dir, monkeypatch):
    """``VIDEO_LIGHTING = "vertex"`` (the default) lights the salsa pair's bodies at the
    vertices on both drawing threads: every frame differs from the per-pixel one (fails if the choice
    is not passed on, e.g. to the second thread's renderer), and by little (fails for a
    broken shade: black bodies are 7 levels off on average). The bounds are ~3x the
    differences measured on 120 frames of three clips at this size (mean 0.04-0.06 levels,
    0.007-0.02% of the pixels more than 16 apart; docs/speed.md)."""

    from snapcore.render import video
    from snapcore.render.bodies import scene_body
    from snapcore.render.camera import default_view, fit_camera, motion_points
    from snapcore.render.renderer import SceneRenderer

    scene = _salsa_pair(motions_dir)
    sent = _frames_sent_to_the_encoder(monkeypatch)
    monkeypatch.setattr(video, "VIDEO_LIGHTING", "vertex")
    size, start, n = (1280, 720), 600, 10
    off = scene.frame_offset
    video.render_video(
        scene, "/tmp/unused.mp4", fps=scene.fps, size=size,
        frame_range=(off + start, off + start + n), progress=False,
    )  # fmt: skip
    assert len(sent) == n
    body = scene_body(scene, kind="human", detail="reduced")
    frames = np.arange(start, start + n)
    cam = fit_camera(motion_points(scene, frames=frames, body=body), default_view(scene), size=size)
    ref = SceneRenderer(scene, size=size, body=body)
    mean, beyond = [], []
    for k, f in enumerate(frames):
        d = np.abs(sent[k].astype(int) - ref.render(int(f), cam, crop=True).astype(int))
        assert d.any(), k
        mean.append(d.mean())
        beyond.append((d.max(axis=2) > 16).mean())
    assert np.mean(mean) < 0.2
    assert np.mean(beyond) < 6e-4
