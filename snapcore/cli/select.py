"""``snapshot select`` and ``snapshot plot-entropy``: the pose of a scene, and why."""

from __future__ import annotations

from pathlib import Path

import click

from snapcore.cli.common import (
    FiniteFloatRange,
    body_option,
    echo_json,
    output_callback,
    refuse_inputs,
    scene_arguments,
    scene_from_options,
)
from snapcore.render.bodies import DEFAULT_BODY, BodyKind
from snapcore.select.paper import EVENT_MODES
from snapcore.select.pose_methods import PaperOptionError, PoseParams
from snapcore.select.pose_selection import MIN_SEPARATION_S
from snapcore.select.signals import SMOOTH_S

__all__ = [
    "select",
    "plot_entropy",
    "pose_options",
    "pose_params_from_options",
    "snapshot_from_options",
    "format_snapshot",
]


def pose_options(f):
    """Decorate a command with the pose-selection options."""
    from snapcore.select.pose_methods import DEFAULT_POSE_METHOD, POSE_METHODS

    opts = [
        click.option(
            "--pose-method",
            "pose_method",
            type=click.Choice(POSE_METHODS),
            default=DEFAULT_POSE_METHOD,
            show_default=True,
            help="Pose selector: 'story' (story information: pose surprisal + "
            "debounced contact events), 'paper' (the paper's pose entropy; "
            "use it to reproduce the paper), or a baseline (stretch, fastest, "
            "middle, random, salient). --w-local/--w-global/--events/--smooth "
            "apply to 'paper' only.",
        ),
        click.option(
            "-k",
            "k",
            type=click.IntRange(min=1),
            default=3,
            show_default=True,
            help="How many distinct top poses to report.",
        ),
        click.option(
            "--min-separation",
            "min_separation",
            type=FiniteFloatRange(min=0.0),
            default=MIN_SEPARATION_S,
            show_default=True,
            metavar="SECONDS",
            help="Minimum time between two reported poses.",
        ),
        click.option(
            "--w-local",
            type=FiniteFloatRange(min=0.0),
            default=1.0,
            show_default=True,
            help="Weight of the local term (joint curvature x limb x rotation).",
        ),
        click.option(
            "--w-global",
            type=FiniteFloatRange(min=0.0),
            default=1.0,
            show_default=True,
            help="Weight of the global term (interaction events).",
        ),
        click.option(
            "--events",
            type=click.Choice(EVENT_MODES),
            default="transitions",
            show_default=True,
            help="Global-term events: onset/release of an interaction, or its whole duration.",
        ),
        click.option(
            "--smooth",
            type=FiniteFloatRange(min=0.0),
            default=SMOOTH_S,
            show_default=True,
            metavar="SECONDS",
            help="Savitzky-Golay window for the joint trajectories (0: none).",
        ),
    ]
    for opt in reversed(opts):
        f = opt(f)
    return f


#: The pose stage's fields that ``snapshot select`` sets under another flag name.
_FLAGS = {"min_separation_s": "--min-separation", "smooth_s": "--smooth"}


def pose_params_from_options(
    pose_method, k, min_separation, w_local, w_global, events, smooth
) -> PoseParams:
    """The pose stage's :class:`~snapcore.select.pose_methods.PoseParams` from the
    command's options. The paper's options set to anything but their defaults with
    another method are refused by PoseParams; here the refusal names the flags (one
    line, exit 2)."""
    try:
        return PoseParams(
            pose_method=pose_method,
            k=k,
            min_separation_s=min_separation,
            w_local=w_local,
            w_global=w_global,
            events=events,
            smooth_s=smooth,
        )
    except PaperOptionError as err:
        flags = ", ".join(_FLAGS.get(n, "--" + n.replace("_", "-")) for n in err.names)
        raise click.BadParameter(
            f"{flags} apply to --pose-method paper only, not {err.method}",
            param_hint="--pose-method",
        ) from None


def snapshot_from_options(
    scene,
    pose_method,
    k,
    min_separation,
    w_local,
    w_global,
    events,
    smooth,
    *,
    view=False,
    window=None,
    baselines=True,
    body: BodyKind = DEFAULT_BODY,
):
    """Run :func:`snapcore.pipeline.take_snapshot` with the command's options
    (the view stage only with ``view=True``; ``body``: what the viewpoint-entropy
    baseline renders)."""
    from snapcore.pipeline import ViewParams, take_snapshot

    pose = pose_params_from_options(
        pose_method, k, min_separation, w_local, w_global, events, smooth
    )
    view_params = (
        ViewParams(window_s=window, baselines=bool(baselines), body=body) if view else None
    )
    return take_snapshot(scene, pose=pose, view=view_params)


def format_snapshot(doc: dict) -> list[str]:
    """Human-readable lines for a snapshot document (``Snapshot.to_dict()``)."""
    fps = doc["fps"]
    first, last = doc["frame_offset"], doc["frame_offset"] + doc["n_frames"] - 1
    lines = [
        f"scene       {doc['scene']} ({len(doc['characters'])} character"
        f"{'s' if len(doc['characters']) != 1 else ''}: {', '.join(doc['characters'])})",
        f"frames      {doc['n_frames']} at {fps:g} fps = {doc['duration_s']:.2f} s "
        f"(source frames {first}..{last})",
    ]
    top = doc["peaks"][0]
    lines.append(
        f"method      {doc.get('pose_method', 'paper')}"
        + (
            "  (the paper's pose entropy)"
            if doc.get("pose_method") == "paper"
            else "  (--pose-method paper: the paper's pose entropy)"
        )
    )
    scores = doc["pose_scores"]
    names = list(scores["terms"])
    what = "entropy" if doc.get("pose_method") == "paper" else f"score ({scores['unit']})"
    terms = " + ".join(f"{n} {top[n]:.3f}" for n in names)
    lines.append(
        f"pose        frame {doc['frame']}  (t = {doc['time_s']:.2f} s)  "
        f"{what} {top['total']:.3f} = {terms}"
    )
    lines.append(
        f"top {len(doc['peaks'])}       rank   frame   time_s   total"
        + "".join(f"  {n:>7}" for n in names)
    )
    for r, p in enumerate(doc["peaks"], start=1):
        lines.append(
            f"            {r:>4}  {p['frame']:>6}  {p['time_s']:>7.2f}  {p['total']:>6.3f}"
            + "".join(f"  {p[n]:>7.3f}" for n in names)
        )
    counts = doc.get("event_counts") or {}
    if counts:
        parts = []
        for ch, objs in counts.items():
            inner = ", ".join(f"{o} {n}" for o, n in objs.items())
            parts.append(f"{ch}: {inner}")
        lines.append("events      " + "; ".join(parts) + "  (interactions per object)")
    else:
        lines.append("events      none detected")
    lines += _format_view(doc)
    t = doc["timings_s"]
    keys = [
        k
        for k in (
            "contacts",
            "local",
            "global",
            "select",
            "pose",
            "view",
            "motion_area",
            "viewpoint_entropy",
            "total",
        )
        if k in t
    ]
    lines.append("timings     " + ", ".join(f"{k} {1000 * t[k]:.1f} ms" for k in keys))
    # one cold run: imports, caches and first-touched memory count here, not in
    # `snapshot bench` (warm, repeated), whose numbers docs/speed.md quotes
    lines.append("            (one first run, set-up included; `snapshot bench` times warm runs)")
    return lines


def _format_view(doc: dict) -> list[str]:
    """Summary lines of the view stage (none when it did not run)."""
    if "view" not in doc:
        return []

    def vec(v):
        return "(" + ", ".join(f"{x:+.3f}" for x in v) + ")"

    pma, win = doc.get("pma", {}), doc.get("window", {})
    span = f"frames {win.get('start_frame')}..{win.get('end_frame')}" + (
        f" (pose ± {win['half_width_s']:g} s)" if win.get("mode") == "pose" else ""
    )
    lines = [
        f"view        {vec(doc['view'])}  PMA {pma.get('score', 0):.1f} "
        f"(mean ratio {pma.get('mean_ratio', 0):.3f}), {span}",
        f"            {pma.get('facing_note', '')}",
    ]
    for i, (name, b) in enumerate((doc.get("baselines") or {}).items()):
        lines.append(
            f"{'baselines' if i == 0 else '':<12}{vec(b['view'])}  {name} "
            f"{b['score']:.4g} {b.get('units', '')}"
        )
    return lines


@click.command()
@scene_arguments
@pose_options
@click.option(
    "--window",
    "window",
    type=FiniteFloatRange(min=0.0),
    default=None,
    metavar="SECONDS",
    help="Score the view over the selected pose ± SECONDS (pose-specific view); "
    "default: the whole sequence.",
)
@click.option(
    "--no-baselines",
    is_flag=True,
    help="Skip the motion-area and viewpoint-entropy baseline views (faster: no rendering).",
)
@click.option("--no-view", is_flag=True, help="Select the pose only (no view stage).")
@click.option(
    "--json",
    "as_json",
    is_flag=True,
    help="Print the snapshot as JSON (data_schema/snapshot.schema.json).",
)
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, writable=True),
    default=None,
    callback=output_callback(),
    help="Also write the JSON document to this file (not one of the inputs).",
)
def select(
    paths,
    fps,
    scale,
    pose_method,
    k,
    min_separation,
    w_local,
    w_global,
    events,
    smooth,
    window,
    no_baselines,
    no_view,
    as_json,
    output,
):
    """Select the most informative pose and view of a scene (paper sections 3.1-3.2).

    PATH is one or more BVH files (several = one multi-character scene sharing a
    world frame) or a scene manifest (.toml/.json). Frame numbers are the source
    file's, 0-based. The pose comes from --pose-method (default 'story', story
    information; '--pose-method paper' gives the paper's pose entropy, as the paper's
    figures and study do); the JSON names it in "pose_method". Without --json a
    summary is printed: the pose, the top-k table,
    interaction events per character and object, the view (Projected Motion Area,
    refined) with the two baseline views, and timings. Views are unit vectors from
    the scene centre to the camera (world frame, Y up).

    \b
    Example:
      snapshot select two_person/60_01_scaled.bvh two_person/61_01_scaled.bvh --fps 60
    """
    refuse_inputs(paths, **{"-o/--output": output})
    scene = scene_from_options(paths, fps, scale)
    snap = snapshot_from_options(
        scene,
        pose_method,
        k,
        min_separation,
        w_local,
        w_global,
        events,
        smooth,
        view=not no_view,
        window=window,
        baselines=not no_baselines,
        body=body_option(),
    )
    doc = snap.to_dict()
    from snapcore.schema import validate

    validate(doc, "snapshot", source="snapshot select output")
    if output:
        import json

        Path(output).write_text(json.dumps(doc, indent=2, allow_nan=False) + "\n", encoding="utf-8")
    if as_json:
        echo_json(doc)
        return
    for line in format_snapshot(doc):
        click.echo(line)


@click.command("plot-entropy")
@scene_arguments
@pose_options
@click.option(
    "-o",
    "--output",
    type=click.Path(dir_okay=False, writable=True),
    required=True,
    callback=output_callback(".png", ".pdf", ".svg"),
    help="Image file to write (.png, .pdf, .svg).",
)
@click.option(
    "--strip",
    type=click.IntRange(min=0),
    default=8,
    show_default=True,
    help="Evenly spaced poses in the film strip besides the top-k (0: top-k only).",
)
@click.option("--dpi", type=click.IntRange(min=30), default=120, show_default=True)
def plot_entropy(
    paths,
    fps,
    scale,
    pose_method,
    k,
    min_separation,
    w_local,
    w_global,
    events,
    smooth,
    output,
    strip,
    dpi,
):
    """Plot the pose score over time with events and the chosen poses (paper Fig. 5-6).

    Top: the --pose-method's terms and total score over time, the top-k peaks marked:
    by default the story information's terms; with '--pose-method paper' the local,
    global and total pose entropy of the paper's Fig. 5-6. Interaction events as ticks
    per character and object (onset and release). Bottom: a film strip of stick
    figures seen from the side, coloured by the score, the top-k poses drawn bold.
    """
    scene = scene_from_options(paths, fps, scale)
    snap = snapshot_from_options(
        scene, pose_method, k, min_separation, w_local, w_global, events, smooth
    )
    from snapcore.render.entropy_plot import plot_entropy as draw

    fig = draw(snap, strip=strip)
    out = Path(output)
    fig.savefig(out, dpi=dpi)
    click.echo(
        f"wrote {out}  (pose: frame {snap.source_frame}, top {len(snap.source_frames)}: "
        f"{', '.join(str(f) for f in snap.source_frames)})"
    )
