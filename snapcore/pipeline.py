"""The pipeline: Scene → Snapshot (the pose and the view of one still image).

:func:`take_snapshot` runs the stages on a scene and returns a :class:`Snapshot`: the
pose selection, the view selection (Projected Motion Area) and the two baseline views
(motion area, and viewpoint entropy, which renders the posed body: this module is the
one place where selection meets rendering). :meth:`Snapshot.to_dict` is the JSON
document ``snapshot select --json`` prints (schema ``data_schema/snapshot.schema.json``).
Like every output, a Snapshot reports frames in the *source* numbering
(``scene.source_frame(i) = i + frame_offset``): ``Snapshot.source_frame``/``source_frames``
and every frame number in ``to_dict``; the per-frame arrays start at source frame
``frame_offset``. ``Snapshot.index``/``indices`` (and ``Snapshot.pose``, a
:class:`~snapcore.select.pose_selection.PoseSelection`) hold internal indices into the scene's
arrays. :attr:`Snapshot.views` gives the three methods' directions by
:class:`~snapcore.select.view_methods.ViewMethod`.
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field, fields
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from snapcore.errors import SelectionError, SnapshotError
from snapcore.motion.scene import Scene
from snapcore.render.bodies import DEFAULT_BODY, BodyKind, check_body
from snapcore.render.viewpoint_entropy import EntropySelection, select_view_entropy
from snapcore.select.pose_methods import PoseParams, select_pose
from snapcore.select.pose_selection import PoseSelection
from snapcore.select.story import DEFAULT_STORY
from snapcore.select.view import (
    MA_FLOOR_M2,
    ViewSelection,
    motion_triangles,
    select_view,
    window_frames,
)
from snapcore.select.view_methods import ViewMethod

__all__ = [
    "Snapshot",
    "ViewParams",
    "DEFAULT_VIEW",
    "take_snapshot",
    "snapshot_params",
    "SNAPSHOT_FORMAT",
    "VIEW_FIELDS",
]

#: Value of the ``format`` field of the JSON document (bump on breaking changes).
SNAPSHOT_FORMAT = "action-snapshot/snapshot@2"
#: Optional fields filled by later stages, in the order ``to_dict`` writes them.
VIEW_FIELDS = ("view", "view_refined", "baselines", "pma", "window")
#: Decimals kept for per-frame entropy values in the JSON (they are in [0, 2]).
_DECIMALS = 6


@dataclass(frozen=True)
class ViewParams:
    """Options of the view stage.

    Attributes
    ----------
    window_s : float or None
        Score the view over the selected pose ± this many seconds (pose-specific
        view); None: the whole sequence.
    baselines : bool
        Also compute the motion-area and viewpoint-entropy views.
    n_views : int
        Samples of the view sphere (2562: icosphere, ~4° apart).
    refine : bool
        Refine the best sample exactly (L1 fixed point, METHOD.md §2).
    floor_m2 : float
        Quads sweeping less than this area (m²) do not vote (:data:`MA_FLOOR_M2`).
    body : {"human", "mannequin"}
        The body the viewpoint-entropy baseline renders and scores
        (:data:`snapcore.render.bodies.BodyKind`; the CLI's ``--body``). The other
        views come from the joints and do not depend on it.
    """

    window_s: float | None = None
    baselines: bool = True
    n_views: int = 2562
    refine: bool = True
    floor_m2: float = MA_FLOOR_M2
    body: BodyKind = DEFAULT_BODY

    def __post_init__(self) -> None:
        check_body(self.body)  # refused here, not after the pose stage has run


@dataclass(eq=False)
class Snapshot:
    """What one still image of a scene shows: the pose(s) and, once chosen, the view.

    Attributes
    ----------
    scene : Scene
        The analysed scene (not serialised).
    pose : PoseSelection
        Selected frame, top-k frames (internal indices), pose entropy, events.
    options : dict
        The options the stages ran with (JSON-ready).
    timings_s : dict
        Seconds per stage: ``contacts``, ``local``, ``global``, ``select``,
        ``pose`` (the whole pose stage), ``total``; later stages add their own.
    view_params : ViewParams or None
        The view stage's options (None: the stage did not run).
    view_selection : ViewSelection or None
        Our view (Projected Motion Area).
    motion_area : ViewSelection or None
        The motion-area baseline view (Kwon & Lee).
    viewpoint_entropy : EntropySelection or None
        The viewpoint-entropy baseline view of the selected pose (Vázquez et al.).
    """

    scene: Any
    pose: PoseSelection
    options: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)
    view_params: ViewParams | None = None
    view_selection: ViewSelection | None = None
    motion_area: ViewSelection | None = None
    viewpoint_entropy: EntropySelection | None = None

    @property
    def views(self) -> dict[ViewMethod, np.ndarray]:
        """The view directions that were computed, by method: unit vectors (3,)."""
        found = {
            ViewMethod.OURS: self.view_selection,
            ViewMethod.VIEWPOINT_ENTROPY: self.viewpoint_entropy,
            ViewMethod.MOTION_AREA: self.motion_area,
        }
        return {m: np.asarray(sel.view, dtype=float) for m, sel in found.items() if sel is not None}

    @property
    def view(self) -> np.ndarray | None:
        """Our view (PMA): unit vector from the scene centre to the camera, or None."""
        return None if self.view_selection is None else self.view_selection.view

    @property
    def view_refined(self) -> np.ndarray | None:
        """The refined view (None without refinement or without the view stage)."""
        return self.view if self.view_params is not None and self.view_params.refine else None

    @property
    def pma(self) -> dict | None:
        """Projected-motion-area details of the view stage (JSON-ready)."""
        sel, params = self.view_selection, self.view_params
        if sel is None:
            return None
        if params is None:  # the view stage sets both
            raise SnapshotError("Snapshot.pma: view_selection is set without its view_params")
        return {
            "score": sel.score,
            "mean_ratio": sel.mean_ratio,
            "view_grid": sel.view_grid,
            "score_grid": sel.score_grid,
            "n_views": int(sel.views.shape[0]),
            "n_quads": sel.n_quads,
            "n_skipped": sel.n_skipped,
            "floor_m2": float(params.floor_m2),
            "iterations": sel.iterations,
            "certified": sel.certified,
            "facing": sel.facing,
            "side_rule": sel.side_rule,
            "facing_note": sel.facing_note,
        }

    @property
    def window(self) -> dict | None:
        """The time window the view was computed over (source frame numbers)."""
        sel = self.view_selection
        if sel is None:
            return None
        src, w = self.scene.source_frame, sel.window_s
        return {
            "mode": "sequence" if w is None else "pose",
            "half_width_s": None if w is None else float(w),
            "frame": None if w is None else int(src(self.pose.index)),
            "start_frame": int(src(sel.frames[0])),
            "end_frame": int(src(sel.frames[1] - 1)),
        }

    @property
    def baselines(self) -> dict | None:
        """The baseline views with their scores (JSON-ready); None when not run."""
        if self.view_params is None or not self.view_params.baselines:
            return None
        out = {}
        if (ma := self.motion_area) is not None:
            out[ViewMethod.MOTION_AREA.value] = {
                "view": ma.view,
                "score": ma.score,
                "units": "m2",
                "side_rule": ma.side_rule,
                "certified": ma.certified,
            }
        if (ve := self.viewpoint_entropy) is not None:
            out[ViewMethod.VIEWPOINT_ENTROPY.value] = {
                "view": ve.view,
                "score": ve.score,
                "units": "bits",
                "frame": int(self.scene.source_frame(ve.frame)),
                "n_views": int(ve.views.shape[0]),
                "resolution": ve.resolution,
                "n_faces": ve.n_faces,
            }
        return out

    @property
    def source_frame(self) -> int:
        """The selected pose as the file's own frame number (``to_dict()["frame"]``)."""
        return int(self.scene.source_frame(self.pose.index))

    @property
    def source_frames(self) -> list[int]:
        """The top-k poses as the file's own frame numbers, best first."""
        return [int(self.scene.source_frame(i)) for i in self.pose.indices]

    @property
    def index(self) -> int:
        """The selected pose as an index into the scene's (cut) arrays (``pose.index``)."""
        return int(self.pose.index)

    @property
    def indices(self) -> list[int]:
        """The top-k poses as indices into the scene's arrays, best first."""
        return [int(i) for i in self.pose.indices]

    def to_dict(self) -> dict:
        """The JSON document (``data_schema/snapshot.schema.json``); source frame numbers."""
        scene = self.scene
        scores = self.pose.scores
        fps = float(scene.fps)

        def src(i: int) -> int:
            return int(scene.source_frame(int(i)))

        def rnd(a: ArrayLike) -> list[float]:
            return np.round(np.asarray(a, dtype=float), _DECIMALS).tolist()

        # each peak: its source frame, time, total and the terms that add up to it
        peaks = [
            {
                "frame": src(i),
                "time_s": round(i / fps, 6),
                "total": float(scores.total[i]),
                **{name: float(v[i]) for name, v in scores.terms.items()},
            }
            for i in self.pose.indices
        ]
        counts: dict[str, dict[str, int]] = {}  # character → object → events
        for e in scores.interactions.events:
            ch = scene.characters[e.character].name
            counts.setdefault(ch, {})
            counts[ch][e.object] = counts[ch].get(e.object, 0) + 1
        doc = {
            "format": SNAPSHOT_FORMAT,
            "scene": scene.name,
            "characters": [c.name for c in scene.characters],
            "fps": fps,
            "n_frames": int(scene.n_frames),
            "frame_offset": int(scene.frame_offset),
            "duration_s": float(scene.duration),
            "frame": src(self.pose.index),
            "time_s": round(self.pose.index / fps, 6),
            "frames": [src(i) for i in self.pose.indices],
            "pose_method": self.pose.method,
            "peaks": peaks,
            "pose_scores": {
                "method": scores.method,
                "unit": scores.unit,
                "first_frame": src(0),
                "terms": {name: rnd(v) for name, v in scores.terms.items()},
                "total": rnd(scores.total),
            },
            "events": scores.interactions.records(scene),
            "event_counts": counts,
            "options": _jsonable(self.options),
            "timings_s": {k: float(v) for k, v in self.timings_s.items()},
        }
        if (ent := self.pose.entropy) is not None:  # the paper's method keeps its names
            doc["pose_entropy"] = {
                "first_frame": src(0),
                "weights": {"local": ent.weights[0], "global": ent.weights[1]},
                "events_mode": ent.events_mode,
                "local": rnd(ent.local),
                "global": rnd(ent.global_),
                "total": rnd(ent.total),
            }
        for name in VIEW_FIELDS:
            value = getattr(self, name)
            if value is not None:
                doc[name] = _jsonable(value)
        return doc


def _jsonable(value: Any) -> Any:
    """NumPy arrays and scalars → lists and Python numbers, recursively."""
    if isinstance(value, dict):
        return {str(k): _jsonable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_jsonable(v) for v in value]
    if isinstance(value, np.ndarray):
        return _jsonable(value.tolist())
    if isinstance(value, np.generic):
        return value.item()
    return value


#: The view stage's options unless told otherwise (``take_snapshot``'s default).
DEFAULT_VIEW = ViewParams()


def snapshot_params(options: Mapping[str, Any]) -> tuple[PoseParams, ViewParams]:
    """The two stages' parameter objects from one flat table of options, by field name.

    What a study config's ``selection`` table and a batch's options give: each key is a
    field of :class:`~snapcore.select.pose_methods.PoseParams` (``pose_method``, ``k``,
    ``min_separation_s``, ``w_local``...) or of :class:`ViewParams` (``window_s``,
    ``baselines``, ``n_views``...) other than ``body``, a render option given beside the
    table.

    Parameters
    ----------
    options : mapping of str to value
        Field names and values; missing fields keep their defaults.

    Returns
    -------
    (PoseParams, ViewParams)

    Raises
    ------
    SelectionError
        A key that is a field of neither (one line naming it and the known ones), or a
        paper-only option with another pose method
        (:class:`~snapcore.select.pose_methods.PaperOptionError`).

    Examples
    --------
    >>> from snapcore.pipeline import snapshot_params
    >>> pose, view = snapshot_params({"pose_method": "paper", "k": 2, "window_s": 0.5})
    >>> pose.method, pose.k, view.window_s, view.baselines
    ('paper', 2, 0.5, True)
    >>> try:
    ...     snapshot_params({"top_k": 3})
    ... except ValueError as err:
    ...     print(str(err).split(" (")[0])
    unknown selection option(s) top_k
    """
    pose_names = [f.name for f in fields(PoseParams)]
    # not the body kind: a render option, given beside the selection (``--body``,
    # ``BatchOptions.body``), so a selection table cannot set it for one baseline alone
    view_names = [f.name for f in fields(ViewParams) if f.name != "body"]
    unknown = [k for k in options if k not in pose_names and k not in view_names]
    if unknown:
        raise SelectionError(
            f"unknown selection option(s) {', '.join(map(str, unknown))} "
            f"(pose: {', '.join(pose_names)}; view: {', '.join(view_names)})"
        )
    pose = PoseParams(**{k: v for k, v in options.items() if k in pose_names})
    view = ViewParams(**{k: v for k, v in options.items() if k in view_names})
    return pose, view


def take_snapshot(
    scene: Scene,
    *,
    pose: PoseParams | None = None,
    view: ViewParams | None = DEFAULT_VIEW,
) -> Snapshot:
    """Run the pipeline on ``scene``: select the pose, then the view.

    Parameters
    ----------
    scene : Scene
        The motion to analyse.
    pose : PoseParams, optional
        The pose stage's options (None: ``PoseParams()``, the default ``story``
        selector). A paper-only option with another method already fails when the
        PoseParams is made.
    view : ViewParams or None
        The view stage's options (default: ``ViewParams()``, the whole sequence with
        both baselines); None skips the view stage (pose only).

    Returns
    -------
    Snapshot
        ``options`` records every pose parameter (the tolerances as
        ``contact_tolerances``) and, with the view stage, ``window_s``, ``baselines``
        and ``n_views``.

    Raises
    ------
    TypeError
        ``pose`` or ``view`` that is not a parameter object.

    Examples
    --------
    >>> from snapcore import PoseParams, ViewParams, take_snapshot
    >>> from snapcore.motion.synth import synth_scene
    >>> scene = synth_scene("walk")
    >>> snap = take_snapshot(scene, pose=PoseParams(k=2), view=ViewParams(baselines=False))
    >>> len(snap.pose.indices), snap.motion_area is None
    (2, True)
    >>> bool(abs(snap.view_selection.view[0]) > 0.9)  # a walk along +Z, seen from the side
    True
    >>> take_snapshot(scene, view=None).view is None  # the pose stage only
    True
    """
    if pose is None:
        pose = PoseParams()
    if not isinstance(pose, PoseParams):
        raise TypeError(f"take_snapshot: pose must be a PoseParams, got {pose!r}")
    if view is not None and not isinstance(view, ViewParams):
        raise TypeError(
            f"take_snapshot: view must be a ViewParams (run the view stage) or None "
            f"(skip it), got {view!r}"
        )
    kwargs = pose.kwargs()
    t0 = time.perf_counter()
    sel = select_pose(scene, **kwargs)
    t1 = time.perf_counter()
    options = {
        "pose_method": sel.method,
        "k": int(pose.k),
        "min_separation_s": float(pose.min_separation_s),
    }
    options.update(
        {
            name: value
            for name, value in kwargs.items()
            if name not in ("method", "k", "min_separation_s", "tolerances", "story")
        }
    )
    tol = sel.scores.interactions.tolerances
    if sel.method == "paper":
        options["contact_tolerances"] = {
            "ground_distance_m": tol.ground_distance,
            "body_distance_m": tol.body_distance,
            "prop_distance_m": tol.prop_distance,
            "displacement_m": tol.displacement,
            "min_duration_s": tol.min_duration,
        }
    elif sel.method == "story":  # every ingredient of the run, for the record
        options["story"] = asdict(pose.story or DEFAULT_STORY)
    timings = {
        key: sel.timings_s[key]
        for key in ("contacts", "local", "global", "story", "select")
        if key in sel.timings_s
    }
    timings["pose"] = t1 - t0
    snap = Snapshot(scene=scene, pose=sel, options=options, timings_s=timings)
    if view is not None:
        options.update(
            window_s=view.window_s, baselines=bool(view.baselines), n_views=int(view.n_views)
        )
        _view_stage(snap, view)
    timings["total"] = time.perf_counter() - t0
    return snap


def _view_stage(snap: Snapshot, params: ViewParams) -> None:
    """Fill the view fields of ``snap`` for its selected pose, adding their timings.

    A baseline that cannot run (no OpenGL for the face-id renders) is left out with a
    warning rather than failing the whole selection.
    """
    scene, index, timings = snap.scene, snap.pose.index, snap.timings_s
    t0 = time.perf_counter()
    frames = window_frames(scene, index if params.window_s is not None else None, params.window_s)
    tri = motion_triangles(scene, frames=frames, floor=params.floor_m2)
    common: dict[str, Any] = dict(
        index=index,
        window_s=params.window_s,
        n_views=params.n_views,
        refine=params.refine,
        floor=params.floor_m2,
        triangles=tri,
    )
    snap.view_params = params
    snap.view_selection = select_view(scene, **common)
    timings["view"] = time.perf_counter() - t0
    if not params.baselines:
        return
    t1 = time.perf_counter()
    snap.motion_area = select_view(scene, method="motion_area", **common)
    t2 = time.perf_counter()
    timings["motion_area"] = t2 - t1
    try:
        snap.viewpoint_entropy = select_view_entropy(scene, index, body=params.body)
    except (SnapshotError, RuntimeError) as err:
        warnings.warn(f"viewpoint-entropy baseline skipped: {err}", stacklevel=3)
    else:
        timings["viewpoint_entropy"] = time.perf_counter() - t2
