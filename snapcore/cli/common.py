"""Options and helpers shared by the snapcore subcommands.

Bad input is refused while click parses the command line, before any file is loaded
or anything is computed: numbers through the parameter types below, output paths through
:func:`output_callback`, vectors through :func:`vector_callback`. Each refusal is one
line that names the option (:mod:`snapcore.cli.main` prints click's errors as ``error: ...``
with exit code 2).
"""

from __future__ import annotations

import json
import math
import os
from pathlib import Path

import click
import numpy as np

from snapcore.motion.load import load_scene
from snapcore.render.bodies import BODY_KINDS, DEFAULT_BODY, BodyKind

__all__ = [
    "scene_arguments",
    "scene_from_options",
    "body_option",
    "echo_json",
    "parse_vector",
    "PositiveFloat",
    "POSITIVE",
    "FiniteFloatRange",
    "check_output",
    "output_callback",
    "refuse_inputs",
    "vector_callback",
    "view_callback",
    "internal_frame",
]


class PositiveFloat(click.ParamType):
    """A positive, finite number: refuses 0, negatives, nan and ±inf, naming the option.

    No plausibility limit beyond that: a tiny but positive scale or frame rate is the
    user's call.
    """

    name = "float"

    def convert(self, value, param, ctx):
        try:
            v = float(value)
        except (TypeError, ValueError):
            self.fail(f"expected a positive number, got '{value}'", param, ctx)
        if not (math.isfinite(v) and v > 0):
            self.fail(f"expected a positive finite number, got '{value}'", param, ctx)
        return v


#: The :class:`PositiveFloat` type (frame rates, scales, millimetres).
POSITIVE = PositiveFloat()


class FiniteFloatRange(click.FloatRange):
    """:class:`click.FloatRange` that also refuses nan and ±inf (click lets them through:
    nan compares False with both bounds)."""

    def convert(self, value, param, ctx):
        v = click.FLOAT.convert(value, param, ctx)
        if not math.isfinite(v):
            self.fail(f"expected a finite number, got '{value}'", param, ctx)
        return super().convert(v, param, ctx)


def _stash(ctx, param, value):
    """Keep ``--body``/``--animation`` in the click context for :func:`body_option` and
    :func:`scene_from_options` (not passed to the command function: every command gets
    them without changing its signature)."""
    ctx.meta[f"snapshot.{param.name}"] = value
    return value


def body_options(f):
    """Decorate a command with ``--body`` and ``--animation`` (kept for
    :func:`body_option` and :func:`scene_from_options`, not passed to the command
    function)."""
    f = click.option(
        "--animation",
        default=None,
        metavar="NAME",
        expose_value=False,
        callback=_stash,
        help="glTF/GLB and FBX characters: the animation (FBX: the take) to play (name or index; "
        "default the first; `snapshot info` lists them).",
    )(f)
    f = click.option(
        "--body",
        type=click.Choice(BODY_KINDS),
        default=None,
        expose_value=False,
        callback=_stash,
        help="Body drawn on skeletons: the MakeHuman 'human' mesh (default; glTF "
        "characters wear their own), the capsule 'mannequin', or 'makehuman': the "
        "MakeHuman mesh on glTF and FBX skeletons too.",
    )(f)
    return f


def scene_arguments(f):
    """Decorate a command with ``PATH...`` plus ``--fps``, ``--scale``, ``--body`` and
    ``--animation``."""
    f = body_options(f)
    f = click.option(
        "--scale",
        type=POSITIVE,
        default=None,
        help="Metres per file unit (default: inferred from the characters' stature).",
    )(f)
    f = click.option(
        "--fps",
        type=POSITIVE,
        default=None,
        help="Frame rate override (some headers are wrong, e.g. CMU salsa).",
    )(f)
    f = click.argument("paths", nargs=-1, required=True, type=click.Path(dir_okay=False))(f)
    return f


def _stashed(name: str):
    ctx = click.get_current_context(silent=True)
    return ctx.meta.get(f"snapshot.{name}") if ctx is not None else None


def scene_from_options(paths, fps=None, scale=None):
    """Load the scene named by a command's PATH arguments and options (``--animation``
    is read from the click context when a command is running)."""
    return load_scene(list(paths), fps=fps, scale=scale, animation=_stashed("animation"))


def body_option() -> BodyKind:
    """The running command's ``--body`` (:data:`~snapcore.render.bodies.DEFAULT_BODY`
    when not given, or outside a command): the commands pass it as ``body=`` to what
    they render. A render option, so it stays out of the scene."""
    return _stashed("body") or DEFAULT_BODY


def _default(o):
    if isinstance(o, np.ndarray):
        return o.tolist()
    if isinstance(o, np.generic):
        return o.item()
    raise TypeError(f"not JSON serialisable: {type(o).__name__}")


def echo_json(obj) -> None:
    """Print ``obj`` as indented JSON (NumPy arrays and scalars allowed)."""
    click.echo(json.dumps(obj, indent=2, default=_default, allow_nan=False))


def parse_vector(text: str, name: str = "--view") -> np.ndarray:
    """Parse ``"x,y,z"`` into a unit vector, with a one-line error naming ``name``."""
    try:
        v = np.array([float(t) for t in text.split(",")], dtype=float)
    except ValueError:
        raise click.BadParameter(
            f"expected three numbers like 0,0,1, got '{text}'", param_hint=name
        ) from None
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise click.BadParameter(f"expected a non-zero vector x,y,z, got '{text}'", param_hint=name)
    return v / np.linalg.norm(v)


def _or(items) -> str:
    items = list(items)
    return items[0] if len(items) == 1 else ", ".join(items[:-1]) + " or " + items[-1]


def check_output(path, suffixes=None, *, option: str = "-o/--output", what: str | None = None):
    """Refuse an output path that the command could not write, before any work.

    Parameters
    ----------
    path : str or Path
        The path as given.
    suffixes : sequence of str, optional
        Allowed suffixes, lower case with the dot (``(".png",)``); compared case-
        insensitively. None: any.
    option : str
        The option, for the message.
    what : str, optional
        Words before the allowed suffixes in the message, e.g. ``"render writes"``
        (default ``"expected"``).

    Returns
    -------
    The path, unchanged.

    Raises
    ------
    click.UsageError
        One line: ``-o/--output x.txt: plot-entropy writes .png, .pdf or .svg``, or the
        folder does not exist / is not writable, or the path is a folder.
    """
    p = Path(path)
    if suffixes and p.suffix.lower() not in suffixes:
        raise click.UsageError(f"{option} {path}: {what or 'expected'} {_or(suffixes)}")
    folder = p.parent
    if p.is_dir():
        raise click.UsageError(f"{option} {path}: is a folder, expected a file name")
    if not folder.is_dir():
        raise click.UsageError(f"{option} {path}: folder {folder} does not exist")
    if not os.access(folder, os.W_OK):
        raise click.UsageError(f"{option} {path}: folder {folder} is not writable")
    return path


def _option_name(param) -> str:
    return "/".join(sorted(param.opts, key=len))


def output_callback(*suffixes: str, what: str | None = None):
    """A click callback checking an output option with :func:`check_output` at parse time.

    ``what`` says what the command writes (default: ``"<command> writes"``), e.g.
    ``-o/--output ent.txt: plot-entropy writes .png, .pdf or .svg``.
    """

    def callback(ctx, param, value):
        if value is None:
            return value
        return check_output(
            value,
            suffixes or None,
            option=_option_name(param),
            what=what or f"{ctx.info_name} writes",
        )

    return callback


def refuse_inputs(paths, **outputs) -> None:
    """Refuse an output that is one of the input files (it would be overwritten).

    ``outputs`` maps option names (``"-o/--output"``) to paths (None: not given).
    """
    inputs = {Path(p).resolve() for p in paths}
    for option, out in outputs.items():
        if out is not None and Path(out).resolve() in inputs:
            raise click.UsageError(f"{option} {out}: is one of the input files")


def _vector(text: str, param) -> np.ndarray:
    try:
        return parse_vector(text)
    except click.BadParameter as err:  # name the option as click does for its own errors
        raise click.BadParameter(err.message, param=param) from None


def vector_callback(ctx, param, value):
    """A click callback parsing ``x,y,z`` into a unit vector (None stays None)."""
    return None if value is None else _vector(value, param)


def view_callback(ctx, param, value):
    """A click callback for ``--view x,y,z|auto|default``: the keywords stay text,
    a vector becomes a unit vector, anything else is refused."""
    if value is None or value in ("auto", "default"):
        return value
    return _vector(value, param)


def internal_frame(scene, source_frame: int, option: str = "--frame") -> int:
    """The scene's internal index of a source frame given on the command line; a frame
    the scene does not keep is a one-line error naming ``option`` and saying why
    (:meth:`snapcore.motion.scene.Scene.internal_frame`)."""
    from snapcore.errors import SceneError

    try:
        return scene.internal_frame(source_frame)
    except SceneError as err:
        raise click.BadParameter(str(err), param_hint=option) from None
