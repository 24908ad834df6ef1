"""Stimuli: the files participants see, and the manifest that vouches for them.

A stimuli folder holds, per scene of the study::

    <scene>/video.mp4           the whole animation, H.264, ``video_fps`` (24 by default)
    <scene>/video.webm          the same frames as WebM/VP9 (browsers without H.264)
    <scene>/frames/00000.jpg    one image per video frame: the frames a participant picks from
    <scene>/view_<method>.png   the selected pose seen from each method's view direction
    <scene>/scene.json          the scene manifest that was loaded (provenance)

and one ``manifest.json`` (``data_schema/stimuli.schema.json``) with the sha256 of every
file, the motion frame (source numbering) shown at each video frame, the algorithm's
picks, and which method made which view. The app refuses a folder whose manifest does
not match its files (:func:`load_stimuli`), before any participant starts.

Stimulus sets are content-addressed and never rewritten:
:func:`~study_app.design.build.build_stimuli` writes the set of ``OUT`` into
``OUT.sets/<content hash>/`` and points ``OUT`` (a symbolic link) at it. A rebuild makes
a new set beside the old one (or reuses it when the content is the same), so a study
serving the old set (the server pins the folder ``OUT`` resolves to at start) keeps
serving it, and participants who started on it resume on it after a restart
(:func:`find_stimulus_set`). A set's identity, :func:`content_sha256`, is the hash of its
manifest without the build's record (time, app version, timings): the files' own sha256
are in it, so it changes exactly when what participants see does.

This module reads, verifies and identifies sets; the candidate views are chosen in
:mod:`study_app.design.candidates`, the media written in :mod:`study_app.design.media`,
and a set built and published in :mod:`study_app.design.build`.
"""

from __future__ import annotations

import hashlib
import json
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from snapcore.errors import SchemaError, SnapshotError
from snapcore.schema import validate
from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

from .protocol import Study, study_from_dict
from .scenes import StudyScene

__all__ = [
    "MANIFEST_NAME",
    "SETS_SUFFIX",
    "PICK_KEYS",
    "default_stimuli_dir",
    "StimuliError",
    "SceneStimulus",
    "Stimuli",
    "sha256_file",
    "load_stimuli",
    "verify_stimuli",
    "app_version",
    "content_sha256",
    "find_stimulus_set",
]

MANIFEST_NAME = "manifest.json"
_REPO = Path(__file__).resolve().parents[2]
_HASH_CHUNK = 1 << 20
#: ``OUT`` links to ``OUT.sets/<content hash>/``, where every build of ``OUT`` is kept.
SETS_SUFFIX = ".sets"
#: Manifest fields that record how a build went, not what it shows: not in its identity.
BUILD_RECORD_FIELDS = ("created_at", "app_version")
SCENE_BUILD_RECORD_FIELDS = ("timings_s",)
#: Characters of the content hash that name a set's folder.
SET_NAME_CHARS = 16
#: The manifest's ``picks`` key of each method's view (ours is ``view``, as in
#: ``snapshot select --json``; the baselines by their method name).
PICK_KEYS = {m: "view" if m is ViewMethod.OURS else m.value for m in VIEW_METHODS}


def default_stimuli_dir(study_id: str) -> Path:
    """Where a study's stimuli live unless told otherwise: ``<repo>/var/stimuli/<id>``."""
    return _REPO / "var" / "stimuli" / study_id


class StimuliError(SnapshotError):
    """A stimuli folder that cannot be used (missing, altered or inconsistent files)."""


def app_version() -> str:
    """The installed package version (stored with manifests and responses)."""
    try:
        from importlib.metadata import version

        return version("action-snapshot")
    except Exception:  # noqa: BLE001 - running from a source tree without metadata
        return "0+unknown"


def sha256_file(path: str | Path) -> str:
    """Lowercase hex sha256 of a file's bytes."""
    h = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(_HASH_CHUNK), b""):
            h.update(chunk)
    return h.hexdigest()


# --------------------------------------------------------------------------- loading


@dataclass(frozen=True, kw_only=True)
class SceneStimulus(StudyScene):
    """One scene's stimuli, paths resolved: the :class:`~study_app.design.scenes.StudyScene`
    (id, timing, the algorithm's picks, title) and its files.

    Attributes
    ----------
    video : Path
    video_webm : Path or None
        The WebM/VP9 copy (None in folders built before it existed).
    video_fps : float
    video_to_motion : tuple of int
        Motion frame (source numbering) shown at each video frame.
    frames : tuple of Path
        One image per video frame.
    views : dict of str to Path
        Candidate view image per method.
    entry : dict
        The scene's entry in the manifest.
    """

    video: Path
    video_fps: float
    video_to_motion: tuple[int, ...]
    frames: tuple[Path, ...]
    views: dict
    entry: dict
    video_webm: Path | None = None

    @property
    def shown_groups(self) -> tuple[tuple[str, ...], ...]:
        """The pictures its view task shows, each the methods it stands for (its own
        first): the manifest's ``shown``, else every method its own picture."""
        shown = self.entry.get("shown")
        if shown:
            return tuple(tuple(g) for g in shown)
        return tuple((m.value,) for m in VIEW_METHODS if m.value in self.views)

    @property
    def videos(self) -> list[Path]:
        """The video's encodings in the order a browser should try them."""
        return [self.video] + ([self.video_webm] if self.video_webm else [])

    @property
    def n_video_frames(self) -> int:
        return len(self.video_to_motion)

    @property
    def algorithm_video_frame(self) -> int:
        """The video frame whose motion frame is closest to the algorithm's pick."""
        m = np.asarray(self.video_to_motion)
        return int(np.argmin(np.abs(m - self.algorithm_frame)))


@dataclass(frozen=True)
class Stimuli:
    """A verified stimuli folder.

    Attributes
    ----------
    folder : Path
    manifest : dict
        The parsed manifest.
    sha256 : str
        :func:`content_sha256` of the manifest: identifies this exact set of stimuli
        (stored with every participant and response).
    study : Study
    scenes : dict of str to SceneStimulus
    file_sha256 : str
        sha256 of the ``manifest.json`` file (what databases of earlier versions stored
        as the participant's manifest: accepted as the same set).
    """

    folder: Path
    manifest: dict
    sha256: str
    study: Study
    scenes: dict
    file_sha256: str = ""

    @property
    def hashes(self) -> tuple[str, ...]:
        """Every hash a participant's ``manifest_sha256`` may hold for this set."""
        return tuple(h for h in (self.sha256, self.file_sha256) if h)

    def file_digests(self) -> dict[str, str]:
        """``{absolute path: sha256}`` of every file of the set (what the server checks
        each file it serves against)."""
        return {str(self.folder / rel): digest for rel, digest in self.manifest["files"].items()}

    @property
    def scene_ids(self) -> list[str]:
        return list(self.scenes)

    @property
    def view_groups(self) -> tuple:
        """``((scene, shown groups), ...)`` of the scenes whose view task merges alike
        pictures (:attr:`SceneStimulus.shown_groups`): the plan's ``shown``, hashable."""
        return tuple(
            (sid, sc.shown_groups) for sid, sc in self.scenes.items() if sc.entry.get("shown")
        )


def _referenced_files(entry: dict) -> list[str]:
    files = [
        entry["video"],
        *([entry["video_webm"]] if "video_webm" in entry else []),
        *entry["frames"],
    ]
    files += [v["file"] for v in entry["views"].values()]
    return files


def verify_stimuli(folder: str | Path) -> dict:
    """Check a stimuli folder against its manifest; return the parsed manifest.

    Checks, in order: the manifest exists, parses and follows its schema; every file it
    lists exists and has the listed sha256; every file a scene uses is listed; each
    scene's frame map, frame images and video agree in length.

    Raises
    ------
    StimuliError
        Naming the folder and the first file or field that is wrong.
    """
    root = Path(folder)
    mpath = root / MANIFEST_NAME
    if not root.is_dir():
        raise StimuliError(
            f"stimuli folder {root} does not exist (build it with "
            "`snapshot stimuli build STUDY.toml -o FOLDER`)"
        )
    if not mpath.is_file():
        raise StimuliError(f"stimuli folder {root}: no {MANIFEST_NAME} (an unfinished build?)")
    try:
        manifest = json.loads(mpath.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as err:
        raise StimuliError(f"{mpath}: cannot read the manifest ({err})") from err
    try:
        validate(manifest, "stimuli", source=str(mpath))
    except SchemaError as err:
        raise StimuliError(str(err)) from err
    listed = manifest["files"]
    for rel, digest in listed.items():
        p = root / rel
        if not p.is_file():
            raise StimuliError(f"stimuli folder {root}: {rel} is missing")
        if sha256_file(p) != digest:
            raise StimuliError(
                f"stimuli folder {root}: {rel} has been altered "
                "(its sha256 differs from the manifest)"
            )
    for entry in manifest["scenes"]:
        for rel in _referenced_files(entry):
            if rel not in listed:
                raise StimuliError(f"{mpath}: scene {entry['id']}: {rel} has no sha256 in files")
        if len(entry["frames"]) != len(entry["video_to_motion"]):
            raise StimuliError(
                f"{mpath}: scene {entry['id']}: {len(entry['frames'])} frame images "
                f"but {len(entry['video_to_motion'])} video frames in the map"
            )
        lo, hi = entry["frame_offset"], entry["frame_offset"] + entry["n_frames"]
        bad = [m for m in entry["video_to_motion"] if not lo <= m < hi]
        if bad or not lo <= entry["picks"]["frame"] < hi:
            raise StimuliError(
                f"{mpath}: scene {entry['id']}: motion frames outside the "
                f"scene's range [{lo}, {hi})"
            )
    return manifest


def load_stimuli(folder: str | Path, *, verify: bool = True) -> Stimuli:
    """Open a stimuli folder (verifying every file's sha256 unless ``verify=False``)."""
    root = Path(folder).resolve()
    if verify:
        manifest = verify_stimuli(root)
    else:
        manifest = json.loads((root / MANIFEST_NAME).read_text(encoding="utf-8"))
    try:
        study = study_from_dict(manifest["study"], source=f"{root / MANIFEST_NAME}: study")
    except SnapshotError as err:
        raise StimuliError(str(err)) from err
    missing = [s for s in study.scene_ids if s not in {e["id"] for e in manifest["scenes"]}]
    if missing:
        raise StimuliError(f"{root / MANIFEST_NAME}: no stimuli for scene(s) {', '.join(missing)}")
    scenes = {}
    for e in manifest["scenes"]:
        scenes[e["id"]] = SceneStimulus(
            scene=e["id"],
            fps=float(e["fps"]),
            n_frames=int(e["n_frames"]),
            frame_offset=int(e["frame_offset"]),
            algorithm_frame=int(e["picks"]["frame"]),
            algorithm_frames=tuple(int(f) for f in e["picks"].get("frames", ())),
            title=e.get("title"),
            video=root / e["video"],
            video_fps=float(e["video_fps"]),
            video_to_motion=tuple(e["video_to_motion"]),
            frames=tuple(root / f for f in e["frames"]),
            views={m: root / v["file"] for m, v in e["views"].items()},
            entry=e,
            video_webm=root / e["video_webm"] if e.get("video_webm") else None,
        )
    return Stimuli(
        folder=root,
        manifest=manifest,
        sha256=content_sha256(manifest),
        study=study,
        scenes=scenes,
        file_sha256=sha256_file(root / MANIFEST_NAME),
    )


def content_sha256(manifest: dict) -> str:
    """The identity of a stimulus set: sha256 of its manifest without the build's record
    (:data:`BUILD_RECORD_FIELDS`, each scene's timings), as canonical JSON.

    Two builds showing the same files (each file's sha256 is in the manifest) with the
    same frame maps, picks and study settings have the same hash, whenever they ran.
    """
    doc = {k: v for k, v in manifest.items() if k not in BUILD_RECORD_FIELDS}
    doc["scenes"] = [
        {k: v for k, v in e.items() if k not in SCENE_BUILD_RECORD_FIELDS}
        for e in manifest.get("scenes", [])
    ]
    text = json.dumps(doc, sort_keys=True, separators=(",", ":"), ensure_ascii=True)
    return hashlib.sha256(text.encode("ascii")).hexdigest()


_SETS: dict[tuple[str, str], Stimuli] = {}


def find_stimulus_set(stimuli: Stimuli, sha256: str) -> Stimuli | None:
    """The set whose hash is ``sha256`` among the sets kept beside ``stimuli`` (the
    other builds in its ``OUT.sets`` folder), verified; None when there is none.

    A participant who started before a rebuild resumes on the set they started with.
    Found sets are kept for the process (they never change).
    """
    if sha256 in stimuli.hashes:
        return stimuli
    key = (str(stimuli.folder.parent), sha256)
    if key in _SETS:
        return _SETS[key]
    parent = stimuli.folder.parent
    if not parent.name.endswith(SETS_SUFFIX):
        return None
    named = parent / sha256[:SET_NAME_CHARS]
    candidates = [named] if named.is_dir() else []
    candidates += sorted(
        p for p in parent.iterdir() if p.is_dir() and p != named and not p.name.startswith(".")
    )
    for folder in candidates:
        try:
            manifest = json.loads((folder / MANIFEST_NAME).read_text(encoding="utf-8"))
        except (OSError, ValueError):
            continue
        if content_sha256(manifest) == sha256 or sha256_file(folder / MANIFEST_NAME) == sha256:
            try:
                found = load_stimuli(folder)
            except StimuliError:
                return None
            _SETS[key] = found
            return found
    return None
