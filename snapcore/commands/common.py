"""Options and helpers shared by the snapcore subcommands."""

from __future__ import annotations

import json

import click
import numpy as np

from ..load import load_scene

__all__ = ["scene_arguments", "scene_from_options", "echo_json", "parse_vector"]


def scene_arguments(f):
    """Decorate a command with ``PATH...`` plus ``--fps`` and ``--scale``."""
    f = click.option("--scale", type=float, default=None,
                     help="Metres per file unit (default: inferred from the characters' stature).")(f)
    f = click.option("--fps", type=float, default=None,
                     help="Frame rate override (some headers are wrong, e.g. CMU salsa).")(f)
    f = click.argument("paths", nargs=-1, required=True,
                       type=click.Path(dir_okay=False))(f)
    return f


def scene_from_options(paths, fps=None, scale=None):
    """Load the scene named by a command's PATH arguments and options."""
    return load_scene(list(paths), fps=fps, scale=scale)


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
        raise click.BadParameter(f"expected three numbers like 0,0,1, got '{text}'",
                                 param_hint=name) from None
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise click.BadParameter(f"expected a non-zero vector x,y,z, got '{text}'", param_hint=name)
    return v / np.linalg.norm(v)
