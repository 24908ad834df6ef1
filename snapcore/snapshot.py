"""The pipeline: Scene → Snapshot (the pose and the view of one still image).

:func:`take_snapshot` runs the stages on a scene and returns a :class:`Snapshot`,
whose :meth:`Snapshot.to_dict` is the JSON document ``snapshot select --json`` prints
(schema ``data_schema/snapshot.schema.json``). Like every output, a Snapshot reports
frames in the *source* numbering (``scene.source_frame(i) = i + frame_offset``):
``Snapshot.frame``/``frames`` and every frame number in ``to_dict``; the per-frame
arrays start at source frame ``frame_offset``. ``Snapshot.index``/``indices`` (and
``Snapshot.pose``, a :class:`~snapcore.pose.PoseSelection`) hold internal indices
into the scene's arrays.

Extending it (the view stage): the view fields below are declared with ``None``
defaults; a stage fills them and ``to_dict`` includes every one that is set (NumPy
arrays become lists). A stage adds its timings to ``timings_s`` under its own keys.
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from .pose import MIN_SEPARATION_S, PoseSelection, select_pose

__all__ = ["Snapshot", "take_snapshot", "SNAPSHOT_FORMAT", "VIEW_FIELDS"]

#: Value of the ``format`` field of the JSON document (bump on breaking changes).
SNAPSHOT_FORMAT = "action-snapshot/snapshot@1"
#: Optional fields filled by later stages, in the order ``to_dict`` writes them.
VIEW_FIELDS = ("view", "view_refined", "baselines", "pma", "window")
#: Decimals kept for per-frame entropy values in the JSON (they are in [0, 2]).
_DECIMALS = 6


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
    view, view_refined : ndarray of shape (3,) or None
        Unit vectors from the scene centre to the camera (world frame, Y up).
    baselines : dict or None
        Baseline view directions by method name.
    pma : dict or None
        Projected-motion-area details of the view stage.
    window : dict or None
        The time window the view was computed over.
    """

    scene: Any
    pose: PoseSelection
    options: dict = field(default_factory=dict)
    timings_s: dict = field(default_factory=dict)
    view: np.ndarray | None = None
    view_refined: np.ndarray | None = None
    baselines: dict | None = None
    pma: dict | None = None
    window: dict | None = None

    @property
    def frame(self) -> int:
        """The selected pose as a SOURCE frame number (like ``to_dict()["frame"]``)."""
        return int(self.scene.source_frame(self.pose.frame))

    @property
    def frames(self) -> list[int]:
        """The top-k poses as SOURCE frame numbers, best first."""
        return [int(self.scene.source_frame(i)) for i in self.pose.frames]

    @property
    def index(self) -> int:
        """The selected pose as an internal index into the scene's arrays."""
        return int(self.pose.frame)

    @property
    def indices(self) -> list[int]:
        """The top-k poses as internal indices, best first."""
        return [int(i) for i in self.pose.frames]

    def to_dict(self) -> dict:
        """The JSON document (``data_schema/snapshot.schema.json``); source frame numbers."""
        scene = self.scene
        ent = self.pose.entropy
        fps = float(scene.fps)

        def src(i) -> int:
            return int(scene.source_frame(int(i)))

        def rnd(a) -> list[float]:
            return np.round(np.asarray(a, dtype=float), _DECIMALS).tolist()

        peaks = [
            {
                "frame": src(i),
                "time_s": round(i / fps, 6),
                "total": float(ent.total[i]),
                "local": float(ent.local[i]),
                "global": float(ent.global_[i]),
            }
            for i in self.pose.frames
        ]
        counts = {}
        for e in ent.interactions.events:
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
            "frame": src(self.pose.frame),
            "time_s": round(self.pose.frame / fps, 6),
            "frames": [src(i) for i in self.pose.frames],
            "pose_method": self.pose.method,
            "peaks": peaks,
            "pose_entropy": {
                "first_frame": src(0),
                "weights": {"local": ent.weights[0], "global": ent.weights[1]},
                "events_mode": ent.events_mode,
                "local": rnd(ent.local),
                "global": rnd(ent.global_),
                "total": rnd(ent.total),
            },
            "events": ent.interactions.records(scene),
            "event_counts": counts,
            "options": _jsonable(self.options),
            "timings_s": {k: float(v) for k, v in self.timings_s.items()},
        }
        for name in VIEW_FIELDS:
            value = getattr(self, name)
            if value is not None:
                doc[name] = _jsonable(value)
        return doc


def _jsonable(value):
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


def take_snapshot(scene, *, pose_method: str | None = None, k: int = 3,
                  min_separation_s: float = MIN_SEPARATION_S, view: bool = True, window_s: float | None = None, baselines: bool = True,
                  n_views: int = 2562, **pose_options) -> Snapshot:
    """Run the pipeline on ``scene``: select the pose, then the view.

    Parameters
    ----------
    scene : Scene
    pose_method : str, optional
        The pose selector (:data:`snapcore.pose_methods.POSE_METHODS`); default
        ``"story"``; ``"paper"`` for the paper's pose entropy.
    k : int
        Number of distinct top poses to keep.
    min_separation_s : float
        Minimum time (s) between them.
    view : bool
        Run the view stage (:func:`snapcore.view.view_stage`): PMA view of the whole
        sequence or of ``window_s``, and the baselines.
    window_s : float, optional
        Score the view over the selected pose ± this many seconds (pose-specific view).
    baselines : bool
        Also compute the motion-area and viewpoint-entropy views.
    n_views : int
        Samples of the view sphere.
    **pose_options
        Passed to :func:`snapcore.pose.select_pose` (``w_local``, ``w_global``,
        ``events``, ``smooth_s``, ``rest_speed``, ``tolerances``).

    Returns
    -------
    Snapshot
    """
    t0 = time.perf_counter()
    sel = select_pose(scene, method=pose_method, k=k, min_separation_s=min_separation_s,
                      **pose_options)
    t1 = time.perf_counter()
    options = {"pose_method": sel.method, "k": int(k), "min_separation_s": float(min_separation_s)}
    for name, value in pose_options.items():
        if name in ("tolerances", "interactions", "story"):
            continue
        options[name] = value
    tol = sel.entropy.interactions.tolerances
    if sel.method == "paper":
        options["contact_tolerances"] = {
            "ground_distance_m": tol.ground_distance,
            "body_distance_m": tol.body_distance,
            "prop_distance_m": tol.prop_distance,
            "displacement_m": tol.displacement,
            "min_duration_s": tol.min_duration,
        }
    elif sel.method == "story":  # every ingredient of the run, for the record
        from dataclasses import asdict

        from .story import DEFAULT_STORY

        options["story"] = asdict(pose_options.get("story") or DEFAULT_STORY)
    timings = {key: sel.timings_s[key] for key in ("contacts", "local", "global", "story", "select")
               if key in sel.timings_s}
    timings["pose"] = t1 - t0
    fields = {}
    if view:
        from .view import view_stage

        options.update(window_s=window_s, baselines=bool(baselines), n_views=int(n_views))
        fields, view_timings = view_stage(scene, sel.frame, window_s=window_s,
                                          baselines=baselines, n_views=n_views)
        timings.update(view_timings)
    timings["total"] = time.perf_counter() - t0
    return Snapshot(scene=scene, pose=sel, options=options, timings_s=timings, **fields)
