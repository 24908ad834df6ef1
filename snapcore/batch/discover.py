"""Finding the scenes of a library: folders, globs and list files → one entry per scene.

A scene is one motion file (BVH, glTF) or one scene manifest (``.toml``/``.json``,
``data_schema/scene.schema.json``) for a multi-character scene. A file that a manifest
names is part of that scene and is not also run alone. Each scene gets a *key*: its
path relative to the SOURCE it was found under (``walk_run/02_01.bvh``), which names
its outputs and its row in the index, so the index does not depend on where the
library is mounted.

The content hash of a scene covers the bytes of every file it reads (a manifest and its
members), so an edited member file makes its scene run again.
"""

from __future__ import annotations

import glob
import hashlib
import json
import os
import tomllib
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath

from snapcore.errors import SnapshotError

__all__ = [
    "BatchError",
    "SceneSource",
    "Discovery",
    "discover",
    "content_hash",
    "MOTION_SUFFIXES",
    "GLTF_SUFFIXES",
    "MANIFEST_SUFFIXES",
    "LIST_SUFFIXES",
]

#: Motion files run as one scene each: the one place the batch lists the formats it
#: reads (discovery, the error for another file named explicitly).
BVH_SUFFIXES = (".bvh",)
GLTF_SUFFIXES = (".glb", ".gltf")
FBX_SUFFIXES = (".fbx",)
MOTION_SUFFIXES = BVH_SUFFIXES + GLTF_SUFFIXES + FBX_SUFFIXES
#: Scene manifests (the same suffixes :func:`snapcore.motion.load.load_scene` accepts).
MANIFEST_SUFFIXES = (".toml", ".json")
#: A SOURCE with one of these suffixes is a list of paths, one per line (``#`` comments).
LIST_SUFFIXES = (".txt", ".list", ".lst")
_CHUNK = 1 << 20
#: Why a manifest's member file is not a scene of its own.
MEMBER = "part of a scene manifest"


class BatchError(SnapshotError):
    """A batch that cannot start: a SOURCE that does not exist, an empty library."""


@dataclass(frozen=True)
class SceneSource:
    """One scene of the library, before it is loaded.

    Attributes
    ----------
    key : str
        Path relative to its SOURCE, POSIX separators (``walk_run/02_01.bvh``): the
        scene's name in the index and its outputs' name.
    kind : {"bvh", "gltf", "fbx", "manifest", "unknown"}
        ``"unknown"``: a file named explicitly whose suffix is none of these.
    path : str
        The file to load (absolute).
    members : tuple of str
        For a manifest, the absolute paths of the files it names (as resolved when
        found); empty otherwise.
    """

    key: str
    kind: str
    path: str
    members: tuple[str, ...] = ()

    @property
    def folder(self) -> str:
        """The key's folder (``""`` at the top of its SOURCE)."""
        parent = str(PurePosixPath(self.key).parent)
        return "" if parent == "." else parent

    @property
    def files(self) -> tuple[str, ...]:
        """Every file the scene reads: the path, then a manifest's members."""
        return (self.path, *self.members)


@dataclass
class Discovery:
    """What :func:`discover` found.

    Attributes
    ----------
    scenes : list of SceneSource
        Sorted by key.
    skipped : list of (str, str)
        Files looked at but not taken, with why (a ``.json`` that is not a scene
        manifest, a manifest's member file).
    """

    scenes: list[SceneSource] = field(default_factory=list)
    skipped: list[tuple[str, str]] = field(default_factory=list)

    @property
    def left_out(self) -> list[tuple[str, str]]:
        """The skipped files worth a look: those that are not a manifest's members (a
        ``.json`` that does not parse, a JSON that is not a scene manifest)."""
        return [(p, why) for p, why in self.skipped if why != MEMBER]


def _kind(path: Path) -> str | None:
    s = path.suffix.lower()
    if s in BVH_SUFFIXES:
        return "bvh"
    if s in GLTF_SUFFIXES:
        return "gltf"
    if s in FBX_SUFFIXES:
        return "fbx"
    if s in MANIFEST_SUFFIXES:
        return "manifest"
    return None


def _manifest_members(path: Path) -> tuple[tuple[str, ...] | None, str]:
    """Absolute paths of the files a scene manifest names, or None and why ``path`` is
    not a scene manifest.

    A file found in a folder is a manifest only if it follows the scene schema
    (``data_schema/scene.schema.json``) whole: the schema is strict (no unknown field,
    a ``file`` for every character), so a gallery, a ``select --json`` document or any
    other JSON that happens to have a ``characters`` list is left alone, while every
    manifest that loads is taken. No marker field is required, so the manifests that
    exist (the shipped salsa scenes, users' own) need no edit.
    """
    try:
        text = path.read_text(encoding="utf-8")
        doc = tomllib.loads(text) if path.suffix.lower() == ".toml" else json.loads(text)
    except (OSError, UnicodeDecodeError, ValueError):
        return None, "not a scene manifest (does not parse)"
    chars = doc.get("characters") if isinstance(doc, dict) else None
    if not isinstance(chars, list):
        return None, "not a scene manifest (no characters list)"
    from snapcore.errors import SchemaError
    from snapcore.schema import validate

    try:
        validate(doc, "scene", source=path.name)
    except SchemaError as err:
        return None, f"not a scene manifest ({err})"
    # resolved exactly as the loader will resolve them (manifest folder, then the data dir)
    from snapcore.motion.load import resolve_data_path

    base = path.resolve().parent
    return tuple(str(resolve_data_path(c["file"], base).resolve()) for c in chars), ""


def _walk(root: Path, exclude: list[Path]) -> list[Path]:
    """Files under ``root``, sorted; hidden folders and ``exclude`` folders left out."""
    found = []
    for folder, dirs, files in os.walk(root):
        here = Path(folder)
        dirs[:] = sorted(
            d
            for d in dirs
            if not d.startswith(".") and not any(_same(here / d, e) for e in exclude)
        )
        found += [here / f for f in sorted(files) if not f.startswith(".")]
    return found


def _same(a: Path, b: Path) -> bool:
    try:
        return a.resolve() == b.resolve()
    except OSError:
        return False


def _glob_root(pattern: str) -> Path:
    """The folder part of a glob before its first wildcard (keys are relative to it)."""
    parts = Path(pattern).parts
    fixed = []
    for p in parts:
        if glob.has_magic(p):
            break
        fixed.append(p)
    return Path(*fixed) if fixed else Path(".")


def _expand(source: str, exclude: list[Path], depth: int = 0) -> list[tuple[Path, Path, bool]]:
    """``(file, root, explicit)`` for one SOURCE; ``explicit``: named by the user (taken
    whatever it holds) rather than found in a folder (taken only if it is a scene)."""
    p = Path(source).expanduser()
    if p.is_dir():
        return [(f, p, False) for f in _walk(p, exclude)]
    if glob.has_magic(source):
        root = _glob_root(source)
        out = []
        for m in sorted(glob.glob(str(p), recursive=True)):
            mp = Path(m)
            out += (
                [(f, mp, False) for f in _walk(mp, exclude)] if mp.is_dir() else [(mp, root, False)]
            )
        if not out:
            raise BatchError(f"SOURCE {source}: the pattern matches no files")
        return out
    if not p.exists():
        raise BatchError(f"SOURCE {source}: no such file or folder")
    if p.suffix.lower() in LIST_SUFFIXES:
        if depth > 0:
            raise BatchError(f"{p}: a list file inside a list file is not supported")
        out = []
        try:
            lines = p.read_text(encoding="utf-8").splitlines()
        except (OSError, UnicodeDecodeError) as err:
            raise BatchError(f"{p}: cannot read the list ({err})") from err
        for n, line in enumerate(lines, start=1):
            entry = line.split("#", 1)[0].strip()
            if not entry:
                continue
            item = Path(entry).expanduser()
            item = item if item.is_absolute() else p.parent / item
            if not item.exists() and not glob.has_magic(str(item)):
                raise BatchError(f"{p}:{n}: {entry}: no such file or folder")
            for f, root, explicit in _expand(str(item), exclude, depth + 1):
                # keys relative to the list's folder when the entry lies under it
                base = p.parent if _is_under(f, p.parent) else root
                out.append((f, base, explicit))
        return out
    return [(p, p.parent, True)]


def _is_under(f: Path, folder: Path) -> bool:
    try:
        f.resolve().relative_to(folder.resolve())
        return True
    except ValueError:
        return False


def discover(sources, *, exclude=(), root=None) -> Discovery:
    """The scenes named by ``sources``.

    Parameters
    ----------
    sources : sequence of str
        Folders (walked recursively), glob patterns (``**`` allowed), list files
        (``.txt``/``.list``/``.lst``: one path, folder or pattern per line, relative to
        the list's folder) or single files.
    exclude : sequence of path-like
        Folders not to walk into (the output folder, when it lies inside a SOURCE).
    root : path-like, optional
        The library's root folder: files under it are keyed relative to it rather than
        to their SOURCE, so a run over one sub-folder names its scenes as the run over
        the whole library did (see :func:`snapcore.batch.run.library_root`).

    Returns
    -------
    Discovery

    Raises
    ------
    BatchError
        A SOURCE that does not exist or matches nothing.

    Notes
    -----
    In folders, ``.bvh``/``.glb``/``.gltf`` files are scenes, and so are ``.toml``/
    ``.json`` files that are scene manifests (they have a ``characters`` list); other
    files are ignored. A file named explicitly is always a scene, so a broken one is
    reported as an error rather than skipped. Files a manifest names are not run alone.
    """
    excl = [Path(e) for e in exclude]
    lib = Path(root).resolve() if root is not None else None
    out = Discovery()
    by_file: dict[str, SceneSource] = {}
    for source in sources:
        for f, root, explicit in _expand(str(source), excl):
            kind = _kind(f)
            if kind is None and not explicit:
                continue
            resolved = str(f.resolve())
            if resolved in by_file:
                continue
            members: tuple[str, ...] = ()
            if kind is None:  # named by the user: loading it says what is wrong
                kind = "unknown"
            elif kind == "manifest":
                found, why = _manifest_members(f)
                if found is None and not explicit:
                    out.skipped.append((str(f), why))
                    continue
                members = found or ()
            # resolved on both sides: a list named by a relative path ('clips.txt', its
            # folder '.') holding the absolute paths `find` prints
            base = lib if lib is not None and _is_under(f, lib) else root
            key = (
                f.resolve().relative_to(base.resolve()).as_posix() if _is_under(f, base) else f.name
            )
            by_file[resolved] = SceneSource(key=key, kind=kind, path=resolved, members=members)
    taken = {m for s in by_file.values() for m in s.members}
    scenes = []
    for resolved, s in by_file.items():
        if resolved in taken:
            out.skipped.append((s.path, MEMBER))
        else:
            scenes.append(s)
    out.scenes = _unique_keys(scenes)
    return out


def _unique_keys(scenes: list[SceneSource]) -> list[SceneSource]:
    """Sorted by key; a key found under two SOURCEs gets ``~2``, ``~3``... (in source
    order) so that no two scenes write the same outputs."""
    seen: dict[str, int] = {}
    out = []
    for s in scenes:
        n = seen.get(s.key, 0) + 1
        seen[s.key] = n
        if n > 1:
            stem = PurePosixPath(s.key)
            s = SceneSource(
                key=str(stem.with_name(f"{stem.stem}~{n}{stem.suffix}")),
                kind=s.kind,
                path=s.path,
                members=s.members,
            )
        out.append(s)
    return sorted(out, key=lambda s: s.key)


def content_hash(scene: SceneSource) -> str:
    """SHA-256 (hex) over the bytes of every file the scene reads, in order.

    A missing member contributes a marker instead of failing here: loading the scene
    reports it, as one error line in the index.
    """
    h = hashlib.sha256()
    for path in scene.files:
        h.update(b"\0file\0")
        try:
            with open(path, "rb") as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
        except OSError:
            h.update(b"\0missing\0")
    return h.hexdigest()
