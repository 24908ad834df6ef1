"""Stimuli: the files participants see, built from a study config, and their manifest.

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

Stimulus sets are content-addressed and never rewritten: ``build_stimuli(study, OUT)``
writes the set into ``OUT.sets/<content hash>/`` and points ``OUT`` (a symbolic link)
at it. A rebuild makes a new set beside the old one (or reuses it when the content is
the same), so a study serving the old set (the server pins the folder ``OUT`` resolves
to at start) keeps serving it, and participants who started on it resume on it after
a restart (:func:`find_stimulus_set`). A set's identity, :func:`content_sha256`, is the
hash of its manifest without the build's record (time, app version, timings): the
files' own sha256 are in it, so it changes exactly when what participants see does.

The builder runs one function per stage, so each can be tested and replaced alone:
:func:`load_study_scene` → :func:`select_scene` → :func:`write_video` →
:func:`write_frames` → :func:`write_views` (→ :func:`replace_alike_views`: a baseline view
whose picture is nearly another candidate's is replaced, ``study.near_duplicate``) →
:func:`write_manifest`. Rendering uses
``snapcore.render.renderer`` (EGL, offline: see PLATFORM-NOTES, renderers do not cross threads).
"""

from __future__ import annotations

import hashlib
import json
import shutil
import time
import warnings
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import numpy as np

from snapcore.errors import SchemaError, SnapshotError
from snapcore.schema import validate
from snapcore.select.view_methods import VIEW_METHODS, ViewMethod

from .protocol import Study, study_from_dict
from .scenes import StudyScene
from .similarity import NEAR_DUPLICATE_IOU, candidate_ious

__all__ = [
    "MANIFEST_NAME",
    "default_stimuli_dir",
    "StimuliError",
    "SceneStimulus",
    "Stimuli",
    "sha256_file",
    "load_stimuli",
    "verify_stimuli",
    "build_stimuli",
    "load_study_scene",
    "select_scene",
    "write_video",
    "write_frames",
    "write_views",
    "write_manifest",
    "app_version",
    "candidate_angles",
    "check_near_duplicates",
    "content_sha256",
    "find_stimulus_set",
    "SETS_SUFFIX",
    "publish_set",
    "check_alike_pictures",
    "replace_alike_views",
    "view_renderer",
]

MANIFEST_NAME = "manifest.json"
_REPO = Path(__file__).resolve().parents[2]
#: JPEG quality of the pickable frames: visually lossless at study sizes, ~20 kB a frame.
FRAME_JPEG_QUALITY = 88
_HASH_CHUNK = 1 << 20
#: ``OUT`` links to ``OUT.sets/<content hash>/``, where every build of ``OUT`` is kept.
SETS_SUFFIX = ".sets"
#: Manifest fields that record how a build went, not what it shows: not in its identity.
BUILD_RECORD_FIELDS = ("created_at", "app_version")
SCENE_BUILD_RECORD_FIELDS = ("timings_s",)
#: Characters of the content hash that name a set's folder.
SET_NAME_CHARS = 16


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


# --------------------------------------------------------------------------- building


def load_study_scene(study: Study, entry: dict, work_dir: str | Path):
    """Stage 1: load one scene of the study (trimmed to its frame window).

    The entry's source (``demo``, ``files`` or ``manifest``) becomes a scene manifest
    written to ``work_dir/scene.json`` (the window as ``frames``), which
    :func:`snapcore.load_scene` reads; that file stays with the stimuli as provenance.
    So that it can be reloaded on another machine, a synthetic scene's BVH files are
    copied beside it, and files found in the motion data folder keep their path relative
    to it (resolved again through ``SNAPSHOT_DATA``); other files are named absolutely.

    Returns
    -------
    (Scene, dict)
        The scene and the manifest document that produced it.
    """
    from snapcore.motion.load import data_dir, load_scene, resolve_data_path
    from snapcore.schema import read_document

    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    base = study.base
    if "demo" in entry:
        doc = _demo_scene_document(entry["demo"], work.parent / ".demo")
        src_base = work.parent / ".demo"
    elif "manifest" in entry:
        mpath = resolve_data_path(entry["manifest"], base)
        doc = read_document(mpath, "scene")
        src_base = mpath.resolve().parent
    else:
        doc = {"characters": [{"file": f} for f in entry["files"]]}
        src_base = base
    doc = json.loads(json.dumps(doc))  # a private copy
    data = data_dir()
    for c in doc["characters"]:
        p = resolve_data_path(c["file"], src_base)
        if not p.exists():
            raise StimuliError(
                f"scene {entry['id']}: {c['file']}: no such file (looked beside the "
                "study config and in SNAPSHOT_DATA)"
            )
        p = p.resolve()
        if "demo" in entry:
            shutil.copy2(p, work / p.name)
            c["file"] = p.name
        elif (
            data is not None
            and p.is_relative_to(data.resolve())
            and not (base is not None and (base / c["file"]).exists())
        ):
            c["file"] = p.relative_to(data.resolve()).as_posix()
        else:
            c["file"] = str(p)
    for key in ("fps", "scale", "frames"):
        if key in entry:
            doc[key] = entry[key]
    doc["name"] = entry["id"]
    spath = work / "scene.json"
    spath.write_text(json.dumps(doc, indent=2), encoding="utf-8")
    return load_scene(spath), doc


def _demo_scene_document(name: str, folder: Path) -> dict:
    """The scene manifest of synthetic demo scene ``name`` (written once into ``folder``)."""
    from snapcore.motion import synth
    from snapcore.schema import read_document

    folder.mkdir(parents=True, exist_ok=True)
    written = [Path(p) for p in synth.write_demo(folder)]
    manifests = {p.stem.split(".")[0]: p for p in written if p.suffix in (".toml", ".json")}
    if name in manifests:
        return read_document(manifests[name], "scene")
    bvhs = {p.stem: p for p in written if p.suffix == ".bvh"}
    if name in bvhs:
        return {"characters": [{"file": str(bvhs[name])}]}
    raise StimuliError(
        f"no synthetic demo scene '{name}' (have: {', '.join(sorted(set(manifests) | set(bvhs)))})"
    )


def select_scene(scene, options: dict | None = None) -> tuple[dict, dict]:
    """Stage 2: the pose and the three view directions.

    Returns
    -------
    (picks, timings) : tuple of dict
        ``picks``: ``frame`` and ``frames`` (source numbering) of the config's pose
        method (``selection.pose_method``, named in ``pose_method``), every selector's
        top-3 in ``by_method``, ``view`` (ours),
        ``viewpoint_entropy`` and ``motion_area`` (unit vectors, world frame).
        ``timings``: seconds per stage of the selection.
    """
    picks, timings, _ = _select(scene, options)
    return picks, timings


def _select(scene, options: dict | None = None):
    """:func:`select_scene`, and the snapshot it came from (the baselines' scored views,
    for replacing a view whose picture is nearly another's)."""
    from snapcore.pipeline import snapshot_params, take_snapshot

    try:
        pose, view = snapshot_params(options or {})
    except ValueError as err:
        raise StimuliError(f"study config [selection]: {err}") from None
    snap = take_snapshot(scene, pose=pose, view=view)
    views = snap.views
    missing = [m for m in VIEW_METHODS if m not in views]
    if missing:
        raise StimuliError(
            f"scene {scene.name}: the selection gave no {', '.join(missing)} "
            "view (a baseline was skipped: see the warning above)"
        )
    picks = {
        "frame": snap.frame,
        "frames": snap.frames,
        "pose_method": snap.pose.method,
        "by_method": _picks_by_method(scene),
    }
    picks.update({_PICK_KEYS[m]: _unit(views[m]) for m in VIEW_METHODS})
    timings = {k: float(v) for k, v in snap.timings_s.items()}
    return picks, timings, snap


def _picks_by_method(scene, k: int = 3) -> dict:
    """Every pose selector's top-k frames (source numbering), for the analysis to
    compare with what people choose."""
    import warnings

    from snapcore import select_pose
    from snapcore.select.pose_methods import POSE_METHODS

    out = {}
    for m in POSE_METHODS:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            sel = select_pose(scene, method=m, k=k)
        out[m] = [int(scene.source_frame(i)) for i in sel.indices]
    return out


#: The manifest's ``picks`` key of each method's view (ours is ``view``, as in
#: ``snapshot select --json``; the baselines by their method name).
_PICK_KEYS = {m: "view" if m is ViewMethod.OURS else m.value for m in VIEW_METHODS}


def candidate_angles(picks: dict, *, threshold_deg: float) -> tuple[dict, list]:
    """Angles between the three candidate views and the pairs that are near-duplicates.

    Returns
    -------
    (angles, pairs) : (dict of str to float, list of [str, str])
        ``{"ours|viewpoint_entropy": degrees, ...}`` and the pairs that are under
        ``threshold_deg`` apart or over ``180 - threshold_deg`` (mirror images).
    """
    from snapcore.select.view import near_duplicate_views, view_angles_deg

    angles = view_angles_deg({m.value: picks[_PICK_KEYS[m]] for m in VIEW_METHODS})
    angles = {k: round(v, 2) for k, v in angles.items()}
    return angles, [list(p) for p in near_duplicate_views(angles, threshold_deg)]


def check_near_duplicates(
    study: Study, scene_id: str, picks: dict, *, action: str | None = None
) -> tuple[dict, list]:
    """The candidates' pairwise angles and near-duplicates, acted on as the study says.

    ``study.near_duplicate == "warn"`` warns (the build goes on; the manifest records the
    pairs and the analysis reports them); ``"error"`` raises :class:`StimuliError`;
    ``"replace"`` only reports them: the pictures decide (:func:`replace_alike_views`).
    ``action`` overrides the study's (the builder warns about pairs left after
    replacing).

    Returns
    -------
    (angles, pairs)
        As :func:`candidate_angles`.
    """
    action = action or study.near_duplicate
    angles, dupes = candidate_angles(picks, threshold_deg=study.near_duplicate_deg)
    if dupes and action != "replace":
        report = ", ".join(f"{k.replace('|', '/')} {v:.1f}°" for k, v in angles.items())
        which = "; ".join(f"{a} and {b} ({angles[f'{a}|{b}']:.1f}° apart)" for a, b in dupes)
        text = (
            f"nearly the same picture from {which} "
            f"(threshold {study.near_duplicate_deg:g}°; all pairs: {report})"
        )
        if action == "error":
            raise StimuliError(
                f"scene {scene_id}: {text}; set study.near_duplicate = "
                '"replace" (the default) or "warn" to build anyway'
            )
        warnings.warn(
            text + ": votes may split between them (the analysis reports it)", stacklevel=3
        )
    return angles, dupes


def check_alike_pictures(study: Study, scene_id: str, views: dict) -> tuple[dict, list]:
    """The candidates' silhouette IoUs and the pairs at or above
    :data:`NEAR_DUPLICATE_IOU`, acted on as the study's ``near_duplicate`` says (as
    :func:`check_near_duplicates`, with the measure in the message)."""
    ious = candidate_ious(views)
    pairs = [k.split("|") for k, v in ious.items() if v >= NEAR_DUPLICATE_IOU]
    if pairs:
        which = "; ".join(
            f"{a} and {b} (silhouette IoU {ious[f'{a}|{b}']:.2f}, mirror images included)"
            for a, b in pairs
        )
        text = (
            f"nearly the same picture from {which} (threshold IoU "
            f"{NEAR_DUPLICATE_IOU:g}; all pairs: "
            + ", ".join(f"{k.replace('|', '/')} {v:.2f}" for k, v in ious.items())
            + ")"
        )
        if study.near_duplicate == "error":
            raise StimuliError(
                f"scene {scene_id}: {text}; set study.near_duplicate = "
                '"replace" (the default) or "warn" to build anyway'
            )
        warnings.warn(
            text + ": votes may split between them (the analysis reports it)", stacklevel=3
        )
    return ious, pairs


def replace_alike_views(
    study: Study, scene_id: str, snap, picks: dict, views: dict, *, renderer=None
) -> tuple[dict, list]:
    """Replace each baseline view whose picture is nearly an earlier candidate's by that
    baseline's best-scoring view whose picture is not (:mod:`study_app.design.replacement`).

    Parameters
    ----------
    study : Study
        Its ``near_duplicate_deg`` is the angle around kept views skipped unrendered.
    scene_id : str
    snap : snapcore.pipeline.Snapshot
        The selection the picks came from (the baselines' scored views).
    picks : dict
        :func:`select_scene`'s picks (the frame).
    views : dict
        :func:`write_views`'s pictures; replaced ones are rewritten in place and their
        ``direction`` updated.
    renderer : SceneRenderer, optional
        The one :func:`write_views` used (:func:`view_renderer`).

    Returns
    -------
    (views, replacements) : (dict, list of dict)
        The views as shown, and one record per replaced view
        (:meth:`~study_app.design.replacement.Replacement.to_dict`).

    Raises
    ------
    StimuliError
        A baseline has no view unlike the others within the bound (scene, method and
        IoU named).
    """
    import imageio.v3 as iio

    from snapcore.render.renderer import save_png

    from .replacement import NoReplacement, find_replacement, ranked_views

    scene = snap.scene
    renderer = renderer or view_renderer(scene, study.size)
    frame = int(picks["frame"]) - scene.frame_offset

    def render(direction) -> np.ndarray:
        return _render_view(scene, frame, direction, renderer)

    def picture(m: str) -> np.ndarray:
        return np.asarray(iio.imread(views[m]["file"]))[..., :3]

    kept = {ViewMethod.OURS.value: (views["ours"]["direction"], picture("ours"))}
    out = []
    for m in VIEW_METHODS[1:]:
        try:
            found, pic = find_replacement(
                m.value,
                views[m.value]["direction"],
                picture(m.value),
                kept,
                ranked_views(snap, m),
                render,
                exclude_deg=study.near_duplicate_deg,
            )
        except NoReplacement as err:
            raise StimuliError(f"scene {scene_id}: {err}") from None
        if found is not None and pic is not None:
            save_png(pic, views[m.value]["file"])
            views[m.value] = {**views[m.value], "direction": _unit(found.replacement)}
            out.append(found.to_dict())
        kept[m.value] = (views[m.value]["direction"], picture(m.value))
    return views, out


def _unit(v) -> list[float]:
    a = np.asarray(v, dtype=float).reshape(3)
    return (a / np.linalg.norm(a)).tolist()


def write_video(
    scene,
    path: str | Path,
    *,
    fps: float,
    size: tuple[int, int],
    view=None,
    progress: bool = False,
    webm: str | Path | None = None,
) -> list[int]:
    """Stage 3: the animation video; returns the motion frame (source numbering) per video frame.

    ``webm``: also write the same frames as WebM/VP9 there (for browsers without H.264).

    ``view=None`` films from the renderer's neutral default (3/4 front of the
    characters' facing, slightly above): not from any of the three candidate views,
    so the video does not make one of them look familiar in the view task.
    """
    from snapcore.render.bodies import DEFAULT_BODY
    from snapcore.render.video import render_video

    # the study shows the default body everywhere (videos, views, and the
    # viewpoint-entropy baseline, ViewParams' default): no config option changes it
    vmap = render_video(
        scene, path, fps=fps, size=size, view=view, progress=progress, webm=webm, body=DEFAULT_BODY
    )
    return [int(m) for m in np.asarray(vmap, dtype=int)]


def write_frames(video: str | Path, folder: str | Path) -> list[Path]:
    """Stage 4: decode the video into one JPEG per frame (what the picker shows).

    Decoding the written video (instead of rendering again) makes each image exactly
    the frame the participant sees in the player.
    """
    import imageio.v3 as iio
    from PIL import Image

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    paths = []
    for i, frame in enumerate(
        iio.imiter(video, plugin="pyav") if _has_pyav() else iio.imiter(video)
    ):
        p = out / f"{i:05d}.jpg"
        Image.fromarray(np.asarray(frame)[..., :3]).save(p, quality=FRAME_JPEG_QUALITY)
        paths.append(p)
    if not paths:
        raise StimuliError(f"{video}: the video has no frames")
    return paths


def _has_pyav() -> bool:
    try:
        import av  # noqa: F401
    except ImportError:
        return False
    return True


def view_renderer(scene, size: tuple[int, int]):
    """The renderer of the candidate pictures: no floor and no shadows (see
    :func:`write_views`)."""
    from snapcore.render.bodies import DEFAULT_BODY
    from snapcore.render.renderer import SceneRenderer

    return SceneRenderer(scene, size=size, ground=False, shadows=False, body=DEFAULT_BODY)


def _render_view(scene, frame: int, direction, renderer) -> np.ndarray:
    """One candidate picture (internal ``frame``), framed as all candidates are."""
    from snapcore.render.renderer import render_still

    return render_still(scene, frame, direction, fit="frame", renderer=renderer)


def write_views(
    scene, picks: dict, folder: str | Path, *, size: tuple[int, int], renderer=None
) -> dict:
    """Stage 5: the selected pose seen along each method's direction (same size and framing).

    Returns
    -------
    dict
        ``{method: {"file": Path, "direction": [x, y, z]}}`` for each of
        :data:`~snapcore.select.view_methods.VIEW_METHODS`.
    """
    from snapcore.render.renderer import save_png

    out = Path(folder)
    out.mkdir(parents=True, exist_ok=True)
    directions = {m: picks[_PICK_KEYS[m]] for m in VIEW_METHODS}
    frame = int(picks["frame"]) - scene.frame_offset
    # Same size and the same framing rule for all three (the pose fitted tightly with
    # the same margin from each direction), so no view wins by being bigger. No floor
    # and no shadows: a tightly framed orthographic view shows the floor grid from
    # above, nothing of it near the horizon and the grid through the legs from below
    # (the methods may pick views down to 10 degrees under the horizon), so the
    # background alone would tell the three methods apart.
    renderer = renderer or view_renderer(scene, size)
    views = {}
    for m in VIEW_METHODS:
        p = out / f"view_{m}.png"
        save_png(_render_view(scene, frame, directions[m], renderer), p)
        views[m.value] = {"file": p, "direction": directions[m]}
    return views


def write_manifest(folder: str | Path, study: Study, scenes: list[dict]) -> Path:
    """Stage 6: hash every file the scenes use and write ``manifest.json``.

    Parameters
    ----------
    folder : path
        The stimuli folder.
    study : Study
    scenes : list of dict
        Scene entries whose file fields (``video``, ``frames``, ``views[*].file`` and
        ``scene_file``) may be absolute paths inside ``folder``; they are written
        relative.

    Returns
    -------
    Path
        The manifest.
    """
    root = Path(folder).resolve()
    files: dict[str, str] = {}

    def rel(p) -> str:
        p = Path(p)
        r = (p if p.is_absolute() else root / p).resolve().relative_to(root).as_posix()
        files[r] = sha256_file(root / r)
        return r

    out = []
    for e in scenes:
        e = dict(e)
        e["video"] = rel(e["video"])
        if e.get("video_webm") is not None:
            e["video_webm"] = rel(e["video_webm"])
        e["frames"] = [rel(f) for f in e["frames"]]
        e["views"] = {m: {**v, "file": rel(v["file"])} for m, v in e["views"].items()}
        if "scene_file" in e:
            e.setdefault("source", {})["scene_file"] = rel(e.pop("scene_file"))
        out.append(e)
    manifest = {
        "format": "action-snapshot-stimuli",
        "version": 1,
        "created_at": datetime.now(UTC).isoformat(timespec="seconds"),
        "app_version": app_version(),
        "study": study.to_dict(),
        "scenes": out,
        "files": dict(sorted(files.items())),
    }
    validate(manifest, "stimuli", source=str(root / MANIFEST_NAME))
    path = root / MANIFEST_NAME
    path.write_text(json.dumps(manifest, indent=1), encoding="utf-8")
    return path


def build_stimuli(
    study: Study, out_dir: str | Path, *, force: bool = False, quiet: bool = False
) -> Path:
    """Build every scene's stimuli into ``out_dir`` and write the manifest.

    The build goes to ``<out_dir>.partial``; when complete it becomes the set
    ``<out_dir>.sets/<content hash>/`` (kept if a build with the same content exists)
    and ``out_dir`` is made a link to it in one step. An interrupted build never leaves
    a folder that looks usable, and the sets of earlier builds stay, untouched, for the
    studies and participants that use them.

    Parameters
    ----------
    study : Study
    out_dir : path
    force : bool
        Point an existing ``out_dir`` at the new build (its earlier sets are kept).
    quiet : bool
        No progress bar.

    Returns
    -------
    Path
        ``out_dir / "manifest.json"``.
    """
    from tqdm.auto import tqdm

    # Not resolved: OUT is a link to the set it shows, and the link is what moves.
    out = Path(out_dir).absolute()
    if (out.exists() or out.is_symlink()) and not force:
        raise StimuliError(f"{out} already exists (use --force to rebuild it)")
    tmp = out.with_name(out.name + ".partial")
    if tmp.exists():
        shutil.rmtree(tmp)
    tmp.mkdir(parents=True)
    entries = []
    bar = tqdm(study.scenes, desc="stimuli", unit="scene", disable=quiet)
    for sc in bar:
        bar.set_postfix_str(sc["id"])
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            entries.append(_build_scene(study, sc, tmp))
        for w in caught:  # say which scene a warning is about
            warnings.warn(f"scene {sc['id']}: {w.message}", w.category, stacklevel=2)
    write_manifest(tmp, study, entries)
    shutil.rmtree(tmp / ".demo", ignore_errors=True)
    return publish_set(tmp, out)


def publish_set(built: str | Path, out: str | Path) -> Path:
    """Make the finished build ``built`` (a folder with its manifest) the set that
    ``out`` shows: moved to ``<out>.sets/<content hash>/`` (or dropped when a set with
    that content exists: that one is kept as it is), then ``out`` re-pointed in one
    step. Returns ``out / "manifest.json"``."""
    built, out = Path(built), Path(out).absolute()
    sets = out.with_name(out.name + SETS_SUFFIX)
    digest = content_sha256(json.loads((built / MANIFEST_NAME).read_text(encoding="utf-8")))
    sets.mkdir(parents=True, exist_ok=True)
    final = sets / digest[:SET_NAME_CHARS]
    if final.exists():
        shutil.rmtree(built)
    else:
        built.rename(final)
    _point(out, final)
    return out / MANIFEST_NAME


def _point(out: Path, final: Path) -> None:
    """Make ``out`` a link to the set ``final`` in one step (a reader sees the old set or
    the new one, never a half-written folder). A real folder at ``out`` (a build of an
    earlier version) is kept among the sets, under its own hash."""
    if out.is_dir() and not out.is_symlink():
        try:
            old = content_sha256(json.loads((out / MANIFEST_NAME).read_text(encoding="utf-8")))
            kept = final.parent / old[:SET_NAME_CHARS]
        except (OSError, ValueError):
            kept = final.parent / f"old-{time.time_ns()}"
        if kept.exists():
            shutil.rmtree(out)
        else:
            out.rename(kept)
    link = out.with_name(f".{out.name}.link-{time.time_ns()}")
    link.symlink_to(Path(final.parent.name) / final.name, target_is_directory=True)
    link.replace(out)


def _build_scene(study: Study, sc: dict, root: Path) -> dict:
    folder = root / sc["id"]
    t0 = time.perf_counter()
    scene, doc = load_study_scene(study, sc, folder)
    t1 = time.perf_counter()
    picks, timings, snap = _select(scene, study.selection)
    angles, dupes = check_near_duplicates(study, sc["id"], picks)
    t2 = time.perf_counter()
    vmap = write_video(
        scene,
        folder / "video.mp4",
        fps=study.video_fps,
        size=study.size,
        webm=folder / "video.webm",
    )
    frames = write_frames(folder / "video.mp4", folder / "frames")
    if len(frames) != len(vmap):
        raise StimuliError(
            f"scene {sc['id']}: the video decodes to {len(frames)} frames but the "
            f"renderer reported {len(vmap)}"
        )
    t3 = time.perf_counter()
    renderer = view_renderer(scene, study.size)
    views = write_views(scene, picks, folder, size=study.size, renderer=renderer)
    replacements: list = []
    if study.near_duplicate == "replace":
        views, replacements = replace_alike_views(
            study, sc["id"], snap, picks, views, renderer=renderer
        )
        # The record describes the views shown (the picks keep each method's own).
        shown = {_PICK_KEYS[m]: views[m.value]["direction"] for m in VIEW_METHODS}
        angles, dupes = check_near_duplicates(study, sc["id"], {**picks, **shown}, action="warn")
    # Judged on the pictures themselves too: two views far apart in angle can still
    # show the same shape (a mirror image, a symmetric pose).
    ious, alike = check_alike_pictures(study, sc["id"], views)
    dupes = dupes + [p for p in alike if p not in dupes]
    t4 = time.perf_counter()
    source = {k: sc[k] for k in ("demo", "files", "manifest", "fps", "scale", "frames") if k in sc}
    return {
        "id": sc["id"],
        "title": sc.get("title", sc["id"]),
        "source": source,
        "scene_file": folder / "scene.json",
        "fps": float(scene.fps),
        "n_frames": int(scene.n_frames),
        "frame_offset": int(scene.frame_offset),
        "video": folder / "video.mp4",
        "video_webm": folder / "video.webm",
        "video_fps": float(study.video_fps),
        "size": list(study.size),
        "video_to_motion": vmap,
        "frames": frames,
        "picks": picks,
        "views": views,
        "view_angles": angles,
        "near_duplicates": dupes,
        "view_iou": ious,
        "replacements": replacements,
        "timings_s": {
            "load": t1 - t0,
            "select": t2 - t1,
            "video": t3 - t2,
            "views": t4 - t3,
            **{f"select_{k}": v for k, v in timings.items()},
        },
    }
