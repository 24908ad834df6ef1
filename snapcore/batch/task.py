"""The one task of a batch: a scene's file(s) in, its snapshot, thumbnail and sheet out.

:func:`run_scene` is the function every executor runs, in this process (``--jobs 1``),
in worker processes (``--jobs N``) or on Dask workers (``--scheduler``): the same code
path everywhere, so a cluster run gives the same index as a local one. It never raises
for a bad scene: the failure becomes the row's one-line ``error`` and the rest of the
library goes on. It writes nothing either: the outputs come back as bytes in the
:class:`SceneResult` and the process that owns the output folder writes them (so
workers need no shared output folder and a killed worker leaves no half files).

Rendering: an EGL context works only on the thread that created it
(../shared/PLATFORM-NOTES.md § Threads), and :func:`snapcore.render.gl.bare_gl_context`
keeps one per thread (the scene renderer and the face-id pass draw in it; pyrender is
not loaded). :func:`init_worker` creates it once when a worker process starts;
every scene of that worker then reuses it.
"""

from __future__ import annotations

import hashlib
import io
import json
import os
import signal
import time
import warnings
from dataclasses import asdict, dataclass, field, replace
from typing import TYPE_CHECKING

from snapcore.batch.discover import SceneSource
from snapcore.errors import SceneError, SnapshotError

if TYPE_CHECKING:  # the worker imports rendering where it renders
    from snapcore.render.bodies import BodyKind

__all__ = [
    "BatchOptions",
    "SceneTask",
    "SceneResult",
    "run_scene",
    "init_worker",
    "worker_env",
    "blas_threads",
    "error_result",
    "OUTPUT_FORMAT",
]

#: Bumped when the outputs of a scene change meaning: part of every options hash, so a
#: new format redoes the library instead of mixing old and new outputs.
OUTPUT_FORMAT = "action-snapshot/batch@3"
#: Longest error text kept in the index (characters).
MAX_ERROR = 400


@dataclass(frozen=True)
class BatchOptions:
    """How every scene of a batch is processed (the same for all of them).

    Attributes
    ----------
    snapshot : dict
        Fields of the pipeline's ``PoseParams`` and ``ViewParams`` by name (``k``,
        ``min_separation_s``, ``w_local``, ``window_s``, ``baselines``...), read by
        :func:`snapcore.pipeline.snapshot_params`; the view stage always runs (the
        thumbnail shows the chosen view). A plain table, as the options hash covers it.
    fps : float or None
        Frame-rate override for every scene (None: each file's or manifest's own).
    scale : float or None
        Metres per file unit for every scene (None: inferred per scene).
    size : (int, int)
        Thumbnail width and height, pixels.
    sheet : bool
        Also render the top-k contact sheet.
    sheet_size : (int, int)
        Size of each contact-sheet panel, pixels.
    preview : int
        Panels of the preview strip (the whole motion at evenly spaced frames, small,
        for scrubbing in the gallery); 0: none.
    body : {"human", "mannequin"} or None
        Body drawn on skeletons (glTF characters wear their own with "human"); it also
        changes the viewpoint-entropy baseline, which renders the body. None: the
        default of :mod:`snapcore.render.bodies`.
    animation : str or None
        glTF characters: the animation to play, by name or index (None: the first).
    """

    snapshot: dict = field(default_factory=dict)
    fps: float | None = None
    scale: float | None = None
    size: tuple[int, int] = (320, 360)
    sheet: bool = False
    sheet_size: tuple[int, int] = (320, 360)
    body: BodyKind | None = None
    animation: str | None = None
    preview: int = 12

    def to_dict(self) -> dict:
        """JSON-ready options (what the options hash covers)."""
        d = asdict(self)
        d["size"], d["sheet_size"] = list(self.size), list(self.sheet_size)
        return d

    def key(self) -> str:
        """SHA-256 (hex) of the options and :data:`OUTPUT_FORMAT`: a scene done with
        the same content hash and the same key is not redone.

        The extra pictures (``sheet``, ``preview``) are left out: they change no number
        of the row, so asking for them again only renders those a row lacks, and
        dropping them redoes nothing (:data:`EXTRAS`)."""
        doc = {"format": OUTPUT_FORMAT, **self.to_dict()}
        for name in EXTRAS:
            doc.pop(name)
        return hashlib.sha256(json.dumps(doc, sort_keys=True).encode()).hexdigest()

    def extras(self) -> tuple[str, ...]:
        """The extra pictures asked for (outputs named as in :data:`EXTRAS`)."""
        return tuple(name for name in EXTRAS if getattr(self, name))


#: Optional pictures of a scene, outside the options hash: option name = output name.
EXTRAS = ("sheet", "preview")


@dataclass(frozen=True)
class SceneTask:
    """One scene to process: where it is, how, and the hashes its row will carry."""

    scene: SceneSource
    options: BatchOptions
    content_hash: str
    options_hash: str
    #: The source frame chosen as the thumbnail in the gallery (None: the chosen pose).
    thumb_choice: int | None = None
    #: A finished row of this scene with the same hashes: the selection is not redone,
    #: only what ``render`` names is rendered again from the row's frames and view.
    reuse: dict | None = None
    #: With ``reuse``: the outputs to render ("thumb", "sheet", "preview").
    render: tuple[str, ...] = ()
    #: With ``reuse`` and "sheet": the caption of each top pose (from its document).
    captions: tuple[str, ...] = ()


@dataclass
class SceneResult:
    """What :func:`run_scene` returns.

    Attributes
    ----------
    row : dict
        The scene's index row without output paths (see :mod:`snapcore.batch.index`).
    outputs : dict of str to bytes
        ``"json"`` (the ``select --json`` document), ``"thumb"`` (PNG), ``"sheet"``
        (PNG, with ``--sheet``), ``"preview"`` (PNG); empty for a failed scene.
    kept : tuple of str
        Outputs of the previous run that stay as they are (a re-render of part of a
        row): neither rewritten nor deleted.
    worker : dict
        ``pid``, ``renderer`` (id of the thread's GL renderer), ``lp_threads`` (Mesa
        rasteriser threads, ``LP_NUM_THREADS``) and ``blas_threads`` (each loaded BLAS
        library's threads, by file name, after the task) of whoever ran it.
    """

    row: dict
    outputs: dict = field(default_factory=dict)
    worker: dict = field(default_factory=dict)
    kept: tuple[str, ...] = ()


#: Environment variables that set a BLAS's or OpenMP's thread count when it loads.
BLAS_THREAD_VARS = ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS")


def worker_env(threads: int = 1) -> dict[str, str]:
    """The environment that gives a process ``threads`` BLAS and Mesa rasteriser threads.

    Read by each BLAS when it loads and by Mesa's llvmpipe (``LP_NUM_THREADS``) when a
    GL context is made: set before either happens. ``threads`` must be at least 1.
    """
    n = str(int(threads))
    return {var: n for var in BLAS_THREAD_VARS} | {"LP_NUM_THREADS": n}


def blas_threads() -> dict[str, int]:
    """Threads of each BLAS (or OpenMP) library loaded in this process, by file name."""
    from threadpoolctl import threadpool_info

    return {os.path.basename(i["filepath"]): int(i["num_threads"]) for i in threadpool_info()}


def init_worker(
    size=(320, 360),
    ignore_sigint: bool = True,
    threads: int | None = 1,
    parent: int | None = None,
    *,
    renderer: bool = True,
):
    """Set up a worker process: the GL renderer, created once, and the signals.

    Parameters
    ----------
    size : (int, int)
        A size to create the renderer at (every render resizes it as needed).
    ignore_sigint : bool
        Ignore Ctrl-C here: the terminal sends it to every process of the group, and
        the parent, not each worker, decides what to do with it (write the index of
        what finished, then stop the workers).
    threads : int or None
        BLAS and Mesa llvmpipe (software GL) threads per worker (None: leave as is). N
        workers on N cores, each running a BLAS and a rasteriser with a thread per core,
        would fight over the cores; one process per core is the parallelism here.
    parent : int, optional
        PID of the process that started this worker: the worker ends itself within a
        second of that process's death (a main process killed with SIGKILL cannot stop
        its workers; a worker holds hundreds of MB and a core).
    renderer : bool
        Create this thread's GL renderer now (False where the tasks run on other
        threads, as on a Dask worker).
    """
    if ignore_sigint:
        signal.signal(signal.SIGINT, signal.SIG_IGN)
    if parent is not None:
        _watch_parent(parent)
    if threads is not None:
        # A BLAS reads its thread count once, when it loads; threadpoolctl can change
        # only the libraries already loaded. NumPy and SciPy (each with its own
        # OpenBLAS) load later, in the first task, so the environment is what limits
        # them (a local pool's parent also sets it around the spawn: see
        # :func:`worker_env`); the call below is for a process (a Dask worker) that
        # loaded them before.
        os.environ.update(worker_env(threads))
        from threadpoolctl import threadpool_limits

        threadpool_limits(threads)
    if not renderer:
        return
    try:
        from snapcore.render.gl import bare_gl_context

        bare_gl_context()
    except SnapshotError:
        # no GL here: each scene then fails with the renderer's own one-line reason
        pass


def _watch_parent(parent: int, every_s: float = 0.5) -> None:
    """End this process (exit code 3) once ``parent`` is no longer its parent.

    A thread polling ``getppid`` rather than ``prctl(PR_SET_PDEATHSIG)``: the latter
    fires when the *thread* that started the worker ends, and the pool starts workers
    from whichever thread submits.
    """
    import threading

    def watch():
        while os.getppid() == parent:
            time.sleep(every_s)
        os._exit(3)

    if os.getppid() == parent:
        threading.Thread(target=watch, name="watch-parent", daemon=True).start()
    else:  # already orphaned while starting
        os._exit(3)


def _one_line(err: BaseException, scene: SceneSource) -> str:
    """The error as one line, the scene's absolute path shortened to its key."""
    text = str(err) if isinstance(err, SnapshotError) else f"{type(err).__name__}: {err}"
    line = (text.strip().splitlines() or [type(err).__name__])[0]
    line = line.replace(scene.path, scene.key)
    return line if len(line) <= MAX_ERROR else line[: MAX_ERROR - 1] + "…"


def _load(task: SceneTask):
    from snapcore.motion.load import load_scene

    s, opts = task.scene, task.options
    if s.kind == "unknown":
        from snapcore.batch.discover import MANIFEST_SUFFIXES, MOTION_SUFFIXES

        raise SceneError(
            f"{s.key}: not a motion file (expected {', '.join(MOTION_SUFFIXES)} or a "
            f"scene manifest {'/'.join(MANIFEST_SUFFIXES)})"
        )
    return load_scene([s.path], fps=opts.fps, scale=opts.scale, animation=opts.animation)


#: zlib level of the batch's PNGs: 3 (zlib's fast matcher) encodes a scene's thumbnail
#: and preview strip in ~8.4 CPU-ms against 14.6 at PIL's default 6, for files ~10%
#: larger (85 against 77 KiB a scene, the 42-scene subset of docs/speed.md).
PNG_LEVEL = 3


def _png(image) -> bytes:
    from PIL import Image

    buf = io.BytesIO()
    Image.fromarray(image).save(buf, format="PNG", compress_level=PNG_LEVEL)
    return buf.getvalue()


def _base_row(task: SceneTask) -> dict:
    s = task.scene
    return {
        "path": s.key,
        "folder": s.folder,
        "name": s.key.rsplit("/", 1)[-1],
        "kind": s.kind,
        "content_hash": task.content_hash,
        "options_hash": task.options_hash,
        "status": "error",
        "error": None,
        "warnings": None,
        # kept on a failed row too: a clip broken for one run keeps its animator's choice
        "thumb_choice": task.thumb_choice,
    }


def error_result(task: SceneTask, err: BaseException) -> SceneResult:
    """The result of a scene whose task could not run at all (a worker that died)."""
    row = _base_row(task)
    row["error"] = _one_line(err, task.scene)
    return SceneResult(row=row)


def run_scene(task: SceneTask) -> SceneResult:
    """Process one scene (see :func:`_run_scene`), then free what it left behind."""
    result = _run_scene(task)
    _release()
    return result


#: Set once the first scene's survivors (modules, caches) are frozen out of the collector.
_FROZEN: list[bool] = []


def _release() -> None:
    """Free the finished scene now, not at the next full collection.

    A scene and its bodies form a reference cycle (the body cache lives on the scene),
    which only the cycle collector frees, and a full collection comes rarely: a worker's
    RSS then swung between 285 and 410 MB over 200 scenes; collected after each scene it
    stayed at 244 MB. The objects alive after the first scene (imported modules, caches)
    are frozen out of the collector (:func:`gc.freeze`), so each later collection only
    looks at one scene's objects.
    """
    import gc

    gc.collect()
    if not _FROZEN:
        gc.freeze()
        _FROZEN.append(True)


def _run_scene(task: SceneTask) -> SceneResult:
    """Process one scene: load, select pose and view, render thumbnail (and sheet).

    Parameters
    ----------
    task : SceneTask

    Returns
    -------
    SceneResult
        ``row["status"]`` is ``"ok"``, or ``"error"`` with ``row["error"]`` one line
        (a malformed file, a scene that cannot be analysed); never raises for those.
        Timings (seconds): ``t_load_s``, ``t_select_s`` (the pipeline), ``t_render_s``
        (thumbnail and sheet), ``t_total_s``.
    """
    opts = task.options
    if task.reuse is not None:
        return _rerender(task)
    row = _base_row(task)
    outputs: dict[str, bytes] = {}
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            scene = _load(task)
            t1 = time.perf_counter()
            outputs["json"], row_fields, captions = _select(scene, opts)
            t2 = time.perf_counter()
            row_fields["thumb_choice"] = task.thumb_choice
            row_fields["thumb_frame"] = _thumb_frame(scene, row_fields, task.thumb_choice)
            pictures, preview = _render(
                scene, row_fields, opts, ("thumb", *opts.extras()), captions
            )
            outputs.update(pictures)
            row_fields["preview_frames"] = preview
            t3 = time.perf_counter()
        except Exception as err:  # one bad scene must not stop a library of thousands
            row["error"] = _one_line(err, task.scene)
            outputs = {}
        else:
            row.update(
                row_fields, status="ok", t_load_s=t1 - t0, t_select_s=t2 - t1, t_render_s=t3 - t2
            )
    row["t_total_s"] = time.perf_counter() - t0
    row["warnings"] = _notes(caught, task.scene) or None
    return SceneResult(row=row, outputs=outputs, worker=_worker(opts))


def _notes(caught, scene: SceneSource) -> list[str]:
    """The warnings caught, one line each, once each, the scene's path as its key."""
    notes = dict.fromkeys(str(w.message).splitlines()[0] for w in caught)
    return [n.replace(scene.path, scene.key) for n in notes]


#: Warnings of a row that were about its thumbnail choice (re-made on every render).
_CHOICE_NOTE = "thumbnail frame "


def _rerender(task: SceneTask) -> SceneResult:
    """Render again only what ``task.render`` names, from the previous row's frames and
    view (no selection): a new thumbnail choice, a sheet or preview asked for now."""
    prev = dict(task.reuse or {})
    row = {k: v for k, v in prev.items() if k not in ("json", "thumb", "sheet", "preview")}
    t0 = time.perf_counter()
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            scene = _load(task)
            t1 = time.perf_counter()
            row["thumb_choice"] = task.thumb_choice
            row["thumb_frame"] = _thumb_frame(scene, row, task.thumb_choice)
            pictures, preview = _render(scene, row, task.options, task.render, task.captions)
            if "preview" in task.render:
                row["preview_frames"] = preview
            t2 = time.perf_counter()
        except Exception as err:  # the files changed under us: the row becomes the error
            row = _base_row(task)
            row.update(error=_one_line(err, task.scene), t_total_s=time.perf_counter() - t0)
            return SceneResult(row=row, worker=_worker(task.options))
    row.update(t_load_s=t1 - t0, t_select_s=0.0, t_render_s=t2 - t1, t_total_s=t2 - t0)
    # warnings of the selection stay; those about the choice are made anew
    old = [w for w in prev.get("warnings") or [] if not w.startswith(_CHOICE_NOTE)]
    row["warnings"] = list(dict.fromkeys(old + _notes(caught, task.scene))) or None
    kept = tuple(k for k in ("json", "thumb", "sheet", "preview") if k not in pictures)
    return SceneResult(row=row, outputs=pictures, worker=_worker(task.options), kept=kept)


def _select(scene, opts: BatchOptions):
    """The snapshot document (bytes), the index fields it gives and the captions of
    its top poses (for the sheet)."""
    from snapcore.pipeline import snapshot_params, take_snapshot
    from snapcore.schema import validate

    pose, view = snapshot_params(opts.snapshot)
    if opts.body is not None:  # what the viewpoint-entropy baseline renders
        view = replace(view, body=opts.body)
    snap = take_snapshot(scene, pose=pose, view=view)
    doc = snap.to_dict()
    validate(doc, "snapshot", source=f"{scene.name} snapshot")
    data = (json.dumps(doc, indent=1, allow_nan=False) + "\n").encode()
    totals = doc["pose_scores"]["total"]
    at = doc["frame"] - doc["pose_scores"]["first_frame"]
    fields = {
        "score": round(float(totals[at]), 6) if 0 <= at < len(totals) else None,
        "characters": len(doc["characters"]),
        "rig": " + ".join(dict.fromkeys(_rig(c) for c in scene.characters)),
        "n_frames": doc["n_frames"],
        "fps": doc["fps"],
        "duration_s": round(doc["duration_s"], 6),
        "frame": doc["frame"],
        "time_s": doc["time_s"],
        "first_frame": doc["pose_scores"]["first_frame"],
        "top_frames": [int(f) for f in doc["frames"]],
        "view_x": round(float(doc["view"][0]), 6),
        "view_y": round(float(doc["view"][1]), 6),
        "view_z": round(float(doc["view"][2]), 6),
    }
    sc = snap.pose.scores
    return data, fields, tuple(sc.caption(sc.total[i]) for i in snap.indices)


def _rig(character) -> str:
    """A skeleton's family as an animator names it: root joint and joint count."""
    roots = [i for i, p in enumerate(character.parents) if p < 0] or [0]
    return f"{character.joint_names[roots[0]]}, {len(character.joint_names)} joints"


def _thumb_frame(scene, row: dict, choice: int | None) -> int:
    """The source frame the thumbnail shows: the animator's choice when the clip has
    it, else the chosen pose, with a warning (kept in the row) that the choice is not
    there. The choice itself is kept either way: the file may come back."""
    if choice is None:
        return int(row["frame"])
    first, last = scene.frame_offset, scene.frame_offset + scene.n_frames - 1
    if first <= choice <= last:
        return int(choice)
    warnings.warn(
        f"{_CHOICE_NOTE}{choice} chosen in the gallery is not in the clip now (it keeps "
        f"source frames {first}..{last}): the chosen pose, frame {row['frame']}, is shown",
        stacklevel=2,
    )
    return int(row["frame"])


def preview_size(size: tuple[int, int]) -> tuple[int, int]:
    """Panel size of the preview strip for thumbnails of ``size``: 3/8 of it, at least
    48 pixels wide (a card's width at the smallest thumbnail setting)."""
    w = max(48, size[0] * 3 // 8)
    return w, max(1, round(w * size[1] / size[0]))


def _render(scene, row: dict, opts: BatchOptions, what, captions=()):
    """The pictures ``what`` names, from the row's frames and view (source frames).

    Returns
    -------
    pictures : dict of str to bytes
        ``"thumb"``: frame ``thumb_frame``; ``"sheet"``: the top poses with their
        ``captions``; ``"preview"``: ``opts.preview`` evenly spaced frames of the whole
        motion side by side, at one scale, no gap (a card pans across it), on the
        mannequin body (cheap; the preview is small).
    preview_frames : list of int or None
        The preview's source frames.
    """
    import numpy as np

    from snapcore.render.bodies import DEFAULT_BODY
    from snapcore.render.renderer import render_still

    body = opts.body or DEFAULT_BODY
    view = np.array([row["view_x"], row["view_y"], row["view_z"]], dtype=float)
    out = {}
    if "thumb" in what:
        frame = row["thumb_frame"]  # source numbering, as render_still takes it
        out["thumb"] = _png(render_still(scene, frame, view, size=opts.size, body=body))
    if "sheet" in what:
        from snapcore.render.composites import contact_sheet

        top = [int(f) for f in row["top_frames"]]  # source numbering
        out["sheet"] = _png(
            contact_sheet(
                scene,
                top,
                view=view,
                captions=list(captions) if len(captions) == len(top) else None,
                size=opts.sheet_size,
                title=scene.name,
                body=body,
            )
        )
    frames = None
    if "preview" in what and opts.preview > 0:
        n = min(opts.preview, scene.n_frames)
        internal = np.unique(np.linspace(0, scene.n_frames - 1, n).round().astype(int))
        # the capsule mannequin: 12 panels cost about what the thumbnail does (the
        # skinned human body, 0.3 s a frame on one core, would cost ten times that)
        out["preview"] = _png(_strip(scene, internal, view, preview_size(opts.size), "mannequin"))
        frames = [int(f) for f in scene.source_frame(internal)]
    return out, frames


def _strip(scene, frames, view, size, body):
    """Panels of ``frames`` (internal) side by side at one scale, the floor level across
    them, no caption or gap: panel ``i`` is columns ``i*W .. (i+1)*W``."""
    import numpy as np

    from snapcore.render.bodies import scene_body
    from snapcore.render.composites import common_cameras, floor_aligned
    from snapcore.render.mannequin import tessellation_for
    from snapcore.render.renderer import SceneRenderer

    # small panels draw a mannequin of fewer triangles (see tessellation_for), framed
    # as the full one is: the same cameras, so the floor and the figures' places in
    # the panels do not move
    sr = SceneRenderer(
        scene, size=size, body=scene_body(scene, tessellation_for(size[1]), kind=body)
    )
    full = scene_body(scene, kind=body)
    pts = [full.vertices(f) for f in frames]
    cams = common_cameras(pts, [view] * len(frames), size=size)
    feet = [np.mean([c.positions[f, 0] for c in scene.characters], axis=0) for f in frames]
    for ft in feet:
        ft[1] = scene.ground
    cams = floor_aligned(cams, pts, feet)
    return np.hstack([sr.render(f, c)[..., :3] for f, c in zip(frames, cams)])


def _worker(opts: BatchOptions) -> dict:
    """Who ran the task: the process and the id of its thread's GL renderer."""
    try:
        from snapcore.render.gl import bare_gl_context

        renderer = id(bare_gl_context())
    except SnapshotError:
        renderer = None
    return {
        "pid": os.getpid(),
        "renderer": renderer,
        "lp_threads": os.environ.get("LP_NUM_THREADS"),
        "blas_threads": blas_threads(),
    }
