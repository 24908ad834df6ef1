"""Building a stimulus set from a study config, and publishing it.

The builder runs one function per stage, so each can be tested and replaced alone:
:func:`load_study_scene` → :func:`~study_app.design.candidates.select_scene` →
:func:`~study_app.design.media.write_video` → :func:`~study_app.design.media.write_frames`
→ :func:`~study_app.design.media.write_views` (→
:func:`~study_app.design.candidates.replace_alike_views`: a baseline view whose picture is
nearly another candidate's is replaced, ``study.near_duplicate``) →
:func:`write_manifest`. A finished build becomes a content-addressed set
(:func:`publish_set`; the folder layout and the manifest are described in
:mod:`study_app.design.stimuli`).
"""

from __future__ import annotations

import json
import shutil
import time
import warnings
from datetime import UTC, datetime
from pathlib import Path

from snapcore.schema import validate
from snapcore.select.view_methods import VIEW_METHODS

from .candidates import (
    check_alike_pictures,
    check_near_duplicates,
    merge_alike_views,
    replace_alike_views,
    select_scene_snapshot,
)
from .media import view_renderer, write_frames, write_video, write_views
from .protocol import Study
from .stimuli import (
    MANIFEST_NAME,
    PICK_KEYS,
    SET_NAME_CHARS,
    SETS_SUFFIX,
    StimuliError,
    app_version,
    content_sha256,
    sha256_file,
)

__all__ = [
    "load_study_scene",
    "write_manifest",
    "build_stimuli",
    "publish_set",
]


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
    from snapcore.motion.fbx import FBX_SUFFIXES
    from snapcore.motion.gltf import GLTF_SUFFIXES
    from snapcore.motion.load import data_dir, load_scene, resolve_data_path
    from snapcore.schema import read_document

    work = Path(work_dir)
    work.mkdir(parents=True, exist_ok=True)
    base = study.base
    src_base: Path | None  # where the scene's files are named from (None: the data dir)
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
    if "animation" in entry:
        animated = GLTF_SUFFIXES + FBX_SUFFIXES
        # the animation (take) of every glTF/FBX character, as `--animation` does; a
        # scene manifest took it per character, a study config not at all (issue 40)
        moving = [c for c in doc["characters"] if Path(c["file"]).suffix.lower() in animated]
        if not moving:
            raise StimuliError(
                f"scene {entry['id']}: 'animation' names a glTF/GLB or FBX animation, "
                "and the scene has no such character"
            )
        for c in moving:
            c["animation"] = entry["animation"]
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
    picks, timings, snap = select_scene_snapshot(scene, study.selection)
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
        shown = {PICK_KEYS[m]: views[m.value]["direction"] for m in VIEW_METHODS}
        angles, dupes = check_near_duplicates(study, sc["id"], {**picks, **shown}, action="warn")
    merged = None
    if study.near_duplicate == "merge":
        # Alike pictures are shown once, standing for each method that proposed them.
        merged = merge_alike_views(study, scene, picks, views, dupes)
        ious, dupes = merged["view_iou"], merged["alike"]
    else:
        # Judged on the pictures themselves too: two views far apart in angle can still
        # show the same shape (a mirror image, a symmetric pose).
        ious, alike = check_alike_pictures(study, sc["id"], views)
        dupes = dupes + [p for p in alike if p not in dupes]
    t4 = time.perf_counter()
    keys = ("demo", "files", "manifest", "fps", "scale", "frames", "animation")
    source = {k: sc[k] for k in keys if k in sc}
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
        **(
            {}
            if merged is None
            else {k: merged[k] for k in ("shown", "pose_distance", "view_task")}
        ),
        "timings_s": {
            "load": t1 - t0,
            "select": t2 - t1,
            "video": t3 - t2,
            "views": t4 - t3,
            **{f"select_{k}": v for k, v in timings.items()},
        },
    }
