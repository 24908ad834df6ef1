"""The paper's figures and tables, regenerated (``snapshot figures``).

Each figure is made from the paper-analogue clips of the motion data folder
(``analysis/data/paper_analogues.csv``: which clip stands in for which of the paper's
animations) by the snapcore modules that own the method:

========  ============================================================================
fig5      pose entropy over each clip, the selected frames marked (Fig. 5);
          ``snapcore.render.entropy_plot``
fig6      local and global pose entropy of the dance (Fig. 6); ``snapcore.render.entropy_plot``
fig8-10   the selected pose from ours / viewpoint entropy / motion area (Fig. 8–10);
          ``compare_views`` of ``snapcore.render.renderer`` (or ``snapcore.render.composites``)
fig11     reliefs of the dance pose from the three views (Fig. 11);
          ``snapcore.relief.scene.relief_comparison_figure``
fig13     chosen-frame histograms (Fig. 13) from study responses, or — labelled as
          such — from simulated participants on the paper's design
table1    our pose / view selection times beside the paper's (Table 1), measured by
          running ``snapcore.pipeline.take_snapshot`` on the clips
table2    the paper's votes with our statistics (Table 2)
========  ============================================================================

A figure whose ingredients are missing (no motion data, a snapcore module absent) is
skipped with a one-line reason; the rest are still made (:func:`make_figures`).
"""

from __future__ import annotations

import time
import warnings
from collections.abc import Iterable
from dataclasses import dataclass, field
from importlib.resources import files
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import pandas as pd
from numpy.typing import ArrayLike

from snapcore.errors import SnapshotError
from snapcore.select.view_methods import VIEW_METHODS

if TYPE_CHECKING:  # imported where a figure needs them (snapcore's pipeline, matplotlib)
    from matplotlib.figure import Figure

    from snapcore.motion.scene import Scene
    from snapcore.pipeline import Snapshot

    from .load import ResponseSource

__all__ = [
    "FIGURES",
    "FigureUnavailable",
    "paper_analogues",
    "load_analogue",
    "paper_table1",
    "make_figures",
    "measure_table1",
    "snapshot_views",
]

#: Every figure/table ``snapshot figures`` can make, in the order it makes them.
FIGURES = ("table2", "fig13", "table1", "fig5", "fig6", "fig8-10", "fig11")
#: The clip the single-scene figures (Fig. 6, Fig. 11) use, like the paper's dancer.
FEATURE_SCENE = "dancing"


class FigureUnavailable(SnapshotError):
    """A figure cannot be made here (missing data or module); the message says why."""


def paper_analogues() -> pd.DataFrame:
    """Which motion clip stands in for which paper animation (package data).

    Returns
    -------
    DataFrame
        ``scene``, ``files`` (list of paths relative to the motion data folder),
        ``fps`` (override or NaN), ``caveat`` (how the stand-in differs from the paper's
        animation, said in every figure title; "" if nothing), ``note``.
    """
    with (files("analysis") / "data" / "paper_analogues.csv").open("r", encoding="utf-8") as fh:
        t = pd.read_csv(fh)
    t["files"] = t["files"].str.split(";")
    t["caveat"] = t["caveat"].fillna("")
    return t


def paper_table1() -> pd.DataFrame:
    """The paper's Table 1 (package data): faces, frames, joints, seconds per step."""
    with (files("analysis") / "data" / "paper_table1.csv").open("r", encoding="utf-8") as fh:
        return pd.read_csv(fh)


def load_analogue(scene_id: str, *, data_dir: str | Path | None = None) -> Scene:
    """Load the paper-analogue clip of ``scene_id`` as a :class:`snapcore.Scene`."""
    from snapcore import load_scene
    from snapcore.motion.load import data_dir as find_data

    base = Path(data_dir) if data_dir is not None else find_data()
    if base is None:
        raise FigureUnavailable("no motion data folder (set SNAPSHOT_DATA)")
    t = paper_analogues().set_index("scene")
    if scene_id not in t.index:
        raise FigureUnavailable(f"no analogue clip for '{scene_id}'")
    row = t.loc[scene_id]
    paths = [base / f for f in row["files"]]
    missing = [str(p) for p in paths if not p.exists()]
    if missing:
        raise FigureUnavailable(f"motion file(s) missing: {', '.join(missing)}")
    fps = None if pd.isna(row["fps"]) else float(row["fps"])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # unit fitting of the salsa files warns, as documented
        return load_scene(paths, fps=fps, name=scene_id)


@dataclass
class _Context:
    """What several figures share: loaded clips and their snapshots (computed once)."""

    out: Path
    source: object = None
    include_simulated: bool = False
    repeats: int = 3
    progress: bool = True
    data_dir: str | Path | None = None
    scenes: dict = field(default_factory=dict)
    snapshots: dict = field(default_factory=dict)

    def scene(self, sid: str) -> Scene:
        if sid not in self.scenes:
            self.scenes[sid] = load_analogue(sid, data_dir=self.data_dir)
        return self.scenes[sid]

    def snapshot(self, sid: str) -> Snapshot:
        if sid not in self.snapshots:
            from snapcore.pipeline import take_snapshot
            from snapcore.select.pose_methods import PoseParams

            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                self.snapshots[sid] = take_snapshot(
                    self.scene(sid), pose=PoseParams(pose_method="paper")
                )
        return self.snapshots[sid]

    def log(self, text: str) -> None:
        if self.progress:
            import click

            click.echo(text, err=True)


def _labels() -> dict:
    from .votes import paper_table2

    t = paper_table2()
    return dict(zip(t["scene"], t["scene_label"], strict=True))


# ----------------------------------------------------------------- the figures


def _table2(ctx: _Context) -> list[Path]:
    from .plots import plot_votes, save_figure
    from .tables import write_table
    from .votes import ours_vs_baselines, paper_counts, vote_table

    counts = paper_counts()
    labels = _labels()
    table = vote_table(counts)
    pair = ours_vs_baselines(counts)
    wide = counts.copy()
    wide.insert(0, "animation", [labels[s] for s in counts.index])
    paths = write_table(
        wide.reset_index(drop=True),
        ctx.out / "table2",
        caption="The paper's Table 2: votes of 100 participants per view.",
    )
    paths += write_table(
        pair,
        ctx.out / "table2_pairwise",
        caption="Ours vs each baseline on the paper's counts: exact binomial, Holm-adjusted.",
    )
    paths += save_figure(
        plot_votes(
            table,
            pairwise=pair,
            labels=labels,
            title="The paper's Table 2 (100 participants per animation)",
        ),
        ctx.out / "table2_votes",
    )
    return paths


def _fig13(ctx: _Context) -> list[Path]:
    from . import frames as fr
    from .load import load_responses, pose_choices
    from .plots import plot_frame_histograms, save_figure

    labels = _labels()
    if ctx.source is not None:
        df = load_responses(ctx.source, include_simulated=ctx.include_simulated)
        title = None
    else:
        from .simulate import paper_design, simulate_participants, simulated_rows

        design = paper_design()
        df = load_responses(
            simulated_rows(simulate_participants(design, 100, seed=0)), include_simulated=True
        )
        title = (
            "SIMULATED participants (100, observer model of analysis.simulate on the "
            "paper's design) — not study data"
        )
    pose = pose_choices(df)
    if pose.empty:
        raise FigureUnavailable("no pose-task responses")
    scenes = fr.scene_frames_from_rows(
        pose, extra={s: {"title": labels.get(s)} for s in pose["scene"].unique()}
    )
    fig = plot_frame_histograms(pose, scenes)
    if title:
        fig.suptitle(title + "\n▼ = the algorithm's pick", fontsize=9, color="#B00000")
    return save_figure(fig, ctx.out / "fig13_frame_histograms")


def measure_table1(
    *,
    repeats: int = 3,
    data_dir: str | Path | None = None,
    progress: bool = False,
    scenes: Iterable[str] | None = None,
) -> pd.DataFrame:
    """Time our pose and view selection on the paper-analogue clips (Table 1).

    Runs ``snapcore.pipeline.take_snapshot`` ``repeats`` times per clip and takes the
    median of each step's time from its ``timings_s``.

    Returns
    -------
    DataFrame
        ``scene``, ``clip``, ``frames``, ``joints`` (all characters), ``ours_pose_s``
        (pose stage), ``ours_view_s`` (PMA view), ``ours_motion_area_s`` and
        ``ours_viewpoint_entropy_s`` (the baselines' views), ``paper_frames``,
        ``paper_joints``, ``paper_pose_s``, ``paper_view_s``, ``note``. A stage the
        pipeline did not run is NaN.
    """
    from snapcore.pipeline import take_snapshot as take
    from snapcore.select.pose_methods import PoseParams

    paper = paper_table1().set_index("scene")
    analogues = paper_analogues().set_index("scene")
    rows = []
    for sid in scenes or list(analogues.index):
        sc = load_analogue(sid, data_dir=data_dir)
        times: dict[str, list[float]] = {
            k: [] for k in ("pose", "view", "motion_area", "viewpoint_entropy")
        }
        for _ in range(repeats):
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                snap = take(sc, pose=PoseParams(pose_method="paper"))
            for k, v in _timings(snap).items():
                times[k].append(v)
        p = paper.loc[sid] if sid in paper.index else None
        rows.append(
            {
                "scene": sid,
                "clip": "; ".join(analogues.loc[sid, "files"]),
                "frames": sc.n_frames,
                "joints": sum(c.n_joints for c in sc.characters),
                "ours_pose_s": _median(times["pose"]),
                "ours_view_s": _median(times["view"]),
                "ours_motion_area_s": _median(times["motion_area"]),
                "ours_viewpoint_entropy_s": _median(times["viewpoint_entropy"]),
                "paper_frames": None if p is None else int(p["frames"]),
                "paper_joints": None if p is None else int(p["joints"]),
                "paper_pose_s": None if p is None else float(p["pose_selection_s"]),
                "paper_view_s": None if p is None else float(p["viewpoint_selection_s"]),
                "note": analogues.loc[sid, "note"],
            }
        )
        if progress:
            import click

            click.echo(
                f"table1: {sid}: pose {rows[-1]['ours_pose_s']:.3f} s, "
                f"view {rows[-1]['ours_view_s']:.3f} s",
                err=True,
            )
    return pd.DataFrame(rows)


def _median(values: ArrayLike) -> float:
    """Median of the finite values; NaN (no warning) when a stage never ran."""
    v = np.asarray(values, dtype=float)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else float("nan")


def _timings(snap: Snapshot) -> dict:
    """Pose and view seconds from a snapshot's ``timings_s`` (dict or attribute).

    The pipeline reports each stage under its own key (``pose`` for the whole pose stage,
    its parts ``contacts``/``local``/...; the view stage ``view`` or ``view_*`` parts).
    """
    t = snap.get("timings_s") if isinstance(snap, dict) else getattr(snap, "timings_s", None)
    t = dict(t or {})
    pose = t.get("pose", np.nan)
    view = t.get("view")
    if view is None:
        parts = [v for k, v in t.items() if k.startswith("view_")]
        view = sum(parts) if parts else np.nan
    return {
        "pose": float(pose),
        "view": float(view),
        "motion_area": float(t.get("motion_area", np.nan)),
        "viewpoint_entropy": float(t.get("viewpoint_entropy", np.nan)),
    }


def _table1(ctx: _Context) -> list[Path]:
    from .tables import write_table

    t = measure_table1(repeats=ctx.repeats, data_dir=ctx.data_dir, progress=ctx.progress)
    return write_table(
        t,
        ctx.out / "table1",
        caption="Selection time, seconds: ours (this machine, median of "
        f"{ctx.repeats} runs) beside the paper's (Xeon W3680). Clips "
        "are analogues of the paper's animations, not the same data.",
    )


def _figure_paths(fig: Figure, stem: Path) -> list[Path]:
    from .plots import save_figure

    return save_figure(fig, stem)


def _fig5(ctx: _Context) -> list[Path]:
    from snapcore.render.entropy_plot import plot_strip

    from .plots import _plt

    labels = _labels()
    ids, skipped = [], []
    for sid in paper_analogues()["scene"]:
        try:
            ctx.snapshot(sid)
            ids.append(sid)
        except FigureUnavailable as err:
            skipped.append(f"{sid} ({err})")
    if not ids:
        raise FigureUnavailable("no paper-analogue clip could be loaded: " + "; ".join(skipped))
    plt = _plt()
    fig, axes = plt.subplots(
        len(ids), 1, figsize=(13, 2.5 * len(ids)), layout="constrained", squeeze=False
    )
    for ax, sid in zip(axes[:, 0], ids, strict=True):
        snap = ctx.snapshot(sid)
        plot_strip(snap, strip=8, ax=ax)
        ax.set_title(
            f"{labels.get(sid, sid)} — stand-in clip {_clip_name(sid)}: selected "
            f"frame {snap.source_frame}",
            fontsize=9,
            loc="left",
        )
    fig.suptitle(
        "Pose entropy along each animation (brighter = more informative; "
        "#1-#3 = the selected poses)",
        fontsize=11,
    )
    return _figure_paths(fig, ctx.out / "fig5_pose_entropy")


def _fig6(ctx: _Context) -> list[Path]:
    from snapcore.render.entropy_plot import plot_curves

    snap = ctx.snapshot(FEATURE_SCENE)
    fig = plot_curves(snap)
    fig.set_size_inches(10, 4.5)
    bottom = fig.axes[-1]
    bottom.set_xlabel("time (s)")
    if bottom.get_legend() is not None:  # keep the #1 peak's label clear of the legend
        bottom.legend(loc="upper right", fontsize=8, framealpha=0.8)
    fig.tight_layout(rect=(0, 0, 1, 0.94))  # leave room for the title
    fig.suptitle(
        f"Local and global pose entropy of the dance ({_clip_name(FEATURE_SCENE)})", fontsize=10
    )
    return _figure_paths(fig, ctx.out / "fig6_local_global_entropy")


def _clip_name(sid: str) -> str:
    """The stand-in clip's name for titles, with its caveat (e.g. "one boxer only")."""
    row = paper_analogues().set_index("scene").loc[sid]
    name = " + ".join(Path(f).stem for f in row["files"])
    return f"{name}, {row['caveat']}" if row["caveat"] else name


def snapshot_views(snap: Snapshot) -> dict:
    """The three methods' view directions of a snapshot, in the paper's order.

    Parameters
    ----------
    snap : snapcore.pipeline.Snapshot
        A snapshot taken with the view stage and the baselines.

    Returns
    -------
    dict of ViewMethod to ndarray of shape (3,)
        :attr:`Snapshot.views` for each of :data:`~snapcore.select.view_methods.VIEW_METHODS`.

    Raises
    ------
    FigureUnavailable
        Naming the views the snapshot lacks (taken without the view stage or without
        the baselines).
    """
    views = snap.views
    missing = [m for m in VIEW_METHODS if m not in views]
    if missing:
        raise FigureUnavailable(
            f"the snapshot has no {', '.join(missing)} view (take it with "
            "the view stage and the baselines)"
        )
    return {m: views[m] for m in VIEW_METHODS}


def _fig8_10(ctx: _Context) -> list[Path]:
    from snapcore.render.composites import compare_views

    from .plots import _plt

    labels = _labels()
    images, names, skipped = [], [], []
    for sid in paper_analogues()["scene"]:
        try:
            snap = ctx.snapshot(sid)
        except FigureUnavailable as err:
            skipped.append(f"{sid} ({err})")
            continue
        views = snapshot_views(snap)
        img = compare_views(
            snap.scene,
            snap.source_frame,
            {m.panel: v for m, v in views.items()},
            title=f"{labels.get(sid, sid)} ({_clip_name(sid)}), frame {snap.source_frame}",
        )
        images.append(np.asarray(img))
        names.append(sid)
    if not images:
        raise FigureUnavailable("no clip could be rendered: " + "; ".join(skipped))
    plt = _plt()
    h, w = images[0].shape[:2]
    fig, axes = plt.subplots(
        len(images), 1, figsize=(12, 12 * h / w * len(images)), squeeze=False, layout="constrained"
    )
    for ax, img in zip(axes[:, 0], images, strict=True):
        ax.imshow(img)
        ax.set_axis_off()
    fig.suptitle("The selected pose from the view of each method", fontsize=11)
    paths = _figure_paths(fig, ctx.out / "fig8-10_views")
    from snapcore.render.renderer import save_png

    for sid, img in zip(names, images, strict=True):
        path = ctx.out / f"fig8-10_{sid}.png"
        save_png(img, path)
        paths.append(path)
    return paths


def _fig11(ctx: _Context) -> list[Path]:
    from snapcore.relief.scene import relief_comparison_figure as relief_figure

    snap = ctx.snapshot(FEATURE_SCENE)
    views = snapshot_views(snap)
    fig = relief_figure(
        snap.scene,
        snap.source_frame,
        {m.panel: v for m, v in views.items()},
        title=f"Reliefs of the dance pose (frame {snap.source_frame}, "
        f"{_clip_name(FEATURE_SCENE)}) from each method's view",
    )
    return _figure_paths(fig, ctx.out / "fig11_reliefs")


_MAKERS = {
    "table2": _table2,
    "fig13": _fig13,
    "table1": _table1,
    "fig5": _fig5,
    "fig6": _fig6,
    "fig8-10": _fig8_10,
    "fig11": _fig11,
}


def make_figures(
    out_dir: str | Path,
    *,
    names: Iterable[str] = FIGURES,
    source: ResponseSource | None = None,
    include_simulated: bool = False,
    repeats: int = 3,
    progress: bool = True,
    data_dir: str | Path | None = None,
) -> dict:
    """Make the named figures in ``out_dir``.

    Returns
    -------
    dict
        name → ``(paths, reason)``: the files written, or ``[]`` and why it was skipped.
    """
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    ctx = _Context(
        out=out,
        source=source,
        include_simulated=include_simulated,
        repeats=repeats,
        progress=progress,
        data_dir=data_dir,
    )
    results = {}
    for name in names:
        t0 = time.perf_counter()
        try:
            results[name] = (_MAKERS[name](ctx), "")
            ctx.log(f"{name}: done in {time.perf_counter() - t0:.1f} s")
        except FigureUnavailable as err:
            results[name] = ([], str(err))
    return results
