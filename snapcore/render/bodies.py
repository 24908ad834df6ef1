"""Which body each character wears, merged into one posable scene mesh.

Every picture, video, stimulus, contact sheet, relief and the viewpoint-entropy baseline
gets its mesh from :func:`scene_body`. The *body kind* (:data:`BodyKind`) is a render
option, not scene data: each public entry point that draws or measures the body takes
one keyword, ``body=`` (default :data:`DEFAULT_BODY`), and hands it down to
:func:`scene_body` — :func:`~snapcore.render.renderer.render_still`,
:class:`~snapcore.render.renderer.SceneRenderer`,
:func:`~snapcore.render.video.render_video`,
:func:`~snapcore.render.composites.contact_sheet`,
:func:`~snapcore.render.composites.compare_views`,
:func:`~snapcore.relief.scene.relief_from_scene`,
:func:`~snapcore.render.viewpoint_entropy.select_view_entropy` and
:func:`~snapcore.render.view_plot.view_maps`; the pipeline's view stage reads it from
``ViewParams.body``. One keyword at the entry points rather than a field on the scene:
the same loaded scene can be drawn both ways (docs/method.md's comparison, a batch run with
``--body``), nothing about the motion changes, and a copy or cut of a scene cannot
silently lose or keep the option. Below the entry points the built body object travels
(``SceneRenderer(body=...)`` also takes one, :func:`~snapcore.render.camera.motion_points`
reads it), so no other function needs the keyword. The CLI's ``--body`` and the batch's
``BatchOptions.body`` give it.

- ``"human"``: a glTF character wears its own skinned mesh (:class:`SkinnedBody`,
  ``Character.mesh``); a BVH skeleton wears the MakeHuman body retargeted onto it
  (:class:`snapcore.render.human.HumanBody`); a skeleton the retargeting cannot map
  falls back to the mannequin, with a warning naming what is missing and the joints no
  role was found for;
- ``"mannequin"``: capsules and spheres on the joints for everyone
  (:class:`snapcore.render.mannequin.CharacterBody`, the body of earlier versions);
- ``"makehuman"``: the MakeHuman body on every skeleton, a glTF or FBX character's too
  (its own mesh set aside: a robot or a stylised figure drawn as the human the BVH
  characters wear, or two sources compared in one body); the mannequin where the
  retargeting cannot map the skeleton, as for ``"human"``.

:class:`MixedSceneBody` has the interface of :class:`snapcore.render.mannequin.SceneBody`
(``vertices``/``normals``/``pose``/``trimesh``, merged ``faces`` and colours), so the
renderer, camera, relief and viewpoint entropy need not know which kinds they draw.
Skinned bodies ignore the tessellation (their mesh is what it is); the shadow pass and
the stills then share one body object, and its block of posed frames
(:mod:`snapcore.render.skinned`) saves the second skinning.
"""

from __future__ import annotations

import warnings
from typing import Literal, get_args

import numpy as np

from snapcore.errors import SceneError
from snapcore.render.mannequin import (
    CHARACTER_COLORS,
    TESSELLATION,
    CharacterBody,
    PosedMesh,
    SceneBody,
)
from snapcore.render.mannequin import scene_body as mannequin_scene_body
from snapcore.render.skinned import FrameBlocks

__all__ = [
    "BodyKind",
    "BODY_KINDS",
    "DEFAULT_BODY",
    "check_body",
    "SkinnedBody",
    "MixedSceneBody",
    "character_body",
    "scene_body",
    "shadow_body",
    "posed_mesh",
    "scene_trimesh",
]

#: What a character is drawn as: its own or the MakeHuman body, the capsule mannequin,
#: or the MakeHuman body whatever mesh the character carries.
BodyKind = Literal["human", "mannequin", "makehuman"]
#: Every :data:`BodyKind`, in the order the CLI lists them.
BODY_KINDS: tuple[BodyKind, ...] = get_args(BodyKind)
#: The body kind when none is given.
DEFAULT_BODY: BodyKind = "human"


def check_body(kind) -> BodyKind:
    """``kind`` when it is one of :data:`BODY_KINDS`.

    Raises
    ------
    SceneError
        One line naming the kinds (a ``ValueError``).
    """
    if kind not in BODY_KINDS:
        raise SceneError(f"body must be one of {', '.join(BODY_KINDS)}, got {kind!r}")
    return kind


class SkinnedBody(FrameBlocks):
    """A glTF character's own skinned mesh, posable like a ``CharacterBody``.

    Parameters
    ----------
    character : Character
        One that carries its own ``mesh`` (:func:`snapcore.motion.gltf.read_gltf`).
    color : tuple of 3 floats
        RGB 0-1 for the faces whose material has no colour of its own (a textured
        or untextured white material; characters are told apart by it).
    """

    kind = "gltf"

    def __init__(self, character, *, color=CHARACTER_COLORS[0]):
        self.character = character
        if character.mesh is None:
            raise SceneError(f"character {character.name!r} carries no skinned mesh")
        self.mesh = character.mesh
        self.faces = self.mesh.faces
        rgb = np.tile(np.clip(np.asarray(color, float), 0, 1), (len(self.faces), 1))
        own = self.mesh.face_rgb
        if own is not None:  # the file's material colours where it has them
            rgb = np.where(np.isnan(own), rgb, own)
        self.face_colors = np.round(np.append(rgb, np.ones((len(rgb), 1)), axis=1) * 255).astype(
            np.uint8
        )

    @property
    def n_vertices(self) -> int:
        return self.mesh.n_vertices

    @property
    def n_faces(self) -> int:
        return int(self.faces.shape[0])

    def _pose(self, frames: np.ndarray) -> np.ndarray:
        return self.mesh.vertices(self.character, frames).astype(np.float32)


def character_body(
    character,
    *,
    kind: BodyKind = DEFAULT_BODY,
    color=CHARACTER_COLORS[0],
    tessellation=TESSELLATION,
    detail: str = "full",
    ground: float | None = None,
):
    """The body one character wears (see the module notes for the rules); ``detail``
    picks the human mesh's level of detail (:mod:`snapcore.render.human_asset`), ``ground``
    the floor height its soles stand on (default: inferred from its joints)."""
    if kind in ("human", "makehuman"):
        if character.mesh is not None and kind == "human":
            return SkinnedBody(character, color=color)
        # imported here: the MakeHuman body takes ~1 s to import, and the renderer,
        # camera and relief import this module for its body kinds alone
        from snapcore.render.human import HumanBody, RetargetError

        try:
            return HumanBody(character, color=color, detail=detail, ground=ground)
        except RetargetError as err:
            warnings.warn(f"{err}; it wears the mannequin instead", stacklevel=3)
    return CharacterBody(character, color=color, tessellation=tessellation)


class MixedSceneBody(SceneBody):
    """The bodies of every character of a scene, merged into one mesh.

    Parameters
    ----------
    scene : Scene
    kind : {"human", "mannequin", "makehuman"}
        The body kind (:data:`BodyKind`, default :data:`DEFAULT_BODY`).
    colors : sequence of RGB tuples, optional
        One base colour per character (default :data:`CHARACTER_COLORS` in order).
    tessellation : tuple, optional
        Faces of mannequin pieces (skinned bodies ignore it).
    bodies : list, optional
        Reuse these per-character bodies (one per character) instead of building them.
    detail : {"full", "reduced"}
        Level of detail of human meshes ("reduced": for videos).
    """

    def __init__(
        self,
        scene,
        *,
        kind: BodyKind = DEFAULT_BODY,
        colors=None,
        tessellation=TESSELLATION,
        bodies=None,
        detail="full",
    ):
        self.kind: BodyKind = check_body(kind)
        colors = list(colors) if colors is not None else list(CHARACTER_COLORS)
        self._merge(
            scene,
            bodies
            if bodies is not None
            else [
                character_body(
                    ch,
                    kind=self.kind,
                    color=colors[i % len(colors)],
                    tessellation=tessellation,
                    detail=detail,
                    ground=scene.ground,
                )
                for i, ch in enumerate(scene.characters)
            ],
        )

    def _yielding(self):
        """Per character: (contact yield, vertex neighbours) of a MakeHuman body, or
        (None, None) (see :mod:`snapcore.render.contacts`)."""
        if getattr(self, "_contact", None) is None:
            from snapcore.render.contacts import contact_yield, vertex_neighbours

            self._contact = [
                (contact_yield(b.asset), vertex_neighbours(b.faces, b.n_vertices))
                if getattr(b, "kind", None) == "human"
                else (None, None)
                for b in self.characters
            ]
        return self._contact

    def vertices(self, frame) -> np.ndarray:
        """Merged world vertices at internal frame(s): (N, 3) or (K, N, 3); two or more
        MakeHuman bodies are pushed out of each other where they meet
        (:func:`snapcore.render.contacts.resolve_contacts`)."""
        self._check(frame)
        if sum(getattr(b, "kind", None) == "human" for b in self.characters) < 2:
            return super().vertices(frame)
        from snapcore.render.contacts import resolve_contacts

        key = np.asarray(frame)
        memo = getattr(self, "_memo", None)
        if key.ndim == 0 and memo is not None and memo[0] == int(key):
            return memo[1]
        # many frames are posed together (as the bodies pose them), then resolved one
        # by one: asking frame by frame would skin a block of frames for each
        verts = [np.asarray(b.vertices(key)) for b in self.characters]
        norms = [np.asarray(b.normals(key)) for b in self.characters]
        ys, ns = zip(*self._yielding())
        if key.ndim == 0:
            out = np.concatenate(resolve_contacts(verts, norms, list(ys), list(ns)), axis=-2)
            out = out.astype(verts[0].dtype)
            self._memo = (int(key), out)
            return out
        return np.stack(
            [
                np.concatenate(
                    resolve_contacts(
                        [v[k] for v in verts], [n[k] for n in norms], list(ys), list(ns)
                    ),
                    axis=-2,
                ).astype(verts[0].dtype)
                for k in range(len(key))
            ]
        )


def _bodies_of(scene) -> dict:
    """The scene's body cache, kept on the scene object itself. (A module-level
    ``WeakKeyDictionary`` keyed by scene never freed an entry: its values, the bodies,
    hold the scene. On the scene, scene and bodies form a cycle the collector frees.)"""
    return vars(scene).setdefault("_snapcore_bodies", {})


def scene_body(
    scene, tessellation=TESSELLATION, *, kind: BodyKind = DEFAULT_BODY, detail: str = "full"
) -> MixedSceneBody:
    """The (cached) body of ``scene``: built once per scene, kind, tessellation and
    level of detail (``detail="reduced"``: the human mesh videos draw).

    ``kind`` is the body kind to draw (:data:`BodyKind`; a ``SceneError`` names the
    kinds for anything else); the entry points that render pass their ``body=`` here.

    Skinned bodies are shared between tessellations (only mannequin pieces differ), so
    the renderer's coarse shadow body reuses the posed human mesh.
    """
    kind = check_body(kind)
    bodies = _bodies_of(scene)
    body = bodies.get((kind, tessellation, detail))
    if body is None:
        other = next((b for (k, _, d), b in bodies.items() if k == kind and d == detail), None)
        reuse = None
        # mannequin pieces are the ones the renderers' shadows take (the scene's cached
        # mannequin of that tessellation, default colours: CharacterBody's by index), so
        # each tessellation is built once per scene (a batch strip draws the coarse one)
        if other is not None:
            pieces = None
            if any(isinstance(b, CharacterBody) for b in other.characters):
                pieces = mannequin_scene_body(scene, tessellation).characters
            reuse = [
                pieces[i] if isinstance(b, CharacterBody) and pieces is not None else b
                for i, b in enumerate(other.characters)
            ]
        elif kind == "mannequin":
            reuse = mannequin_scene_body(scene, tessellation).characters
        body = bodies[(kind, tessellation, detail)] = MixedSceneBody(
            scene, kind=kind, tessellation=tessellation, bodies=reuse, detail=detail
        )
    return body


def shadow_body(body: MixedSceneBody, tessellation) -> MixedSceneBody:
    """The stand-in that casts ``body``'s floor shadows: a coarse mannequin for every
    skeleton (a human body's shadow is its silhouette blurred by the floor's angle;
    capsules cast nearly the same one for a fifth of the triangles, measured 30% of a
    1280x720 frame's time), a glTF character's own mesh (a fox is no mannequin).

    The coarse mannequins are the scene's cached ones
    (:func:`snapcore.render.mannequin.scene_body`): every renderer of a scene casts the
    same (a batch scene's thumbnail, human, and its preview strip, mannequin, built them
    twice: ~6 ms a scene)."""
    skinned = [isinstance(b, SkinnedBody) for b in body.characters]
    coarse = None if all(skinned) else mannequin_scene_body(body.scene, tessellation)
    return MixedSceneBody(
        body.scene,
        kind=body.kind,
        tessellation=tessellation,
        bodies=[
            b if own or coarse is None else coarse.characters[i]
            for i, (b, own) in enumerate(zip(body.characters, skinned, strict=True))
        ],
    )


def posed_mesh(scene, index: int, *, kind: BodyKind = DEFAULT_BODY) -> PosedMesh:
    """Merged body mesh of every character of ``scene`` at internal index ``index``,
    each wearing a ``kind`` body (:data:`BodyKind`).

    Returns
    -------
    PosedMesh
        ``vertices`` (N, 3) metres, ``faces`` (M, 3), ``face_colors`` (M, 4) uint8,
        ``normals`` (N, 3), ``face_character`` (M,).
    """
    return scene_body(scene, kind=kind).pose(index)


def scene_trimesh(scene, index: int, *, kind: BodyKind = DEFAULT_BODY):
    """:func:`posed_mesh` as a :class:`trimesh.Trimesh` (face colours set)."""
    return posed_mesh(scene, index, kind=kind).trimesh()
