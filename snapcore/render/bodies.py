"""Which body each character wears, merged into one posable scene mesh.

Every picture, video, stimulus, contact sheet, relief and the viewpoint-entropy baseline
gets its mesh from :func:`scene_body`. The *body kind* is a scene setting,
``scene.meta["body"]`` (the CLI's ``--body``), default :data:`DEFAULT_BODY`:

- ``"human"``: a glTF character wears its own skinned mesh (:class:`SkinnedBody`);
  a BVH skeleton wears the MakeHuman body retargeted onto it
  (:class:`snapcore.render.human.HumanBody`); a skeleton the retargeting cannot map
  falls back to the mannequin, with a warning naming what is missing and the joints no
  role was found for;
- ``"mannequin"``: capsules and spheres on the joints for everyone
  (:class:`snapcore.render.mannequin.CharacterBody`, the body of earlier versions).

:class:`MixedSceneBody` has the interface of :class:`snapcore.render.mannequin.SceneBody`
(``vertices``/``normals``/``pose``/``trimesh``, merged ``faces`` and colours), so the
renderer, camera, relief and viewpoint entropy need not know which kinds they draw.
Skinned bodies ignore the tessellation (their mesh is what it is); the shadow pass and
the stills then share one body object, and its block of posed frames
(:mod:`snapcore.render.skinned`) saves the second skinning.
"""

from __future__ import annotations

import warnings

import numpy as np

from snapcore.errors import SceneError
from snapcore.render.human import HumanBody, RetargetError
from snapcore.render.mannequin import (
    CHARACTER_COLORS,
    TESSELLATION,
    CharacterBody,
    PosedMesh,
    SceneBody,
)
from snapcore.render.skinned import FrameBlocks

__all__ = [
    "BODY_KINDS",
    "DEFAULT_BODY",
    "body_kind",
    "with_body",
    "SkinnedBody",
    "MixedSceneBody",
    "character_body",
    "scene_body",
    "shadow_body",
    "posed_mesh",
    "scene_trimesh",
]

BODY_KINDS = ("human", "mannequin")
DEFAULT_BODY = "human"


def body_kind(scene) -> str:
    """The scene's body kind: ``scene.meta["body"]``, default :data:`DEFAULT_BODY`."""
    kind = scene.meta.get("body", DEFAULT_BODY)
    if kind not in BODY_KINDS:
        raise SceneError(f"body must be one of {', '.join(BODY_KINDS)}, got {kind!r}")
    return kind


def with_body(scene, kind: str | None):
    """``scene`` set to wear ``kind`` bodies (None: unchanged); returns the scene."""
    if kind is not None:
        if kind not in BODY_KINDS:
            raise SceneError(f"body must be one of {', '.join(BODY_KINDS)}, got {kind!r}")
        scene.meta["body"] = kind
    return scene


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
    kind: str = DEFAULT_BODY,
    color=CHARACTER_COLORS[0],
    tessellation=TESSELLATION,
    detail: str = "full",
    ground: float | None = None,
):
    """The body one character wears (see the module notes for the rules); ``detail``
    picks the human mesh's level of detail (:mod:`snapcore.render.human_asset`), ``ground``
    the floor height its soles stand on (default: inferred from its joints)."""
    if kind == "human":
        if character.mesh is not None:
            return SkinnedBody(character, color=color)
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
    kind : {"human", "mannequin"}, optional
        Default :func:`body_kind` of the scene.
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
        kind=None,
        colors=None,
        tessellation=TESSELLATION,
        bodies=None,
        detail="full",
    ):
        self.kind = kind or body_kind(scene)
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


def _bodies_of(scene) -> dict:
    """The scene's body cache, kept on the scene object itself. (A module-level
    ``WeakKeyDictionary`` keyed by scene never freed an entry: its values, the bodies,
    hold the scene. On the scene, scene and bodies form a cycle the collector frees.)"""
    return vars(scene).setdefault("_snapcore_bodies", {})


def scene_body(
    scene, tessellation=TESSELLATION, *, kind: str | None = None, detail: str = "full"
) -> MixedSceneBody:
    """The (cached) body of ``scene``: built once per scene, kind, tessellation and
    level of detail (``detail="reduced"``: the human mesh videos draw).

    Skinned bodies are shared between tessellations (only mannequin pieces differ), so
    the renderer's coarse shadow body reuses the posed human mesh.
    """
    kind = kind or body_kind(scene)
    bodies = _bodies_of(scene)
    body = bodies.get((kind, tessellation, detail))
    if body is None:
        other = next((b for (k, _, d), b in bodies.items() if k == kind and d == detail), None)
        reuse = None
        if other is not None:
            colors = list(CHARACTER_COLORS)
            reuse = [
                b
                if not isinstance(b, CharacterBody)
                else CharacterBody(
                    b.character, color=colors[i % len(colors)], tessellation=tessellation
                )
                for i, b in enumerate(other.characters)
            ]
        body = bodies[(kind, tessellation, detail)] = MixedSceneBody(
            scene, kind=kind, tessellation=tessellation, bodies=reuse, detail=detail
        )
    return body


def shadow_body(body: MixedSceneBody, tessellation) -> MixedSceneBody:
    """The stand-in that casts ``body``'s floor shadows: a coarse mannequin for every
    skeleton (a human body's shadow is its silhouette blurred by the floor's angle;
    capsules cast nearly the same one for a fifth of the triangles, measured 30% of a
    1280x720 frame's time), a glTF character's own mesh (a fox is no mannequin)."""
    colors = list(CHARACTER_COLORS)
    return MixedSceneBody(
        body.scene,
        kind=body.kind,
        tessellation=tessellation,
        bodies=[
            b
            if isinstance(b, SkinnedBody)
            else CharacterBody(
                b.character, color=colors[i % len(colors)], tessellation=tessellation
            )
            for i, b in enumerate(body.characters)
        ],
    )


def posed_mesh(scene, frame: int, *, kind: str | None = None) -> PosedMesh:
    """Merged body mesh of every character of ``scene`` at internal frame ``frame``.

    Returns
    -------
    PosedMesh
        ``vertices`` (N, 3) metres, ``faces`` (M, 3), ``face_colors`` (M, 4) uint8,
        ``normals`` (N, 3), ``face_character`` (M,).
    """
    return scene_body(scene, kind=kind).pose(frame)


def scene_trimesh(scene, frame: int, *, kind: str | None = None):
    """:func:`posed_mesh` as a :class:`trimesh.Trimesh` (face colours set)."""
    return posed_mesh(scene, frame, kind=kind).trimesh()
