"""Figures of the study's data: votes (Table 2), strengths, frame histograms (Fig. 13),
distances to the algorithm and baselines, power curves.

Every function draws with matplotlib (Agg backend, imported lazily), takes the tidy
frames made by :mod:`analysis.votes`, :mod:`analysis.frames` and :mod:`analysis.power`,
and returns the :class:`matplotlib.figure.Figure` (``ax=`` where one axes suffices).
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from snapcore.select.view_methods import ViewMethod

__all__ = [
    "METHOD_COLORS",
    "PREDICTOR_STYLES",
    "plot_votes",
    "plot_strengths",
    "plot_frame_histograms",
    "plot_error_distributions",
    "plot_power_curve",
    "save_figure",
]

#: One colour per method, the same in every figure (colour-blind safe, Okabe–Ito).
METHOD_COLORS = {
    ViewMethod.OURS: "#D55E00",
    ViewMethod.VIEWPOINT_ENTROPY: "#0072B2",
    ViewMethod.MOTION_AREA: "#009E73",
}
#: How each frame predictor is marked: (colour, line style, label).
PREDICTOR_STYLES = {
    "algorithm": ("#D55E00", "-", "algorithm's pick"),
    "middle": ("#555555", ":", "middle frame"),
    "fastest": ("#0072B2", "--", "fastest frame"),
    "stretch": ("#009E73", "-.", "most stretched pose"),
    "uniform_random": ("#999999", (0, (1, 3)), "uniform random frame"),
}


#: TrueType (Type 42) fonts in PDF/PS: publishers' checks (ACM, IEEE PDF eXpress) reject
#: matplotlib's default Type 3 fonts.
PDF_FONTS = {"pdf.fonttype": 42, "ps.fonttype": 42}


def _method_label(method) -> str:
    """A method's legend entry: its panel title (:attr:`ViewMethod.panel`), or the name."""
    return ViewMethod(method).panel if method in set(ViewMethod) else str(method)


def _plt():
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    return plt


def _figure_axes(ax, figsize):
    """``(figure, axes)``: the given axes and its figure, or a new constrained figure."""
    if ax is not None:
        return ax.figure, ax
    return _plt().subplots(figsize=figsize, layout="constrained")


def _grid(n: int, *, ncols: int = 3, size=(4.2, 2.9)):
    plt = _plt()
    ncols = max(1, min(ncols, n))
    nrows = max(1, math.ceil(n / ncols))
    fig, axes = plt.subplots(
        nrows,
        ncols,
        figsize=(size[0] * ncols, size[1] * nrows),
        squeeze=False,
        layout="constrained",
    )
    for ax in axes.flat[n:]:
        ax.set_visible(False)
    return fig, list(axes.flat[:n])


def save_figure(fig, stem, *, formats=("png", "pdf"), dpi: int = 150) -> list:
    """Write ``fig`` as ``<stem>.png`` and ``<stem>.pdf``; close it; return the paths.

    The figure is laid out once, by the first format written; the others reuse it.
    """
    from pathlib import Path

    stem = Path(stem)
    stem.parent.mkdir(parents=True, exist_ok=True)
    out = []
    with _plt().rc_context(PDF_FONTS):
        for i, fmt in enumerate(formats):
            p = stem.with_suffix(f".{fmt}")
            fig.savefig(p, dpi=dpi)
            out.append(p)
            if i == 0:
                # The first save laid the figure out; the others keep that layout rather
                # than solving the constrained layout again (a fifth of a report's
                # drawing time, issue 35). Positions are in figure units, so the PDF is
                # laid out as the PNG.
                fig.set_layout_engine("none")
    _plt().close(fig)
    return out


def plot_votes(
    table: pd.DataFrame,
    *,
    pairwise: pd.DataFrame | None = None,
    labels: dict | None = None,
    ax=None,
    title: str | None = None,
):
    """Grouped bars: vote share per method per scene with its 95% interval (Table 2).

    Parameters
    ----------
    table : DataFrame
        :func:`analysis.votes.vote_table` output.
    pairwise : DataFrame, optional
        :func:`analysis.votes.ours_vs_baselines` output: a star above ours' bar for each
        baseline it beats significantly (Holm-adjusted).
    labels : dict, optional
        Scene id → display name.
    """
    labels = labels or {}
    scenes = list(dict.fromkeys(table["scene"]))
    methods = list(dict.fromkeys(table["method"]))
    fig, ax = _figure_axes(ax, (max(6.0, 1.5 * len(scenes) + 2), 3.8))
    width = 0.8 / len(methods)
    x = np.arange(len(scenes))
    for j, m in enumerate(methods):
        t = table[table["method"] == m].set_index("scene").reindex(scenes)
        share = t["share"].to_numpy(dtype=float)
        err = np.vstack([share - t["ci_low"].to_numpy(float), t["ci_high"].to_numpy(float) - share])
        xs = x + (j - (len(methods) - 1) / 2) * width
        ax.bar(xs, share, width, color=METHOD_COLORS.get(m), label=_method_label(m))
        ax.errorbar(xs, share, yerr=err, fmt="none", ecolor="black", elinewidth=0.8, capsize=2)
        for xi, v, hi in zip(xs, t["votes"], t["ci_high"].to_numpy(float), strict=True):
            ax.text(xi, hi + 0.01, f"{int(v)}", ha="center", va="bottom", fontsize=7)
    if pairwise is not None and "ours" in methods:
        j = methods.index("ours")
        for i, s in enumerate(scenes):
            won = pairwise[(pairwise["scene"] == s) & (pairwise["verdict"] == "ours preferred")]
            if len(won):
                top = float(
                    table[(table["scene"] == s) & (table["method"] == "ours")]["ci_high"].iloc[0]
                )
                ax.text(
                    x[i] + (j - (len(methods) - 1) / 2) * width,
                    top + 0.05,
                    "*" * len(won),
                    ha="center",
                    va="bottom",
                    fontsize=11,
                )
    ax.set_xticks(x, [labels.get(s, s) for s in scenes], rotation=20, ha="right")
    ax.set_ylabel("share of votes (95% Wilson CI)")
    ax.set_ylim(0, 1)
    ax.axhline(1 / len(methods), color="grey", lw=0.8, ls=":", label="no preference")
    ax.legend(
        fontsize=8,
        ncols=len(methods) + 1,
        loc="lower center",
        bbox_to_anchor=(0.5, 1.0),
        frameon=False,
    )
    note = (
        "* ours beats one baseline, ** both (exact binomial, Holm-adjusted, α = 0.05)"
        if pairwise is not None
        else ""
    )
    ax.set_title("\n".join(t for t in (title, note) if t), fontsize=9, pad=22)
    return fig


def plot_strengths(strengths: pd.DataFrame, *, labels: dict | None = None, ax=None):
    """Luce strengths (choice probability when all three are shown) with bootstrap CIs."""
    labels = labels or {}
    scenes = list(dict.fromkeys(strengths["scene"]))
    methods = list(dict.fromkeys(strengths["method"]))
    fig, ax = _figure_axes(ax, (max(6.0, 1.3 * len(scenes) + 2), 3.6))
    y = np.arange(len(scenes))[::-1]
    for j, m in enumerate(methods):
        t = strengths[strengths["method"] == m].set_index("scene").reindex(scenes)
        s = t["strength"].to_numpy(float)
        yy = y + (j - 1) * 0.22
        ax.errorbar(
            s,
            yy,
            xerr=np.vstack([s - t["ci_low"].to_numpy(float), t["ci_high"].to_numpy(float) - s]),
            fmt="o",
            color=METHOD_COLORS.get(m),
            label=_method_label(m),
            ms=4,
            capsize=2,
        )
    ax.set_yticks(y, [labels.get(s, s) for s in scenes])
    ax.axvline(1 / max(1, len(methods)), color="grey", lw=0.8, ls=":")
    ax.set_xlim(0, 1)
    ax.set_xlabel("Luce strength = P(chosen | all shown), 95% bootstrap CI")
    ax.legend(fontsize=8, loc="lower right", frameon=False)
    return fig


def plot_frame_histograms(
    pose: pd.DataFrame, scenes: dict, *, bins: int | None = None, show_baselines: bool = True
):
    """The paper's Fig. 13: per scene, the histogram of chosen frames, picks marked.

    Parameters
    ----------
    pose : DataFrame
        Pose-task rows.
    scenes : dict
        scene id → :class:`study_app.design.scenes.StudyScene`.
    show_baselines : bool
        Mark the baseline frames (middle, fastest, most stretched) too.
    """
    from .frames import frame_histogram, predictor_frames

    fig, axes = _grid(len(scenes))
    for ax, (sid, info) in zip(axes, scenes.items(), strict=True):
        counts, edges = frame_histogram(pose, info, bins=bins)
        ax.stairs(counts, edges, fill=True, color="#BBBBBB", edgecolor="#666666", lw=0.6)
        top = max(1, counts.max())
        preds = predictor_frames(info)
        others = [f for f in info.algorithm_frames if f != info.algorithm_frame]
        for k, extra in enumerate(others):
            ax.axvline(
                extra,
                color=PREDICTOR_STYLES["algorithm"][0],
                lw=0.8,
                ls=(0, (2, 2)),
                alpha=0.7,
                label="the algorithm's other top-k picks" if k == 0 else None,
            )
        for name, f in preds.items():
            if name != "algorithm" and not show_baselines:
                continue
            color, ls, label = PREDICTOR_STYLES[name]
            ax.axvline(f, color=color, ls=ls, lw=2.0 if name == "algorithm" else 1.2, label=label)
        ax.plot(
            [info.algorithm_frame],
            [top * 1.05],
            marker="v",
            color=PREDICTOR_STYLES["algorithm"][0],
            ms=8,
            clip_on=False,
        )
        n = int((pose["scene"] == sid).sum())
        ax.set_title(f"{info.title or sid}  (n = {n})", fontsize=9)
        ax.set_xlim(edges[0], edges[-1])
        ax.set_ylim(0, top * 1.12)
        ax.set_xlabel(f"motion frame ({info.fps:g} fps)", fontsize=8)
        ax.set_ylabel("participants", fontsize=8)
        ax.yaxis.get_major_locator().set_params(integer=True)
        ax.tick_params(labelsize=7)
        sec = ax.secondary_xaxis(
            "top",
            functions=(
                lambda f, i=info: (f - i.frame_offset) / i.fps,
                lambda s, i=info: s * i.fps + i.frame_offset,
            ),
        )
        sec.tick_params(labelsize=6)
        sec.set_xlabel("seconds into the clip", fontsize=7)
    _shared_legend(fig, axes)
    fig.suptitle("Chosen frames per animation; ▼ = the algorithm's pick", fontsize=10)
    return fig


def plot_error_distributions(
    distances: pd.DataFrame,
    scenes: dict,
    *,
    tolerances=(0.25, 0.5, 1.0),
    hits: pd.DataFrame | None = None,
):
    """Per scene, the cumulative distribution of |chosen − predictor| in seconds.

    Parameters
    ----------
    distances : DataFrame
        :func:`analysis.frames.frame_distances` output.
    hits : DataFrame, optional
        :func:`analysis.frames.hit_rates` output, for the uniform-random curve's
        expected hit rates at the tolerances (drawn as grey points).
    """
    fig, axes = _grid(len(scenes))
    for ax, sid in zip(axes, scenes, strict=True):
        d = distances[distances["scene"] == sid]
        xmax = 0.0
        for name, g in d.groupby("predictor", sort=False):
            x = np.sort(g["abs_error_s"].to_numpy(float))
            if x.size == 0:
                continue
            color, ls, label = PREDICTOR_STYLES.get(name, ("black", "-", name))
            ax.step(
                np.r_[0, x],
                np.r_[0, np.arange(1, x.size + 1) / x.size],
                where="post",
                color=color,
                ls=ls,
                lw=2.0 if name == "algorithm" else 1.2,
                label=label,
            )
            xmax = max(xmax, float(np.quantile(x, 0.9)))
        if hits is not None:
            u = hits[(hits["scene"] == sid) & (hits["predictor"] == "uniform_random")]
            if len(u):
                ys = [float(u[f"hit_{t:g}s"].iloc[0]) for t in tolerances]
                color, _, label = PREDICTOR_STYLES["uniform_random"]
                ax.plot(tolerances, ys, "s", color=color, ms=4, label=label)
        for t in tolerances:
            ax.axvline(t, color="grey", lw=0.5, ls=":")
        ax.set_xlim(0, max(1.5, xmax * 1.05))
        ax.set_ylim(0, 1)
        ax.set_title(scenes[sid].title or sid, fontsize=9)
        ax.set_xlabel("|chosen − predicted| (s)", fontsize=8)
        ax.set_ylabel("fraction of participants", fontsize=8)
        ax.tick_params(labelsize=7)
    _shared_legend(fig, axes)
    fig.suptitle("How close are people to each predictor? (dotted: ±0.25, 0.5, 1 s)", fontsize=10)
    return fig


def plot_power_curve(
    curve: pd.DataFrame,
    *,
    target: float = 0.8,
    title: str | None = None,
    n_needed: int | None = None,
    ax=None,
):
    """Power against participants (:func:`analysis.power.power_curve` output).

    ``n_needed`` (e.g. :func:`analysis.power.sample_size`'s ``n_stable``) is marked.
    """
    fig, ax = _figure_axes(ax, (6, 3.6))
    ax.plot(
        curve["n"],
        curve["power_pairwise"],
        color=METHOD_COLORS[ViewMethod.OURS],
        label="ours beats the baseline (exact binomial, corrected level)",
    )
    ax.plot(
        curve["n"],
        curve["power_chisquare"],
        color="#555555",
        ls="--",
        label="some preference among the three (chi-square, uncorrected)",
    )
    ax.axhline(target, color="grey", lw=0.8, ls=":")
    if n_needed is not None:
        ax.axvline(n_needed, color=METHOD_COLORS[ViewMethod.OURS], lw=0.8, ls=":")
        ax.annotate(
            f"{n_needed} participants",
            (n_needed, target),
            xytext=(6, -14),
            textcoords="offset points",
            fontsize=8,
            color=METHOD_COLORS[ViewMethod.OURS],
        )
    ax.set_ylim(0, 1)
    ax.set_xlabel("participants (votes per scene)")
    ax.set_ylabel("power")
    ax.legend(fontsize=8, frameon=False, loc="lower right")
    if title:
        ax.set_title(title, fontsize=9)
    return fig


def _shared_legend(fig, axes) -> None:
    """One legend under the panels: every style that appears in any of ``axes``, once."""
    if not axes:
        return
    handles, labels = [], []
    for ax in axes:
        for h, lab in zip(*ax.get_legend_handles_labels(), strict=True):
            if lab not in labels:
                handles.append(h)
                labels.append(lab)
    fig.legend(
        handles, labels, loc="outside lower center", ncols=len(labels), fontsize=8, frameon=False
    )
