"""Exception types of snapcore.

The library raises these precise types; only the edges (the CLI, the study app) catch
them and turn them into one clear line for a person. Each is a ``ValueError`` too, so
callers that only know the standard library still catch bad input.
"""

from __future__ import annotations

__all__ = [
    "SnapshotError",
    "BVHError",
    "GLTFError",
    "FBXError",
    "SceneError",
    "SchemaError",
    "RenderError",
    "SelectionError",
    "ReliefError",
]


class SnapshotError(ValueError):
    """Base of every error snapcore raises for bad input or an impossible request."""


class BVHError(SnapshotError):
    """A BVH file that cannot be read.

    Parameters
    ----------
    message : str
        What was expected and what was found.
    path : str, optional
        The file, as given by the caller.
    line : int, optional
        1-based line number in the file where the problem is.
    """

    def __init__(self, message: str, *, path: str | None = None, line: int | None = None) -> None:
        self.path = path
        self.line = line
        self.reason = message
        where = path or "<bvh>"
        if line is not None:
            where = f"{where}:{line}"
        super().__init__(f"{where}: {message}")


class GLTFError(SnapshotError):
    """A glTF 2.0 / GLB file that cannot be read or is not supported.

    Parameters
    ----------
    message : str
        What is wrong, naming the glTF object (``accessor 12``, ``animation 'Walk'``).
    path : str, optional
        The file, as given by the caller.
    """

    def __init__(self, message: str, *, path: str | None = None) -> None:
        self.path = path
        self.reason = message
        super().__init__(f"{path or '<gltf>'}: {message}")


class FBXError(SnapshotError):
    """An FBX file that cannot be read (damaged, truncated, no skeleton, no animation).

    Parameters
    ----------
    message : str
        What is wrong.
    path : str, optional
        The file, as given by the caller.
    """

    def __init__(self, message: str, *, path: str | None = None) -> None:
        self.path = path
        self.reason = message
        super().__init__(f"{path or '<fbx>'}: {message}")


class SceneError(SnapshotError):
    """A scene that cannot be built (incompatible characters, bad manifest values)."""


class SchemaError(SnapshotError):
    """A JSON/TOML document that does not follow its schema in ``data_schema/``.

    The message names the file and the JSON path of the offending field.
    """


class RenderError(SnapshotError):
    """A render that cannot be made (no GL context, bad size, bad view)."""


class SelectionError(SnapshotError):
    """A pose or view selection that cannot be made: an option out of range, an unknown
    method or option name."""


class ReliefError(SnapshotError):
    """A relief that cannot be made (empty silhouette, bad print size, bad parameters)."""
