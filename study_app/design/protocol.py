"""The study protocol: configuration, per-participant trial order, answer checks.

A study config (TOML or JSON, ``data_schema/study.schema.json``) names the scenes and
the questions. From it and one participant's seed this module derives the trial plan
the app walks through (paper §4.4):

1. pose tasks, one per scene, in a seeded random order: watch the video, pick the most
   meaningful frame;
2. view tasks, one per scene, in another seeded order: three candidate views of the
   selected pose (ours, viewpoint entropy, motion area) in seeded random positions;
3. one attention check.

Consent and the background questions come before the trials and are not trials.
Everything here is pure (no Streamlit, no SQL): the same seed always gives the same
plan, so a participant who reloads or returns later sees the same order.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from snapcore.errors import SnapshotError
from snapcore.schema import read_document, validate
from snapcore.select.view_methods import VIEW_METHODS

__all__ = [
    "DEMO_CONFIG",
    "PAPER_CONFIG",
    "TASKS",
    "DEFAULT_BACKGROUND",
    "DEFAULT_ATTENTION",
    "DEFAULT_CONSENT",
    "StudyError",
    "AnswerError",
    "Study",
    "Trial",
    "load_study",
    "study_from_dict",
    "trial_plan",
    "check_video_frame",
    "check_view_choice",
    "check_attention_answer",
    "redirect_url",
    "estimated_minutes",
    "consent_text",
    "DEFAULT_CONTACT",
    "NEAR_DUPLICATE_ACTIONS",
]

#: The study configs shipped with the app (``study_app/configs/``).
CONFIGS = Path(__file__).resolve().parents[1] / "configs"
#: The embedded demo: synthetic scenes from snapcore.motion.synth, no data needed.
DEMO_CONFIG = CONFIGS / "demo.toml"
#: The paper's six analogues on the real motions (SNAPSHOT_DATA).
PAPER_CONFIG = CONFIGS / "paper.toml"

#: Trial kinds, in the order the plan puts them.
TASKS = ("pose", "view", "attention")

#: Background questions and their default choices (paper §4.4: age, gender, experience).
DEFAULT_BACKGROUND = {
    "age_bands": ["18–24", "25–34", "35–44", "45–54", "55–64", "65 or older", "Prefer not to say"],
    "genders": ["Woman", "Man", "Non-binary", "Prefer to self-describe", "Prefer not to say"],
    "experience": [
        "No experience",
        "Some (a course or a hobby)",
        "Experienced (animation, 3D or art is part of my work or studies)",
        "Professional (animator, 3D artist, illustrator, sculptor)",
    ],
}

#: An instructed-response item: it has one right answer whatever the participant thinks.
DEFAULT_ATTENTION = {
    "question": "This question checks that you are reading carefully. "
    "Please choose the option 'A purple circle'.",
    "options": ["A red square", "A purple circle", "A green triangle", "I am not sure"],
    "answer": "A purple circle",
}

DEFAULT_CONSENT = """\
You are invited to take part in a research study about how people see human motion.

**What you will do.** You will watch short animations of moving figures and, for each,
pick the moment that best tells what the figure is doing. Then you will see still
images of such moments from three viewpoints and pick the one that shows the action
best. A few questions about you come first. It takes about {minutes} minutes.

**Your data.** We record your answers, how long each took, and how you used the video
player (play, pause, seek). We do not record your name, e-mail or IP address. Answers
are stored under a random identifier and analysed only in aggregate.

**Your rights.** Taking part is voluntary. You may stop at any time by closing the page;
you can come back later with the same link and continue where you left off.

**Withdrawing.** You can withdraw at any time, also after you finish, without giving a
reason: write to {contact} with your personal link (shown at the bottom of every page)
or your Prolific ID, and all your answers are deleted. Shared data carry no Prolific ID.
"""
#: How the consent text names the contact when the config gives none.
DEFAULT_CONTACT = "the researchers (on Prolific: through Prolific's messages)"


#: What the stimuli build does when two candidate pictures of a scene are nearly the same:
#: "replace" (the default: a baseline's view by its best-scoring view whose picture is
#: unlike the others, :mod:`study_app.design.replacement`), "error" (stop) or "warn"
#: (build, warn, and let the analysis report it).
NEAR_DUPLICATE_ACTIONS = ("merge", "replace", "error", "warn")
#: Seconds a participant needs per study step beyond watching (estimates for the consent
#: page's duration: reading the consent and background, choosing a view, the check).
_SECONDS_CONSENT, _SECONDS_BACKGROUND, _SECONDS_VIEW, _SECONDS_ATTENTION = 60, 45, 15, 15
#: A pose task takes about this many times the animation (watch, replay, step) plus
#: a fixed overhead in seconds.
_POSE_WATCH_FACTOR, _SECONDS_POSE = 3.0, 20


class StudyError(SnapshotError):
    """A study configuration that cannot be used (names the file and the field)."""


class AnswerError(SnapshotError):
    """An answer that does not fit the trial it claims to answer (nothing is stored)."""


@dataclass(frozen=True)
class Study:
    """A validated study configuration with defaults filled in.

    Attributes
    ----------
    id, title, description : str
    video_fps : float
        Frame rate of the stimulus videos (frames per second).
    size : tuple of int
        ``(width, height)`` in pixels of every video, frame and candidate view.
    picker : str
        ``"video"`` (frame-accurate player) or ``"frames"`` (slider over frames).
    completion_code, redirect_url : str or None
    consent : str
        Markdown shown on the consent page.
    contact : str or None
        Who participants write to, e.g. to withdraw (replaces ``{contact}`` in the
        consent text; :data:`DEFAULT_CONTACT` without it).
    license, citation : str or None
        The shared dataset's licence and how to cite it (Psych-DS metadata).
    creators : tuple of str
        Who made the dataset (Psych-DS metadata).
    min_answer_s : float
        Seconds a trial must have been on screen before an answer to it is accepted
        (a double click cannot answer the next trial unseen).
    require_watch : bool
        The pose task's Confirm stays off until the animation was played through once.
    near_duplicate_deg : float
        Candidate views closer than this angle (degrees), or than it to each other's
        opposite, count as the same picture (and are skipped unrendered when looking
        for a replacement).
    near_duplicate : str
        What the stimuli build does about them (:data:`NEAR_DUPLICATE_ACTIONS`).
    background : dict of str to list of str
        Choices for ``age_bands``, ``genders``, ``experience``.
    attention : dict
        ``question``, ``options``, ``answer``.
    selection : dict
        Keyword options for the pose/view selection.
    scenes : tuple of dict
        The config's scene entries, in config order.
    base : Path or None
        Folder that relative scene paths are resolved against (the config's folder).
    """

    id: str
    title: str
    description: str = ""
    video_fps: float = 24.0
    size: tuple[int, int] = (640, 480)
    picker: str = "video"
    completion_code: str | None = None
    redirect_url: str | None = None
    consent: str = DEFAULT_CONSENT
    contact: str | None = None
    license: str | None = None
    creators: tuple = ()
    citation: str | None = None
    min_answer_s: float = 1.0
    require_watch: bool = True
    near_duplicate_deg: float = 15.0
    near_duplicate: str = "merge"
    background: dict = field(default_factory=lambda: dict(DEFAULT_BACKGROUND))
    attention: dict = field(default_factory=lambda: dict(DEFAULT_ATTENTION))
    selection: dict = field(default_factory=dict)
    scenes: tuple = ()
    base: Path | None = None

    @property
    def scene_ids(self) -> list[str]:
        """Scene ids in config order."""
        return [s["id"] for s in self.scenes]

    def to_dict(self) -> dict:
        """The config as a document that :func:`study_from_dict` reads back (for manifests)."""
        study = {
            "id": self.id,
            "title": self.title,
            "description": self.description,
            "video_fps": self.video_fps,
            "size": list(self.size),
            "picker": self.picker,
            "consent": self.consent,
            "min_answer_s": self.min_answer_s,
            "require_watch": self.require_watch,
            "near_duplicate_deg": self.near_duplicate_deg,
            "near_duplicate": self.near_duplicate,
        }
        if self.completion_code:
            study["completion_code"] = self.completion_code
        if self.redirect_url:
            study["redirect_url"] = self.redirect_url
        if self.contact:
            study["contact"] = self.contact
        for name in ("license", "citation"):
            if getattr(self, name):
                study[name] = getattr(self, name)
        if self.creators:
            study["creators"] = list(self.creators)
        return {
            "study": study,
            "background": dict(self.background),
            "attention": dict(self.attention),
            "selection": dict(self.selection),
            "scenes": [dict(s) for s in self.scenes],
        }


@dataclass(frozen=True)
class Trial:
    """One trial of a participant's plan.

    Attributes
    ----------
    index : int
        0-based position in the plan (the store's ``trial_index``).
    task : str
        ``"pose"``, ``"view"`` or ``"attention"``.
    scene : str
        Scene id (``"attention"`` for the attention check).
    stimulus_id : str
        ``"<scene>/pose"``, ``"<scene>/view"`` or ``"attention"``.
    shown_order : tuple of str or None
        View task: the method whose picture is shown at each screen position, left to
        right.
    shown_groups : tuple of tuple of str or None
        View task: the methods each shown picture stands for (its own first): alike
        candidates share one picture (``study.near_duplicate = "merge"``).
    """

    index: int
    task: str
    scene: str
    stimulus_id: str
    shown_order: tuple[str, ...] | None = None
    shown_groups: tuple[tuple[str, ...], ...] | None = None


def load_study(path: str | Path) -> Study:
    """Read and validate a study config file (TOML or JSON).

    Raises
    ------
    SchemaError
        The file breaks ``study.schema.json`` (message names file and field).
    StudyError
        A rule the schema cannot express (duplicate scene ids, an attention answer that
        is not an option, an empty frame window).
    """
    p = Path(path)
    doc = read_document(p, "study")
    return study_from_dict(doc, source=str(p), base=p.resolve().parent, validated=True)


def study_from_dict(
    doc: dict, *, source: str = "study config", base: Path | None = None, validated: bool = False
) -> Study:
    """Build a :class:`Study` from a parsed config document (validating it first)."""
    if not validated:
        validate(doc, "study", source=source)
    s = doc["study"]
    ids = [sc["id"] for sc in doc["scenes"]]
    dupes = sorted({i for i in ids if ids.count(i) > 1})
    if dupes:
        raise StudyError(f"{source}: scenes: duplicate scene id(s) {', '.join(dupes)}")
    for k, sc in enumerate(doc["scenes"]):
        if "frames" in sc and sc["frames"][0] >= sc["frames"][1]:
            raise StudyError(
                f"{source}: scenes[{k}].frames: {sc['frames']} is an empty window "
                "(need start < stop)"
            )
    width, height = (int(v) for v in s.get("size", (640, 480)))  # two: the schema's
    attention = dict(doc.get("attention") or DEFAULT_ATTENTION)
    if attention["answer"] not in attention["options"]:
        raise StudyError(
            f"{source}: attention.answer: '{attention['answer']}' is not one of attention.options"
        )
    background = dict(DEFAULT_BACKGROUND)
    background.update(doc.get("background") or {})
    return Study(
        id=s["id"],
        title=s["title"],
        description=s.get("description", ""),
        video_fps=float(s.get("video_fps", 24.0)),
        size=(width, height),
        picker=s.get("picker", "video"),
        completion_code=s.get("completion_code") or None,
        redirect_url=s.get("redirect_url") or None,
        consent=s.get("consent") or DEFAULT_CONSENT,
        contact=s.get("contact") or None,
        license=s.get("license") or None,
        creators=tuple(s.get("creators") or ()),
        citation=s.get("citation") or None,
        min_answer_s=float(s.get("min_answer_s", 1.0)),
        require_watch=bool(s.get("require_watch", True)),
        near_duplicate_deg=float(s.get("near_duplicate_deg", 15.0)),
        near_duplicate=s.get("near_duplicate", "merge"),
        background=background,
        attention=attention,
        selection=dict(doc.get("selection") or {}),
        scenes=tuple(dict(sc) for sc in doc["scenes"]),
        base=base,
    )


def trial_plan(
    scene_ids, seed: int, *, methods=VIEW_METHODS, attention: bool = True, shown=None
) -> list[Trial]:
    """The ordered trials of one participant.

    Parameters
    ----------
    scene_ids : sequence of str
        Scenes of the study (the order given does not matter beyond determinism).
    seed : int
        The participant's seed (stored with the participant): one seed, one plan.
    methods : sequence of ViewMethod
        Methods whose views each view task shows (default: the three of
        :data:`snapcore.select.view_methods.VIEW_METHODS`, the paper's Fig. 8–10 and Table 2).
    attention : bool
        Append the attention check.
    shown : dict of str to sequence of sequence of str, optional
        Per scene, the pictures its view task shows, each the methods it stands for
        (its own first; the manifest's ``shown``, :attr:`Stimuli.view_groups`). Absent
        scenes show each method's own picture. A scene with a single picture (all alike)
        has no view task.

    Returns
    -------
    list of Trial
        Pose tasks (a seeded permutation of the scenes), then view tasks (another
        permutation, each with its own seeded screen order of the methods), then the
        attention check; ``index`` runs 0..n-1.

    Notes
    -----
    One ``numpy.random.Generator`` from ``seed`` draws, in a fixed sequence, the pose
    order, the view order and each view trial's picture order (a uniform permutation of
    the pictures shown, so a merged picture is no likelier on the left), so the plan is
    a pure function of ``(scene_ids, seed, shown)``; without merged pictures it is the
    plan of earlier versions.
    """
    ids = list(scene_ids)
    if not ids:
        raise StudyError("a study needs at least one scene")
    rng = np.random.default_rng(int(seed))
    pose_order = rng.permutation(len(ids))
    view_order = rng.permutation(len(ids))
    trials: list[Trial] = []
    for k in pose_order:
        trials.append(Trial(len(trials), "pose", ids[k], f"{ids[k]}/pose"))
    for k in view_order:
        groups = [tuple(g) for g in (shown or {}).get(ids[k], ())] or [(m,) for m in methods]
        if len(groups) < 2:
            continue  # every candidate the same picture: nothing to compare
        perm = rng.permutation(len(groups))
        trials.append(
            Trial(
                len(trials),
                "view",
                ids[k],
                f"{ids[k]}/view",
                tuple(groups[i][0] for i in perm),
                tuple(groups[i] for i in perm),
            )
        )
    if attention:
        trials.append(Trial(len(trials), "attention", "attention", "attention"))
    return trials


def _as_int(value, what: str) -> int:
    # Values arrive from a browser as JSON: accept 12 and 12.0, refuse "12", True, 12.5.
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise AnswerError(f"{what} must be a whole number, got {value!r}")
    if not math.isfinite(float(value)) or float(value) != int(value):
        raise AnswerError(f"{what} must be a whole number, got {value!r}")
    return int(value)


def check_video_frame(video_frame, video_to_motion) -> tuple[int, int]:
    """Check a chosen video frame and convert it to a motion frame.

    Parameters
    ----------
    video_frame : int
        0-based frame of the stimulus video the participant confirmed.
    video_to_motion : sequence of int
        The stimulus's map: motion frame (source numbering) shown at each video frame.

    Returns
    -------
    (video_frame, motion_frame) : tuple of int

    Raises
    ------
    AnswerError
        Not a whole number, or outside ``[0, len(video_to_motion))``.
    """
    v = _as_int(video_frame, "the chosen frame")
    n = len(video_to_motion)
    if not 0 <= v < n:
        raise AnswerError(f"frame {v} is outside this video (frames 0 to {n - 1})")
    return v, int(video_to_motion[v])


def check_view_choice(trial: Trial, position, method=None) -> tuple[int, str]:
    """Check a view-task answer against what the plan showed; map the position to its method.

    Participants' pages carry positions only (they must not reveal which method made
    which picture), so the method comes from the participant's seeded screen order.
    A caller that also claims a ``method`` (a simulation, an import) must name the one
    shown at that position, or the answer is refused instead of miscounted.

    Returns
    -------
    (position, method) : tuple

    Raises
    ------
    AnswerError
    """
    if trial.task != "view" or not trial.shown_order:
        raise AnswerError(f"trial {trial.index} is not a view task")
    p = _as_int(position, "the chosen position")
    if not 0 <= p < len(trial.shown_order):
        raise AnswerError(f"position {p} does not exist (0 to {len(trial.shown_order) - 1})")
    if method is None:
        return p, trial.shown_order[p]
    if method not in VIEW_METHODS:
        raise AnswerError(f"unknown method label {method!r}")
    if trial.shown_order[p] != method:
        raise AnswerError(f"the label {method!r} does not match the view shown at position {p}")
    return p, method


def check_attention_answer(study: Study, answer) -> bool:
    """Whether ``answer`` is right; :class:`AnswerError` if it is not an option at all."""
    if not isinstance(answer, str) or answer not in study.attention["options"]:
        raise AnswerError(f"{answer!r} is not one of the options")
    return answer == study.attention["answer"]


def redirect_url(study: Study, code: str) -> str | None:
    """The done page's link with ``{code}`` replaced, or None without a redirect."""
    if not study.redirect_url:
        return None
    return study.redirect_url.replace("{code}", code)


def estimated_minutes(video_seconds, *, attention: bool = True) -> int:
    """How long the study takes a participant, in whole minutes (at least 1).

    Parameters
    ----------
    video_seconds : sequence of float
        Duration (s) of each scene's animation; every scene gives one pose and one
        view task.
    attention : bool
        Whether the plan ends with the attention check.

    Notes
    -----
    A pose task is taken as ``3 ×`` its animation (watch, replay, step to the moment)
    plus 20 s; a view task 15 s; consent 60 s, background 45 s, attention check 15 s.
    Rounded up, so the consent page never promises less than it takes.
    """
    secs = [float(v) for v in video_seconds]
    total = (
        _SECONDS_CONSENT
        + _SECONDS_BACKGROUND
        + (_SECONDS_ATTENTION if attention else 0)
        + sum(_POSE_WATCH_FACTOR * v + _SECONDS_POSE for v in secs)
        + _SECONDS_VIEW * len(secs)
    )
    return max(1, math.ceil(total / 60))


def consent_text(study: Study, minutes: int) -> str:
    """The consent Markdown with ``{minutes}`` replaced by the study's estimated duration
    and ``{contact}`` by whom to write to (to withdraw, :attr:`Study.contact`)."""
    return study.consent.replace("{minutes}", str(int(minutes))).replace(
        "{contact}", study.contact or DEFAULT_CONTACT
    )
