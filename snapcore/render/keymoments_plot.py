"""The key-moment timeline figure: one row per scene, intervals shaded, picks marked."""

from __future__ import annotations

__all__ = ["plot_keymoment_timelines"]

#: Marker per method (cycled for others).
_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*")


def plot_keymoment_timelines(doc: dict, *, ax=None, extra: dict | None = None):
    """Timelines of annotated scenes with each selector's picks.

    Parameters
    ----------
    doc : dict
        An evaluation document (:func:`snapcore.select.keymoments.run_keymoments`).
    ax : matplotlib Axes, optional
        Where to draw; a new figure when None.
    extra : dict, optional
        ``{scene: [source frames]}`` drawn as a grey tick histogram under each row (the
        people's chosen frames in ``snapshot analyze``).

    Returns
    -------
    matplotlib.figure.Figure
        Time (s from the clip's first analysed frame, each row over its own clip
        length) runs right; the widened intervals are light, the intervals dark; the
        top pick of each method is a filled marker, picks 2..k hollow.
    """
    import matplotlib

    matplotlib.use("Agg", force=False)
    import matplotlib.pyplot as plt

    scenes = doc["scenes"]
    methods = doc["methods"]
    n = len(scenes)
    if ax is None:
        fig, ax = plt.subplots(figsize=(9, 0.75 * n + 1.4))
    else:
        fig = ax.figure
    colors = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    widen = doc.get("widen_s", 0.1)
    by = {(r["scene"], r["method"]): r for r in doc["rows"]}
    for y, sc in enumerate(scenes):
        fps, first = sc["fps"], sc["first_frame"]
        dur = (sc["last_frame"] - first) / fps
        ax.plot([0, 1], [y, y], color="0.7", lw=1, zorder=1)
        for a, b in sc["intervals"]:
            t0, t1 = (a - first) / fps / dur, (b - first) / fps / dur
            w = widen / dur
            ax.fill_between([t0 - w, t1 + w], y - 0.32, y + 0.32, color="C2", alpha=0.15, lw=0)
            ax.fill_between([t0, t1], y - 0.32, y + 0.32, color="C2", alpha=0.35, lw=0)
        for mi, m in enumerate(methods):
            r = by.get((sc["scene"], m))
            if not r:
                continue
            off = (mi - (len(methods) - 1) / 2) * 0.5 / max(len(methods), 1)
            ts = [(f - first) / fps / dur for f in r["frames"]]
            mk, col = _MARKERS[mi % len(_MARKERS)], colors[mi % len(colors)]
            ax.plot(ts[:1], [y + off], mk, color=col, ms=7, zorder=3, label=m if y == 0 else None)
            ax.plot(ts[1:], [y + off] * len(ts[1:]), mk, mfc="none", color=col, ms=5, zorder=3)
        if extra and sc["scene"] in extra and dur > 0:
            xs = [(f - first) / fps / dur for f in extra[sc["scene"]]]
            ax.plot(
                xs,
                [y - 0.4] * len(xs),
                "|",
                color="0.3",
                ms=6,
                alpha=0.5,
                zorder=2,
                label="people" if y == 0 else None,
            )
    ax.set_yticks(range(n))
    ax.set_yticklabels(
        [f"{s['scene']} ({(s['last_frame'] - s['first_frame']) / s['fps']:.1f} s)" for s in scenes]
    )
    ax.set_ylim(n - 0.5, -0.5)
    ax.set_xlim(-0.02, 1.02)
    ax.set_xlabel("time in the clip (fraction of its length)")
    ax.set_title(
        "key moments (green; light: widened for hits) and each selector's picks "
        "(filled: top pick, hollow: picks 2..k)",
        fontsize=9,
    )
    ax.legend(
        loc="upper center",
        bbox_to_anchor=(0.5, -0.12 - 0.3 / max(n, 1)),
        ncol=min(len(methods) + 1, 8),
        frameon=False,
        fontsize=8,
    )
    fig.tight_layout()
    return fig
