"""Simulated participants from a documented observer model (``snapshot simulate``).

Until real people have taken the study — and to check that the analysis recovers what
it should — simulated observers answer the same trials. They are stored through the
study store with ``simulated=True`` and every real analysis leaves them out unless asked.

The observer model (:class:`ObserverModel` its parameters, :class:`SimulatedParticipant`
the one implementation, which the load test's drivers answer through too), one
participant at a time:

- **Pose task** (per scene), by ``pose_model``:

  - ``"salient"`` (the default): with probability ``lapse`` a frame uniformly at random
    from the clip; otherwise one of the scene's *salient moments* — the algorithm's pick
    with probability ``algorithm_weight``, else one of the other salient frames
    (``StudyScene.salient_frames``: the top-k entropy peaks of the manifest, or moments
    the paper's text names) uniformly — landing ``round(N(0, spread_s) · fps)`` frames
    from it, clipped to the clip;
  - ``"uniform"``: a frame uniformly at random (a random clicker);
  - ``"centre"``: the frame at clip position ``u ~ Beta(2, 2)`` (an observer who ignores
    the motion but prefers the middle of the clip);
  - ``"habit"``: the frame at ``u ~ Beta(a, b)``, with ``a, b ~ U(0.5, 4)`` drawn once per
    observer (a personal position habit, the same in every scene).

  The last three are the null observers of ``snapshot calibrate``: their clip position
  does not depend on the scene.
- **View task** (per scene): the three methods' views appear in the left-to-right
  order the app's own trial plan gives the participant's seed
  (:func:`study_app.design.protocol.trial_plan`); the observer chooses by Luce's choice
  axiom, ``P(m) = s_m / Σ_shown s_j``, from the scene's method strengths
  (``StudyScene.strengths``, else the model's) — or, with ``view_position`` set, always
  takes that screen position (0 = left), whatever is shown there.
- **Attention check**: answered right with probability ``attention_pass``, else a
  random wrong option.
- Response times: log-normal with medians ``pose_time_s`` / ``view_time_s`` and log-SD
  0.5. Background answers: uniform over the study's choices.

Trial order is the app's protocol for the participant's seed (drawn first): pose tasks
in a random scene order, then view tasks in another, each with its own random screen
order of the methods, then the attention check; stimulus ids ``<scene>/pose``,
``<scene>/view``, ``attention``. Everything else is drawn from one seeded
``numpy.random.Generator``.
"""

from __future__ import annotations

import hashlib
import json
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING, Any, TypedDict

import numpy as np
import pandas as pd

from snapcore.select.view_methods import VIEW_METHODS
from study_app.data.answer import Answer
from study_app.design.protocol import trial_plan
from study_app.design.scenes import StudyScene

if TYPE_CHECKING:  # the store (SQLAlchemy) only when a simulation is stored
    from study_app.data.store import Store

__all__ = [
    "ObserverModel",
    "SimulatedParticipant",
    "SimulatedPerson",
    "paper_design",
    "design_from_stimuli",
    "simulate_participants",
    "simulated_rows",
    "store_simulation",
    "simulate_vote_counts",
    "design_sha256",
    "SIM_APP_VERSION",
    "with_strengths",
    "POSE_MODELS",
]

#: The observers' pose-task models (see the module docstring).
POSE_MODELS = ("salient", "uniform", "centre", "habit")

#: ``app_version`` stored with simulated participants.
SIM_APP_VERSION = "simulate-1"
#: Fallback attention check when the design names none (mirrors the app's default).
_ATTENTION: dict[str, Any] = {
    "options": ["A red square", "A purple circle", "A green triangle", "I am not sure"],
    "answer": "A purple circle",
}
_BACKGROUND = {
    "age_band": ["18–24", "25–34", "35–44", "45–54", "55–64", "65 or older"],
    "gender": ["Woman", "Man", "Non-binary", "Prefer not to say"],
    "experience": [
        "No experience",
        "Some (a course or a hobby)",
        "Experienced (animation, 3D or art is part of my work or studies)",
    ],
}


class SimulatedPerson(TypedDict):
    """One simulated participant (:func:`simulate_participants`): the seed of its trial
    plan, its background answers and its answers in trial order."""

    seed: int
    background: dict[str, str]
    rows: list[Answer]


@dataclass(frozen=True)
class ObserverModel:
    """Parameters of the simulated observer (see the module docstring).

    Attributes
    ----------
    spread_s : float
        Standard deviation, seconds, of a pose choice around the salient moment aimed at.
    lapse : float
        Probability of a uniformly random frame instead.
    algorithm_weight : float
        Probability that the moment aimed at is the algorithm's pick (when the scene has
        other salient frames; otherwise it is always the pick).
    strengths : dict
        Default Luce strengths of the methods (any positive scale).
    attention_pass : float
        Probability of answering the attention check right.
    pose_time_s, view_time_s : float
        Median response times, seconds.
    pose_model : str
        One of :data:`POSE_MODELS`.
    view_position : int or None
        Always take this screen position (0 = left) in the view task instead of the
        Luce choice (a position-bias null).
    """

    spread_s: float = 0.5
    lapse: float = 0.1
    algorithm_weight: float = 0.7
    strengths: dict = field(default_factory=lambda: {m: 1.0 for m in VIEW_METHODS})
    attention_pass: float = 0.95
    pose_time_s: float = 12.0
    view_time_s: float = 5.0
    pose_model: str = "salient"
    view_position: int | None = None

    def __post_init__(self) -> None:
        if self.pose_model not in POSE_MODELS:
            raise ValueError(f"pose_model: expected one of {POSE_MODELS}, got {self.pose_model!r}")
        if self.view_position is not None and not 0 <= self.view_position < len(VIEW_METHODS):
            raise ValueError(
                f"view_position: expected 0..{len(VIEW_METHODS) - 1} (screen positions, "
                f"0 = left), got {self.view_position}"
            )
        for name in ("lapse", "algorithm_weight", "attention_pass"):
            v = getattr(self, name)
            if not 0.0 <= v <= 1.0:
                raise ValueError(f"{name}: expected a probability in [0, 1], got {v}")
        if not self.spread_s >= 0:
            raise ValueError(f"spread_s: expected >= 0 seconds, got {self.spread_s}")
        _check_strengths(self.strengths, "strengths")


def _check_strengths(s: dict, what: str) -> None:
    bad = {m: v for m, v in s.items() if not (np.isfinite(v) and v > 0)}
    if bad or set(s) != set(VIEW_METHODS):
        raise ValueError(
            f"{what}: expected a positive strength for each of "
            f"{[str(m) for m in VIEW_METHODS]}, got {s}"
        )


def paper_design() -> list[StudyScene]:
    """A study shaped like the paper's: its six animations, Table 2 shares as strengths.

    Frame counts are the paper's Table 1; the motion rate is *assumed* 30 fps (the paper
    gives only the 24 fps video rate). Algorithm picks are the frames the paper's §4.4
    text names (Dancing 604, Soccer 406, Arguing 1240; Basketball: the middle of the
    300–350 window it names) — Running and Boxing have none there, so illustrative
    frames (40 of 66, 100 of 150) stand in. Other salient moments are those the text
    says people also chose (Dancing 430, Soccer 360, Arguing 850 and 1470). Strengths are
    the Table 2 vote shares, floored at 0.01 (Basketball's viewpoint entropy got 0).
    """
    from .votes import paper_counts

    counts = paper_counts()
    spec = [
        ("dancing", "Dancing", 1096, 604, (430,)),
        ("running", "Running", 66, 40, ()),
        ("soccer_kicking", "Soccer kicking", 525, 406, (360,)),
        ("basketball_shooting", "Basketball shooting", 540, 325, ()),
        ("two_person_arguing", "Two-person arguing", 1992, 1240, (850, 1470)),
        ("two_person_boxing", "Two-person boxing", 150, 100, ()),
    ]
    out = []
    for sid, title, n, a, extra in spec:
        shares = counts.loc[sid] / counts.loc[sid].sum()
        strengths = {m: max(float(shares[m]), 0.01) for m in VIEW_METHODS}
        out.append(
            StudyScene(
                scene=sid,
                fps=30.0,
                n_frames=n,
                algorithm_frame=a,
                salient_frames=extra,
                strengths=strengths,
                title=title,
            )
        )
    return out


def design_from_stimuli(
    manifest: str | Path | Mapping[str, Any], *, strengths: dict | None = None
) -> list[StudyScene]:
    """Scenes of a stimuli manifest as a simulation design (top-k picks as salient moments)."""
    from .stimuli import stimuli_scenes

    t = stimuli_scenes(manifest)
    return [
        StudyScene(
            scene=r.scene,
            fps=r.fps,
            n_frames=r.n_frames,
            algorithm_frame=r.algorithm_frame,
            frame_offset=r.frame_offset,
            salient_frames=tuple(f for f in r.algorithm_frames if f != r.algorithm_frame),
            strengths=strengths,
            title=r.title,
        )
        for r in t.itertuples()
    ]


#: The scene fields a simulated study depends on (hashed by :func:`design_sha256`).
_DESIGN_FIELDS = (
    "scene",
    "fps",
    "n_frames",
    "algorithm_frame",
    "frame_offset",
    "salient_frames",
    "strengths",
    "title",
)


def design_sha256(design: Iterable[StudyScene], model: ObserverModel) -> str:
    """A stable sha256 of a design + model (the store's ``manifest_sha256`` for them)."""
    doc = {
        "design": [{k: getattr(s, k) for k in _DESIGN_FIELDS} for s in design],
        "model": asdict(model),
    }
    return hashlib.sha256(json.dumps(doc, sort_keys=True, default=str).encode()).hexdigest()


# ----------------------------------------------------------------- the observer


class SimulatedParticipant:
    """One simulated observer's answers: the one participant model of the suite.

    ``snapshot simulate`` (:func:`simulate_participants`) and the load test's two drivers
    (:mod:`study_app.ops.loadtest`: the protocol client and the browser) all answer
    through it, so the behaviour the module docstring describes is written once. Every
    draw comes from ``rng``, in the order the methods are called: the same seed and calls
    give the same answers.

    Parameters
    ----------
    rng : numpy.random.Generator
        This participant's random draws.
    model : ObserverModel, optional
        The observer's parameters (default :class:`ObserverModel()`). A ``"habit"``
        observer draws its Beta(a, b) position habit here, once.

    Notes
    -----
    A driver that cannot know what the page means (the load test sees neither the
    algorithm's pick nor which method is where, nor the attention check's answer) says
    so: no ``aim``, a count of positions, no ``answer``; the model then chooses uniformly
    (a ``"uniform"`` pose model, equal strengths, a random option).
    """

    def __init__(self, rng: np.random.Generator, model: ObserverModel | None = None) -> None:
        self.rng = rng
        self.model = model or ObserverModel()
        self.habit: tuple[float, float] = (2.0, 2.0)
        if self.model.pose_model == "habit":
            a, b = rng.uniform(0.5, 4.0, 2)
            self.habit = (float(a), float(b))

    def pose_frame(
        self,
        first: int,
        last: int,
        *,
        fps: float = 30.0,
        aim: int | None = None,
        salient: Sequence[int] = (),
    ) -> int:
        """The frame chosen in a clip of frames ``first..last`` (inclusive, any numbering).

        Parameters
        ----------
        fps : float
            Frames per second of the clip (the spread of a salient choice is in seconds).
        aim : int, optional
            The algorithm's pick, aimed at with probability ``algorithm_weight`` by the
            ``"salient"`` model (required by it); else one of ``salient`` is.
        salient : sequence of int
            The clip's other salient frames.
        """
        model, rng = self.model, self.rng
        if model.pose_model in ("centre", "habit"):
            u = rng.beta(*self.habit)
            return int(np.clip(np.rint(first + u * (last - first)), first, last))
        if model.pose_model == "uniform" or rng.random() < model.lapse:
            return int(rng.integers(first, last + 1))
        if aim is None:
            raise ValueError("pose_frame: the salient model aims at a frame; none given")
        target = aim
        if salient and rng.random() >= model.algorithm_weight:
            target = salient[int(rng.integers(len(salient)))]
        f = target + rng.normal(0.0, model.spread_s) * fps
        return int(np.clip(np.rint(f), first, last))

    def view_position(
        self, shown: Sequence[str] | int, strengths: Mapping[str, float] | None = None
    ) -> int:
        """The screen position chosen (0 = left) among the ``shown`` methods, by Luce's
        choice axiom with ``strengths`` (default the model's); a count of positions when
        the methods are not known (equal strengths). The model's ``view_position``, when
        set, wins."""
        if self.model.view_position is not None:
            return self.model.view_position
        if isinstance(shown, int):
            return int(self.rng.integers(shown))
        s = strengths or self.model.strengths
        w = np.array([s[m] for m in shown], dtype=float)
        return int(self.rng.choice(len(shown), p=w / w.sum()))

    def attention_answer(self, options: Sequence[str], answer: str | None = None) -> str:
        """The option chosen in the attention check: ``answer`` with probability
        ``attention_pass``, else a wrong option; any option when the answer is not known."""
        if answer is None:
            return options[int(self.rng.integers(len(options)))]
        right = self.rng.random() < self.model.attention_pass
        wrong = [o for o in options if o != answer]
        return answer if right or not wrong else wrong[int(self.rng.integers(len(wrong)))]

    def choose(self, options: Sequence[str]) -> str:
        """A background answer: one of ``options``, uniformly."""
        return options[int(self.rng.integers(len(options)))]

    def response_time(self, task: str) -> float:
        """Seconds to answer a ``task`` trial: log-normal, log-SD 0.5, around the model's
        median (``pose_time_s``, ``view_time_s``; 4 s for the attention check)."""
        median = {"pose": self.model.pose_time_s, "view": self.model.view_time_s}.get(task, 4.0)
        return float(median * self.rng.lognormal(0, 0.5))


def simulate_participants(
    design: Iterable[StudyScene],
    n: int,
    *,
    seed: int = 0,
    model: ObserverModel | None = None,
    attention: dict | None = None,
    background: dict | None = None,
) -> list[SimulatedPerson]:
    """Simulate ``n`` participants answering every trial of ``design``.

    Parameters
    ----------
    design : sequence of StudyScene
        The study's scenes.
    n : int
        Number of participants.
    seed : int
        Seed of the one ``numpy.random.Generator`` behind every draw.
    model : ObserverModel, optional
        Observer parameters (default :class:`ObserverModel()`).
    attention : dict, optional
        ``{"options": [...], "answer": str}``; default the app's attention check.
    background : dict, optional
        field → choices for the background answers.

    Returns
    -------
    list of dict
        Per participant: ``seed`` (int), ``background`` (dict), ``rows`` (the trial
        fields of ``response.schema.json``, in trial order).
    """
    if n < 0:
        raise ValueError(f"n: expected a number of participants >= 0, got {n}")
    design = list(design)
    if not design:
        raise ValueError("design: no scenes to simulate")
    model = model or ObserverModel()
    for s in design:
        if s.strengths is not None:
            _check_strengths(s.strengths, f"scene '{s.scene}' strengths")
    attention = attention or _ATTENTION
    background = background or _BACKGROUND
    rng = np.random.default_rng(seed)
    by_id = {s.scene: s for s in design}
    if len(by_id) != len(design):
        raise ValueError("design: scene ids repeat")
    out: list[SimulatedPerson] = []
    for _ in range(n):
        pseed = int(rng.integers(2**62))
        plan = trial_plan(list(by_id), pseed, attention=False)
        person = SimulatedParticipant(rng, model)
        rows: list[Answer] = []
        for trial in (t for t in plan if t.task == "pose"):
            s = by_id[trial.scene]
            first = s.frame_offset
            f = person.pose_frame(
                first,
                first + s.n_frames - 1,
                fps=s.fps,
                aim=s.algorithm_frame,
                salient=s.salient_frames,
            )
            rows.append(
                {
                    "task": "pose",
                    "scene": s.scene,
                    "stimulus_id": f"{s.scene}/pose",
                    "chosen_frame": f,
                    "algorithm_frame": s.algorithm_frame,
                    "fps": float(s.fps),
                    "n_frames": int(s.n_frames),
                    "response_time_s": person.response_time("pose"),
                    "trial_index": len(rows),
                }
            )
        for trial in (t for t in plan if t.task == "view"):
            s = by_id[trial.scene]
            shown = trial.shown_order or ()  # every view trial has its screen order
            pos = person.view_position(shown, s.strengths)
            rows.append(
                {
                    "task": "view",
                    "scene": s.scene,
                    "stimulus_id": f"{s.scene}/view",
                    "chosen_method": shown[pos],
                    "chosen_position": pos,
                    "shown_order": list(shown),
                    "response_time_s": person.response_time("view"),
                    "trial_index": len(rows),
                }
            )
        value = person.attention_answer(attention["options"], attention["answer"])
        rows.append(
            {
                "task": "attention",
                "scene": "attention",
                "stimulus_id": "attention",
                "chosen_value": value,
                "correct": value == attention["answer"],
                "response_time_s": person.response_time("attention"),
                "trial_index": len(rows),
            }
        )
        bg = {k: person.choose(v) for k, v in background.items()}
        out.append({"seed": pseed, "background": bg, "rows": rows})
    return out


def simulated_rows(
    participants: Iterable[SimulatedPerson],
    *,
    study_id: str = "simulated",
    manifest_sha256: str = "0" * 64,
) -> pd.DataFrame:
    """Simulated participants → export-shaped rows (no database), ``simulated`` true.

    Participant ids are ``sim-000000``, ``sim-000001``, ...; ``created_at`` is now.
    """
    now = datetime.now(UTC).isoformat()
    recs = []
    for i, p in enumerate(participants):
        for r in p["rows"]:
            recs.append(
                {
                    "participant_id": f"sim-{i:06d}",
                    "study_id": study_id,
                    "created_at": now,
                    "app_version": SIM_APP_VERSION,
                    "manifest_sha256": manifest_sha256,
                    "simulated": True,
                    "age_band": p["background"].get("age_band"),
                    "gender": p["background"].get("gender"),
                    "experience": p["background"].get("experience"),
                    "prolific_pid": None,
                    **r,
                }
            )
    return pd.DataFrame.from_records(recs)


def store_simulation(
    store: Store,
    participants: Iterable[SimulatedPerson],
    *,
    study_id: str,
    manifest_sha256: str,
    app_version: str = SIM_APP_VERSION,
    progress: bool = False,
) -> list[str]:
    """Write simulated participants through the study store, marked simulated.

    Returns
    -------
    list of str
        The new participant ids.
    """
    from tqdm import tqdm

    ids = []
    for p in tqdm(participants, desc="simulate", unit="participant", disable=not progress):
        pid = store.create_participant(
            study_id, manifest_sha256, app_version=app_version, seed=p["seed"], simulated=True
        )
        store.set_background(pid, p["background"])
        rows = [r.copy() for r in p["rows"]]
        store.record_responses(pid, rows)
        store.complete(pid)
        ids.append(pid)
    return ids


def simulate_vote_counts(
    n: int, strengths: Sequence[float] | np.ndarray, *, n_sims: int, seed: int = 0
) -> np.ndarray:
    """Vote counts of ``n`` participants, all methods shown, ``n_sims`` times (numpy only).

    Parameters
    ----------
    strengths : sequence of float, shape (M,)
        Luce strengths; choice probabilities are ``strengths / sum``.

    Returns
    -------
    ndarray of int, shape (n_sims, M)
    """
    p = np.asarray(strengths, dtype=float)
    if p.ndim != 1 or np.any(p < 0) or p.sum() <= 0:
        raise ValueError(f"strengths: expected non-negative weights, got {strengths}")
    rng = np.random.default_rng(seed)
    return rng.multinomial(n, p / p.sum(), size=n_sims)


def with_strengths(design: Iterable[StudyScene], strengths: dict | None) -> list[StudyScene]:
    """The design with every scene's strengths replaced (None: use the model's)."""
    return [replace(s, strengths=strengths) for s in design]
