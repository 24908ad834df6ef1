"""Loading scenes: BVH/glTF/FBX files or a scene manifest → :class:`~snapcore.motion.scene.Scene`.

This is the I/O edge of the motion core. ``load_scene`` accepts

- one or more BVH, skinned glTF/GLB or FBX paths (several files = one multi-character
  scene sharing a world frame, e.g. a two-person capture; glTF characters carry their
  own mesh, :mod:`snapcore.motion.gltf`, and so do FBX characters with a skinned mesh,
  :mod:`snapcore.motion.fbx`), or
- one scene manifest (``.toml`` or ``.json``, schema ``data_schema/scene.schema.json``)
  naming files with per-character offset, yaw, fps and scale, the ground height and
  optional props.

Real data lives outside the repository; :func:`data_dir` finds it (``SNAPSHOT_DATA``,
else ``../shared/motions`` beside the checkout or the working directory).
"""

from __future__ import annotations

import os
import warnings
from collections.abc import Sequence
from pathlib import Path
from typing import Any, Literal, cast, overload

import numpy as np

from snapcore.errors import SceneError
from snapcore.motion.bvh import BVHDocument, read_bvh, split_roots
from snapcore.motion.fbx import FBX_SUFFIXES, fbx_characters, fbx_unit, read_fbx, still_fbx
from snapcore.motion.gltf import (
    GLTF_SUFFIXES,
    MAX_HEIGHT_M,
    gltf_characters,
    gltf_unit,
    lowest_points,
    read_gltf,
)
from snapcore.motion.scene import (
    Z_UP_TO_Y_UP,
    Character,
    Scene,
    character_from_bvh,
    infer_scale,
    stands_along_z,
    stature_units,
    tpose_lead_in,
)

__all__ = ["load_scene", "data_dir", "resolve_data_path", "MANIFEST_SUFFIXES", "infer_ground"]

MANIFEST_SUFFIXES = (".toml", ".json")


#: Statures (in file units) of characters loaded together that differ by more than
#: this factor are taken for files in different units: a child and an adult differ by
#: less than 1.8x; the shared motion files' units differ by 20x and more.
MAX_STATURE_RATIO = 2.0
#: A BVH root with fewer joints (end sites not counted) is a prop, not a person: the
#: scene's unit is inferred from the people alone.
MIN_PERSON_JOINTS = 5


def _warn_unit_mismatch(probes: Sequence[Character], statures: Sequence[float]) -> None:
    """Warn when characters that will share one scale look like different units."""
    s = np.asarray(statures, float)
    if s.size < 2 or not np.all(np.isfinite(s) & (s > 0)):
        return
    if s.max() / s.min() > MAX_STATURE_RATIO:
        hi, lo = int(np.argmax(s)), int(np.argmin(s))
        warnings.warn(
            f"characters '{probes[hi].name}' and '{probes[lo].name}' differ {s.max() / s.min():.0f}x "
            "in size in their files' units: the files probably use different units, but one "
            "scale is shared; give each character its own `scale` in a scene manifest",
            stacklevel=4,
        )


@overload
def data_dir(required: Literal[True]) -> Path: ...
@overload
def data_dir(required: bool = False) -> Path | None: ...
def data_dir(required: bool = False) -> Path | None:
    """Folder of the real motion data.

    ``$SNAPSHOT_DATA`` if set, else the first existing of ``<repo>/../shared/motions`` and
    ``./../shared/motions``. Returns None (or raises :class:`SceneError` if
    ``required``) when there is none.
    """
    env = os.environ.get("SNAPSHOT_DATA")
    candidates = [Path(env)] if env else []
    here = Path(__file__).resolve().parent.parent
    candidates += [here.parent / "shared" / "motions", Path.cwd().parent / "shared" / "motions"]
    for c in candidates:
        if c.is_dir():
            return c
    if required:
        raise SceneError(
            "no motion data folder: set SNAPSHOT_DATA to the folder holding the BVH files "
            "(e.g. ../shared/motions)"
        )
    return None


def resolve_data_path(name: str | Path, base: Path | None = None) -> Path:
    """Resolve a file named in a manifest: as given, relative to ``base``, then to the data dir."""
    p = Path(name).expanduser()
    if p.is_absolute():
        return p
    tried = []
    if base is not None:
        tried.append(base / p)
    d = data_dir()
    if d is not None:
        tried.append(d / p)
    tried.append(p)
    for t in tried:
        if t.exists():
            return t
    return tried[0]


def infer_ground(positions: list[np.ndarray]) -> float:
    """Ground height (metres): 5th percentile over frames of the lowest joint.

    A percentile, not the minimum, so one noisy frame (a foot through the floor) does
    not move the floor; frames in the air do not lift it either.
    """
    lowest = np.min([x[..., 1].min(axis=1) for x in positions], axis=0)  # (F,)
    return float(np.percentile(lowest, 5))


def load_scene(
    paths_or_manifest: str | os.PathLike[str] | Sequence[str | os.PathLike[str]],
    *,
    fps: float | None = None,
    scale: float | None = None,
    ground: float | None = None,
    drop_tpose: bool | None = None,
    name: str | None = None,
    animation: str | None = None,
) -> Scene:
    """Load a scene from BVH files or a scene manifest.

    Parameters
    ----------
    paths_or_manifest : str, path-like, or sequence of them
        BVH file(s), or a single ``.toml``/``.json`` scene manifest.
    fps : float, optional
        Frame rate override for every character (beats the files and the manifest).
    scale : float, optional
        Metres per file unit for every character; inferred from stature when absent.
    ground : float, optional
        Ground height in metres; inferred from the lowest joints when absent.
    drop_tpose : bool, optional
        Drop an added T-pose first frame (default True, or the manifest's value).
    name : str, optional
        Scene name (default: the manifest's name or the first file's stem).
    animation : str, optional
        The animation of every glTF or FBX character (name or index; default each entry's
        ``animation``, else the file's first).

    Returns
    -------
    Scene

    Raises
    ------
    BVHError, GLTFError, FBXError, SchemaError, SceneError
        With a one-line message naming the file and what is wrong.

    Examples
    --------
    A BVH file of the synthetic jump, 3 s at 30 fps from the first frame to the last:

    >>> import tempfile
    >>> from pathlib import Path
    >>> from snapcore import load_scene
    >>> from snapcore.motion.bvh import write_bvh
    >>> from snapcore.motion.synth import humanoid_document
    >>> with tempfile.TemporaryDirectory() as folder:
    ...     path = Path(folder) / "jump.bvh"
    ...     write_bvh(humanoid_document("jump", fps=30.0), path)
    ...     scene = load_scene(path)
    >>> scene.name, scene.n_frames, scene.fps, len(scene.characters)
    ('jump', 91, 30.0, 1)
    """
    if isinstance(paths_or_manifest, (str, os.PathLike)):
        items = [paths_or_manifest]
    else:
        items = list(paths_or_manifest)
    if not items:
        raise SceneError("no input files given")
    paths = [Path(p) for p in items]
    manifests = [p for p in paths if p.suffix.lower() in MANIFEST_SUFFIXES]
    if manifests:
        if len(paths) > 1:
            raise SceneError(
                f"{manifests[0]}: give either one scene manifest or BVH files, not both"
            )
        # imported here: jsonschema is only needed for manifests, and finding files
        # (resolve_data_path, e.g. a `snapshot batch` re-run) should not pay for it
        from snapcore.schema import read_document

        spec = read_document(manifests[0], "scene")
        base = manifests[0].resolve().parent
    else:
        spec = {"characters": [{"file": str(p)} for p in paths]}
        base = None
    return _build(
        spec,
        base,
        fps=fps,
        scale=scale,
        ground=ground,
        drop_tpose=drop_tpose,
        name=name,
        source=str(manifests[0]) if manifests else None,
        animation=animation,
    )


def _kind(path: Path) -> str:
    """How a character file is read, by its suffix (the one dispatch by extension)."""
    suffix = Path(path).suffix.lower()
    return "gltf" if suffix in GLTF_SUFFIXES else "fbx" if suffix in FBX_SUFFIXES else "bvh"


def _build(
    spec: dict[str, Any],
    base: Path | None,
    *,
    fps: float | None,
    scale: float | None,
    ground: float | None,
    drop_tpose: bool | None,
    name: str | None,
    source: str | None,
    animation: str | None,
) -> Scene:
    docs: list[BVHDocument | None] = []  # None: a glTF or FBX character, read by its entry
    paths, entries, kinds = [], [], []
    for e in spec["characters"]:
        path = resolve_data_path(e["file"], base)
        if not path.exists():
            where = f"{source}: " if source else ""
            raise SceneError(f"{where}{e['file']}: no such file")
        kind = _kind(path)
        if kind != "bvh":
            # one character per skeleton of the file, named after it when there are more
            roots = gltf_characters(path) if kind == "gltf" else fbx_characters(path)
            for k, root in enumerate(roots):
                paths.append(path)
                docs.append(None)
                kinds.append(kind)
                entries.append(
                    e
                    if len(roots) == 1
                    else {**e, "name": f"{e.get('name') or path.stem}_{root}", "_character": k}
                )
            continue
        parts: list[BVHDocument | None] = list(split_roots(read_bvh(path)))
        for d in parts:
            paths.append(path)
            docs.append(d)
            kinds.append("bvh")
            # one character per ROOT, named after the file (or the entry) and its root
            entries.append(
                e
                if d is None or len(parts) == 1
                else {**e, "name": f"{e.get('name') or path.stem}_{d.names[0]}"}
            )
    # Forward kinematics once, in file units; positions scale linearly afterwards.
    bvh_fps = [d.fps for d in docs if d is not None]
    probes = []
    for d, e, path, kind in zip(docs, entries, paths, kinds):
        rate = fps or e.get("fps") or spec.get("fps")
        if d is None:  # glTF, FBX: sampled at the BVH characters' rate when mixed with them
            reader = read_gltf if kind == "gltf" else read_fbx
            probes.append(
                reader(
                    path,
                    animation=animation or e.get("animation"),
                    fps=rate or (round(bvh_fps[0]) if bvh_fps else None),
                    name=e.get("name"),
                    character=e.get("_character"),
                )
            )
        else:
            c = character_from_bvh(d, scale=1.0, name=e.get("name"), fps=rate)
            if stands_along_z(c.skeleton, c.positions):
                warnings.warn(
                    f"{path}: written Z up (its skeleton stands along +Z, at rest and "
                    "in the motion); read turned to Y up",
                    stacklevel=3,
                )
                c = c.transformed(rotation=Z_UP_TO_Y_UP)
            probes.append(c)
    is_gltf = [k == "gltf" for k in kinds]
    is_fbx = [k == "fbx" for k in kinds]
    # FBX takes that move nothing are no animation: refused
    still_fbx([p for p, fb in zip(probes, is_fbx) if fb])
    # One scale for the scene unless given per character: people captured together
    # must keep their distances. glTF is in metres (its own rule, gltf_unit).
    scene_scale = scale or spec.get("scale")
    how = "given"
    bvh_probes = [p for p, k in zip(probes, kinds) if k == "bvh"]
    if (
        scene_scale is None
        and bvh_probes
        and not all("scale" in e for e, k in zip(entries, kinds) if k == "bvh")
    ):
        # props (a ball: a root with a joint or two) do not say what the unit is
        people = [p for p in bvh_probes if np.sum(~p.skeleton.end_site) >= MIN_PERSON_JOINTS]
        people = people or bvh_probes
        statures = [stature_units(p.skeleton, p.positions) for p in people]
        _warn_unit_mismatch(people, statures)
        scene_scale, how = infer_scale(statures)
        if how == "fitted":
            warnings.warn(
                f"no standard unit makes these characters adult-sized; scaled to a mean "
                f"stature of 1.70 m ({scene_scale:.4g} m per unit). Pass --scale to override.",
                stacklevel=3,
            )
    chars: list[Character] = []
    used_names: set[str] = set()
    for probe, e, g, fb in zip(probes, entries, is_gltf, is_fbx):
        if fb and not (scale or e.get("scale") or spec.get("scale")):
            metres, unit, why = fbx_unit(probe)
            if why:
                warnings.warn(why, stacklevel=3)
            c = probe.rescaled(metres)
            c.meta["unit"] = unit
        elif g and not (scale or e.get("scale") or spec.get("scale")):
            metres, unit = gltf_unit(probe)
            c = probe.rescaled(metres)
            c.meta["unit"] = unit
            if unit != "m":
                warnings.warn(
                    f"{probe.meta['path']}: read in {unit}, not in metres as glTF "
                    f"specifies: in metres '{probe.name}' would be taller than "
                    f"{MAX_HEIGHT_M:g} m. Pass --scale to override.",
                    stacklevel=3,
                )
        else:
            # a BVH without a scene scale has its own (the check above)
            c = probe.rescaled(cast(float, scale or e.get("scale") or scene_scale))
            c.meta["unit"] = how if not (scale or e.get("scale")) else "given"
        if c.name in used_names:
            c.name = f"{c.name}_{len(chars)}"
        used_names.add(c.name)
        if e.get("yaw") or e.get("offset"):
            c = c.transformed(yaw_deg=e.get("yaw", 0.0), offset=e.get("offset", (0.0, 0.0, 0.0)))
        chars.append(c)
    rates = {round(c.fps, 6) for c in chars}
    if len(rates) != 1:
        raise SceneError(
            "characters have different frame rates ("
            + ", ".join(f"{c.name}: {c.fps:g}" for c in chars)
            + "); set one fps in the manifest or with --fps"
        )
    counts = {c.n_frames for c in chars}
    if len(counts) != 1:
        n = min(counts)
        warnings.warn(
            "characters have different frame counts ("
            + ", ".join(f"{c.name}: {c.n_frames}" for c in chars)
            + f"); keeping the first {n} frames of each",
            stacklevel=3,
        )
        chars = [c.frames(0, n) for c in chars]
    offset, why_cut = 0, ""
    start, stop = spec.get("frames", (0, None))
    if start or stop is not None:
        n = chars[0].n_frames
        if stop is not None and stop > n:
            warnings.warn(
                f"{source or 'scene'}: frames [{start}, {stop}) runs past the motion's "
                f"{n} frames; keeping [{start}, {n})",
                stacklevel=3,
            )
        stop = n if stop is None else min(stop, n)
        if not 0 <= start < stop:
            raise SceneError(
                f"{source or 'scene'}: frames [{start}, {stop}) is empty (the motion has {n} frames)"
            )
        chars = [c.frames(start, stop) for c in chars]
        offset = start
        why_cut = "the scene manifest's frames range starts there"
    drop = drop_tpose if drop_tpose is not None else spec.get("drop_tpose", True)
    if drop and offset == 0:
        # glTF animations have no added T-pose; BVH and FBX (skeleton takes, BVH
        # converted in Blender or MotionBuilder) are checked
        cut = tpose_lead_in([c.positions for c, g in zip(chars, is_gltf) if not g], chars[0].fps)
        if cut:
            chars = [c.frames(cut, c.n_frames) for c in chars]
            offset = cut
            why_cut = (
                "they are an added T-pose and the blend out of it "
                "(drop_tpose = false in a scene manifest keeps them)"
            )
    if chars[0].n_frames < 1:
        raise SceneError(f"{source or paths[0]}: no frames left to analyse")
    ground_y = ground if ground is not None else spec.get("ground")
    if ground_y is None:
        # a glTF character stands on its mesh (soles, paws), not on its joints
        ground_y = infer_ground(
            [lowest_points(c) if c.mesh is not None else c.positions for c in chars]
        )
    scene_name = name or spec.get("name") or chars[0].name
    return Scene(
        characters=chars,
        fps=chars[0].fps,
        ground=float(ground_y),
        name=scene_name,
        props=list(spec.get("props", [])),
        frame_offset=offset,
        meta={
            "source": source or list(dict.fromkeys(str(p) for p in paths)),
            "unit": how,
            **({"cut": why_cut} if offset else {}),
        },
    )
