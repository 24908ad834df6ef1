"""Figures of pose entropy: the curves over time (paper Fig. 6) and a film strip (Fig. 5).

:func:`plot_entropy` draws, for a :class:`~snapcore.pipeline.Snapshot`,

- the local, global and total pose entropy over time with the top-k peaks marked,
- the interaction events as ticks per character and object (onsets and releases
  over light bars for the interactions themselves),
- a film strip of stick figures seen from the side, coloured by total entropy (the
  brighter, the more informative, as in Fig. 5); the top-k poses bold and labelled.

Matplotlib with the Agg backend, imported lazily; every function returns the figure.
"""

from __future__ import annotations

import numpy as np

from snapcore.motion.facing import character_facing

__all__ = ["plot_entropy", "plot_curves", "plot_events", "plot_strip", "side_axis", "STRIP_CMAP"]

#: Colour map of the film strip: dark = little information, bright = much (Fig. 5).
STRIP_CMAP = "viridis"
_TERM_COLOURS = {"local": "#1f77b4", "global": "#ff7f0e", "total": "#222222"}
_CHAR_STYLES = ("-", (0, (4, 2)), (0, (1, 1.5)), "-.")  # solid, dashed, dotted, dash-dot


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() not in ("agg", "pdf", "svg", "ps", "cairo"):
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def plot_curves(snapshot, *, axes=None):
    """The method's terms (top axis) and its total (bottom axis) over time.

    Parameters
    ----------
    snapshot : Snapshot
    axes : pair of Axes, optional
        Where to draw; a new figure with two rows otherwise.

    Returns
    -------
    Figure
    """
    plt = _pyplot()
    if axes is None:
        fig, axes = plt.subplots(2, 1, figsize=(10, 4.5), sharex=True)
    ax_terms, ax_total = axes
    sc = snapshot.pose.scores
    t = np.arange(sc.n_frames) / sc.fps
    paper = sc.method == "paper"
    # the paper's terms keep their entropy names; other methods' terms are named after
    # what they hold (PoseScores.terms), in the method's own unit
    colours = [_TERM_COLOURS["local"], _TERM_COLOURS["global"], "#27ae60", "#8e44ad", "#17becf"]
    for k, (name, values) in enumerate(sc.terms.items()):
        label = (
            {"local": "local $w H^*_{local}$", "global": "global $w H^*_{global}$"}.get(name, name)
            if paper
            else name
        )
        ax_terms.plot(t, values, color=colours[k % len(colours)], lw=1.0, alpha=0.9, label=label)
    ax_terms.set_ylabel("normalised\nentropy" if paper else f"terms\n({sc.unit})")
    ax_terms.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8, frameon=False)
    ax_total.plot(
        t, sc.total, color=_TERM_COLOURS["total"], lw=1.1, label="total = " + " + ".join(sc.terms)
    )
    ent = sc
    top = max(float(ent.total.max()), 1e-9)
    ax_total.set_ylim(-0.03 * top, 1.45 * top)  # room above the curve for the peak labels
    ax_total.set_ylabel(sc.label)
    for rank, i in enumerate(snapshot.indices, start=1):
        for ax in (ax_terms, ax_total):
            ax.axvline(t[i], color="#c0392b", lw=0.8, ls="--", alpha=0.8, zorder=0)
        ax_total.plot(t[i], ent.total[i], "o", color="#c0392b", ms=5, zorder=3)
        # one row per rank above the curve, beside the peak's dashed line: close peaks
        # (0.3 s apart at the default separation) do not print over each other or the curve
        late = t.size > 1 and t[i] > t[0] + 0.75 * (t[-1] - t[0])
        ax_total.text(
            t[i],
            top * (1.37 - 0.11 * (rank - 1)),
            f"#{rank} frame {snapshot.scene.source_frame(i)}" + (" " if late else ""),
            ha="right" if late else "left",
            va="center",
            fontsize=8,
            color="#c0392b",
            zorder=4,
            bbox={"boxstyle": "square,pad=0.1", "fc": "white", "ec": "none", "alpha": 0.8},
        )
    ax_total.legend(loc="upper left", bbox_to_anchor=(1.005, 1.0), fontsize=8, frameon=False)
    for ax in (ax_terms, ax_total):
        ax.grid(alpha=0.25)
        ax.set_xlim(t[0] if t.size else 0, t[-1] if t.size > 1 else 1.0)
    return ax_total.figure


def plot_events(snapshot, *, ax=None):
    """Interaction events per (character, object): bars for interactions, ticks for
    their onsets and releases (the frames the ``transitions`` mode scores).

    Returns
    -------
    Figure
    """
    plt = _pyplot()
    if ax is None:
        _, ax = plt.subplots(figsize=(10, 1.8))
    scene = snapshot.scene
    inter = snapshot.pose.scores.interactions
    fps = float(scene.fps)
    n_f = scene.n_frames
    rows: dict[tuple[int, str], list] = {}
    for e in inter.events:
        rows.setdefault((e.character, e.object), []).append(e)
    labels = []
    cmap = plt.get_cmap("tab10")
    for r, ((ci, obj), evs) in enumerate(sorted(rows.items(), key=lambda kv: kv[0])):
        who = scene.characters[ci].name
        labels.append(f"{who} → {obj}" if scene.n_characters > 1 else f"→ {obj}")
        colour = cmap(r % 10)
        bars = [(e.start / fps, (e.end + 1 - e.start) / fps) for e in evs]
        ax.broken_barh(bars, (r - 0.3, 0.6), facecolors=colour, alpha=0.12, lw=0)
        on = [e.start / fps for e in evs if e.start > 0]
        off = [e.end / fps for e in evs if e.end < n_f - 1]
        ax.vlines(on, r - 0.38, r + 0.38, color=colour, lw=0.9)
        ax.vlines(off, r - 0.38, r + 0.38, color=colour, lw=0.9, alpha=0.55)
    for i in snapshot.indices:
        ax.axvline(i / fps, color="#c0392b", lw=0.8, ls="--", alpha=0.8, zorder=0)
    ax.set_yticks(range(len(labels)), labels, fontsize=7)
    ax.set_ylim(-0.7, max(len(labels), 1) - 0.3)
    ax.invert_yaxis()
    ax.set_xlim(0, max(scene.duration, 1.0 / fps))
    ax.set_xlabel("time (s)")
    if not labels:
        ax.text(
            0.5,
            0.5,
            "no interaction events",
            transform=ax.transAxes,
            ha="center",
            va="center",
            fontsize=9,
            color="0.4",
        )
        ax.set_yticks([])
    ax.grid(axis="x", alpha=0.25)
    return ax.figure


def side_axis(scene, index: int) -> np.ndarray:
    """Horizontal screen axis (unit, world) for a side view of ``scene`` at internal
    index ``index``.

    Two or more characters: the direction from the first character's root to the
    second's, so both stand side by side. One character: its facing (hips and
    shoulders, :mod:`snapcore.motion.facing`) averaged over a quarter second, so it faces
    screen-right. Falls back to the principal horizontal direction of the pose.
    """
    chars = scene.characters
    if len(chars) > 1:
        d = chars[1].positions[index, 0] - chars[0].positions[index, 0]
        d = np.array([d[0], 0.0, d[2]])
        if np.linalg.norm(d) > 0.15:
            return d / np.linalg.norm(d)

    half = max(1, int(0.125 * scene.fps))
    a, b = max(0, index - half), min(scene.n_frames, index + half + 1)
    f = np.zeros(3)
    for c in chars:
        f += character_facing(c.positions[a:b], c.joint_names, c.parents).sum(axis=0)
    if np.linalg.norm(f) > 1e-6:
        return f / np.linalg.norm(f)
    pts = np.concatenate([c.positions[index] for c in chars])[:, [0, 2]]
    pts = pts - pts.mean(axis=0)
    _, _, vt = np.linalg.svd(pts, full_matrices=False)
    return np.array([vt[0, 0], 0.0, vt[0, 1]])


def _strip_frames(snapshot, strip: int) -> list[int]:
    n_f = snapshot.scene.n_frames
    even = np.linspace(0, n_f - 1, strip).round().astype(int).tolist() if strip > 0 else []
    top = snapshot.indices
    # Drop evenly spaced frames that would crowd a top pose.
    gap = max(1, n_f // (3 * max(strip, 1)))
    even = [f for f in even if all(abs(f - i) >= gap for i in top)]
    return sorted(set(even) | set(top))


def plot_strip(snapshot, *, strip: int = 8, ax=None):
    """Film strip: stick figures seen from the side, coloured by total entropy.

    Parameters
    ----------
    snapshot : Snapshot
    strip : int
        Evenly spaced poses shown besides the top-k.
    ax : Axes, optional

    Returns
    -------
    Figure

    Notes
    -----
    Each pose sits in its own cell, centred on the characters' mean root position,
    seen along the horizontal axis of :func:`side_axis` (limbs on the far side drawn
    fainter). Characters differ by line style (solid, dashed, ...).
    """
    plt = _pyplot()
    from matplotlib import cm, colors

    if ax is None:
        _, ax = plt.subplots(figsize=(12, 2.6))
    scene = snapshot.scene
    ent = snapshot.pose.scores
    frames = _strip_frames(snapshot, strip)
    norm = colors.Normalize(vmin=0.0, vmax=max(float(ent.total.max()), 1e-9))
    cmap = plt.get_cmap(STRIP_CMAP)
    rank = {i: r for r, i in enumerate(snapshot.indices, start=1)}
    height = max(c.height for c in scene.characters)
    up = np.array([0.0, 1.0, 0.0])
    # First the 2-D figures (screen x relative to the pose centre, height, depth), then
    # cells as wide as each pose needs, so distant partners do not overlap neighbours.
    drawn = []
    for i in frames:
        u = side_axis(scene, i)
        v = np.cross(u, up)  # towards the viewer
        centre = np.mean([c.positions[i, 0] for c in scene.characters], axis=0)
        figs = []
        for c in scene.characters:
            p = c.positions[i] - centre
            figs.append((p @ u, c.positions[i, :, 1] - scene.ground, p @ v))
        lo = min(float(f[0].min()) for f in figs)
        hi = max(float(f[0].max()) for f in figs)
        drawn.append((i, figs, lo, hi))
    margin = 0.3 * height
    x0: list[float] = []  # left edge of each drawn frame's figures, metres
    cursor = 0.0
    for k, (_, _, lo, hi) in enumerate(drawn):
        if k:
            cursor = max(cursor - lo + margin, x0[-1] + 0.6 * height)  # room for the labels
        x0.append(cursor)
        cursor += hi
    for k, (i, figs, _, _) in enumerate(drawn):
        colour = cmap(norm(ent.total[i]))
        bold = i in rank
        for ci, (sx, sy, depth) in enumerate(figs):
            c = scene.characters[ci]
            sx = sx + x0[k]
            span = max(float(np.ptp(depth)), 1e-6)
            for a, b in c.skeleton.links:
                near = 0.5 * (depth[a] + depth[b] - 2 * depth.min()) / span  # 0 far .. 1 near
                ax.plot(
                    [sx[a], sx[b]],
                    [sy[a], sy[b]],
                    color=colour,
                    lw=(2.6 if bold else 1.4) * (0.7 + 0.3 * near),
                    alpha=0.45 + 0.55 * near,
                    ls=_CHAR_STYLES[ci % len(_CHAR_STYLES)],
                    solid_capstyle="round",
                    zorder=2 + near,
                )
            head = int(np.argmax(sy))
            ax.plot(sx[head], sy[head], "o", color=colour, ms=4 if bold else 3, zorder=4)
        ax.text(
            x0[k],
            -0.08 * height,
            f"{scene.source_frame(i)}",
            ha="center",
            va="top",
            fontsize=7,
            fontweight="bold" if bold else "normal",
            color="#c0392b" if bold else "0.3",
        )
        if bold:  # the rank above the figure, where there is room
            top = max(float(f[1].max()) for f in figs)
            ax.text(
                x0[k],
                top + 0.06 * height,
                f"#{rank[i]}",
                ha="center",
                va="bottom",
                fontsize=9,
                fontweight="bold",
                color="#c0392b",
            )
        ax.text(
            x0[k],
            -0.2 * height,
            f"{i / ent.fps:.2f} s",
            ha="center",
            va="top",
            fontsize=6,
            color="0.45",
        )
    # what the numbers under the poses are (short, so close poses' labels fit)
    ax.text(
        drawn[0][2] - 0.5 * margin,
        -0.08 * height,
        "frame ",
        ha="right",
        va="top",
        fontsize=7,
        color="0.3",
    )
    ax.text(
        drawn[0][2] - 0.5 * margin,
        -0.2 * height,
        "time ",
        ha="right",
        va="top",
        fontsize=6,
        color="0.45",
    )
    ax.axhline(0.0, color="0.6", lw=0.8, zorder=0)
    ax.set_xlim(drawn[0][2] - 0.5 * margin, cursor + 0.5 * margin)
    ax.set_ylim(-0.3 * height, 1.25 * height)
    # equal scale, with whichever range is short widened to fill the axes (limits that
    # may move, not fixed ones): the strip spans the figure's width
    ax.set_autoscale_on(True)
    ax.set_aspect("equal", adjustable="datalim")
    ax.axis("off")
    sm = cm.ScalarMappable(norm=norm, cmap=cmap)
    cb = ax.figure.colorbar(sm, ax=ax, fraction=0.02, pad=0.01, shrink=0.8)
    cb.set_label(ent.label, fontsize=8)
    cb.ax.tick_params(labelsize=7)
    if scene.n_characters > 1:
        from matplotlib.lines import Line2D

        handles = [
            Line2D([], [], color="0.3", ls=_CHAR_STYLES[ci % len(_CHAR_STYLES)], label=c.name)
            for ci, c in enumerate(scene.characters)
        ]
        ax.legend(
            handles=handles,
            loc="upper left",
            fontsize=7,
            frameon=False,
            bbox_to_anchor=(0.0, 1.08),
            ncol=len(handles),
        )
    return ax.figure


def plot_entropy(snapshot, *, strip: int = 8, title: str | None = None):
    """The whole figure: curves, events and film strip (see the module docstring).

    Parameters
    ----------
    snapshot : Snapshot
    strip : int
        Evenly spaced poses in the film strip besides the top-k.
    title : str, optional
        Default: scene name, frames, fps and the chosen frame.

    Returns
    -------
    Figure
    """
    plt = _pyplot()
    scene = snapshot.scene
    n_rows = max(
        1, len({(e.character, e.object) for e in snapshot.pose.scores.interactions.events})
    )
    ev_h = 0.45 + 0.22 * n_rows
    fig = plt.figure(figsize=(12, 6.4 + ev_h), layout="constrained")
    grid = fig.add_gridspec(4, 1, height_ratios=[1.5, 1.5, ev_h, 2.4])
    ax_terms = fig.add_subplot(grid[0])
    ax_total = fig.add_subplot(grid[1], sharex=ax_terms)
    ax_events = fig.add_subplot(grid[2], sharex=ax_terms)
    ax_strip = fig.add_subplot(grid[3])
    plot_curves(snapshot, axes=(ax_terms, ax_total))
    plt.setp(ax_terms.get_xticklabels(), visible=False)
    plt.setp(ax_total.get_xticklabels(), visible=False)
    plot_events(snapshot, ax=ax_events)
    plot_strip(snapshot, strip=strip, ax=ax_strip)
    if title is None:
        title = (
            f"{scene.name}: {scene.n_frames} frames at {scene.fps:g} fps, "
            f"selected frame {snapshot.source_frame} (source numbering)"
        )
    fig.suptitle(title, fontsize=11)
    return fig
