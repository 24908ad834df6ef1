"""The participant's session: :class:`ParticipantSession`, the only way to read or change
where a participant is, and :class:`Stage`, the steps of the walk through the study
(see :mod:`study_app.session`)."""

from __future__ import annotations

import math
import re
import secrets
from datetime import UTC, datetime
from enum import StrEnum
from functools import lru_cache

from study_app.data.answer import Answer
from study_app.data.withdraw import withdrawal_of
from study_app.design.protocol import (
    AnswerError,
    Trial,
    check_attention_answer,
    check_video_frame,
    check_view_choice,
    redirect_url,
    trial_plan,
)
from study_app.design.stimuli import Stimuli, app_version, find_stimulus_set

from .errors import InvalidAnswer, MaterialsChanged, TooEarly, UnknownParticipant, Withdrawn
from .events import (
    _TAB,
    MAX_EVENTS_PER_TRIAL,
    MEDIA_FAILED_EVENT,
    MEDIA_LOADED_EVENT,
    SHOWN_EVENT,
    WATCHED_ENOUGH,
    _picker_items,
    _ranges,
    _share,
    _unite,
    client_fields,
)
from .links import prolific_params

__all__ = ["Stage", "ParticipantSession", "STALE_TAB_TEXT"]

#: Participant ids are ``secrets.token_urlsafe(16)`` (22 characters); refuse anything
#: that could not be one before asking the database.
_PID = re.compile(r"^[A-Za-z0-9_-]{16,64}$")
#: What a tab says when the step it showed was answered elsewhere (another tab or
#: browser) first, so what it sent for that step was not stored.
STALE_TAB_TEXT = (
    "This question had already been answered in another window or tab, so "
    "the answer given here was not saved. Here is the next step."
)
#: Longest plausible response time (s) stored; longer ones (a tab left open) are clipped.
MAX_RESPONSE_TIME_S = 24 * 3600.0
#: Background questions: answer key → the study's choices key.
BACKGROUND_FIELDS = {"age_band": "age_bands", "gender": "genders", "experience": "experience"}
#: How the participant-facing messages name each background question.
BACKGROUND_NAMES = {"age_band": "age", "gender": "gender", "experience": "experience"}


@lru_cache(maxsize=4096)
def _plan(scene_ids: tuple, seed: int, shown: tuple = ()) -> tuple[Trial, ...]:
    return tuple(trial_plan(scene_ids, seed, shown=dict(shown)))


def _join(words: list[str]) -> str:
    """``a``, ``a and b``, ``a, b and c``."""
    return words[0] if len(words) == 1 else ", ".join(words[:-1]) + " and " + words[-1]


class Stage(StrEnum):
    """Where a participant is."""

    CONSENT = "consent"
    BACKGROUND = "background"
    POSE = "pose"
    VIEW = "view"
    ATTENTION = "attention"
    DONE = "done"


class ParticipantSession:
    """A participant's state, loaded from the store, and the only way to change it.

    Create one per script run with :meth:`start` (on consent) or :meth:`resume` (from
    the id in the URL); it is cheap (two queries).

    Parameters
    ----------
    store : study_app.data.store.Store
    stimuli : Stimuli
        The verified stimuli the app serves.
    participant : dict
        The participant record (:meth:`Store.get_participant`).
    answered : set of int
        Trial indices already answered.
    """

    def __init__(self, store, stimuli: Stimuli, participant: dict, answered: set[int]):
        self.store = store
        self.stimuli = stimuli
        self.participant = participant
        self.answered = set(answered)
        #: {trial index: epoch seconds} shown times this object stored or read
        self._shown: dict[int, float] = {}
        # The plan is a pure function of (scenes, seed): made once per participant and
        # process, not on every script run that resumes them.
        self.plan: list[Trial] = list(
            _plan(tuple(stimuli.scene_ids), int(participant["seed"]), stimuli.view_groups)
        )

    # -- construction --------------------------------------------------------------
    @classmethod
    def start(
        cls,
        store,
        stimuli: Stimuli,
        *,
        prolific: dict | None = None,
        seed: int | None = None,
        simulated: bool = False,
    ) -> ParticipantSession:
        """Register a new participant (they agreed to take part) and return their session.

        ``seed`` defaults to 62 random bits; pass one only to reproduce a plan.
        """
        if seed is None:
            seed = secrets.randbits(62)
        params = prolific_params(prolific or {})
        if params.get("PROLIFIC_PID") and not simulated:
            # One Prolific id, one participant: a second browser resumes the first record.
            pid, _ = store.participant_for_prolific(
                stimuli.study.id,
                stimuli.sha256,
                app_version=app_version(),
                seed=int(seed),
                prolific=params,
            )
            return cls.resume(store, stimuli, pid)
        pid = store.create_participant(
            stimuli.study.id,
            stimuli.sha256,
            app_version=app_version(),
            seed=int(seed),
            prolific=params or None,
            simulated=simulated,
        )
        return cls.resume(store, stimuli, pid)

    @classmethod
    def for_prolific(cls, store, stimuli: Stimuli, query: dict) -> ParticipantSession | None:
        """The session already registered for the URL's ``PROLIFIC_PID``, or None.

        A Prolific participant who returns with the study link (no ``pid``), from any
        browser, resumes where they were instead of consenting again; one who withdrew
        gets :class:`Withdrawn`.
        """
        ppid = prolific_params(query).get("PROLIFIC_PID")
        if not ppid:
            return None
        pid = store.find_prolific(stimuli.study.id, ppid)
        if pid is None:
            # A Prolific participant who withdrew is not enrolled again by the study link.
            gone = withdrawal_of(store, prolific_pid=ppid, study_id=stimuli.study.id)
            if gone is not None:
                raise Withdrawn(gone.withdrawn_at)
            return None
        return cls.resume(store, stimuli, pid)

    @classmethod
    def resume(cls, store, stimuli: Stimuli, participant_id) -> ParticipantSession:
        """The session of an existing participant.

        Raises
        ------
        Withdrawn
            The participant withdrew: their data were deleted.
        UnknownParticipant
            The id is malformed or unknown, belongs to another study, or the participant
            started with different stimuli (answers would not be comparable).
        """
        if not isinstance(participant_id, str) or not _PID.match(participant_id):
            raise UnknownParticipant(
                "This participant link is not valid. Please use the "
                "link you were given, or start a new session."
            )
        part, answered = store.participant_state(participant_id)
        if part is None:
            gone = withdrawal_of(store, participant_id=participant_id)
            if gone is not None:
                raise Withdrawn(gone.withdrawn_at)
            raise UnknownParticipant(
                "This participant link is not known to this study. "
                "Please use the link you were given, or start a new session."
            )
        if part["study_id"] != stimuli.study.id:
            raise UnknownParticipant("This participant link belongs to another study.")
        # A participant who started before the stimuli were rebuilt goes on with the set
        # they started on (kept beside the new one): never answers against another set.
        own = find_stimulus_set(stimuli, part["manifest_sha256"])
        if own is None or own.study.id != part["study_id"]:
            raise MaterialsChanged(
                "The study's materials have changed since you started, "
                "and the ones you saw are no longer available, so this "
                "session cannot continue. Your answers so far are saved. "
                "Please contact the researchers."
            )
        return cls(store, own, part, answered)

    # -- where the participant is ----------------------------------------------------
    @property
    def participant_id(self) -> str:
        return self.participant["participant_id"]

    @property
    def seed(self) -> int:
        return int(self.participant["seed"])

    @property
    def current_trial(self) -> Trial | None:
        """The first unanswered trial (None when all are answered)."""
        for t in self.plan:
            if t.index not in self.answered:
                return t
        return None

    @property
    def stage(self) -> Stage:
        if self.participant.get("background") is None:
            return Stage.BACKGROUND
        t = self.current_trial
        return Stage.DONE if t is None else Stage(t.task)

    @property
    def step_key(self):
        """The step on screen: ``"background"``, a trial index, or ``"done"``."""
        if self.participant.get("background") is None:
            return "background"
        t = self.current_trial
        return "done" if t is None else t.index

    def is_done(self, step) -> bool:
        """Whether a step (:attr:`step_key` value) has been answered."""
        if step == "background":
            return self.participant.get("background") is not None
        return isinstance(step, int) and step in self.answered

    def progress(self) -> tuple[int, int]:
        """``(steps done, steps in all)``: consent, background, then each trial."""
        total = 2 + len(self.plan)
        done = 1 + (self.participant.get("background") is not None) + len(self.answered)
        return min(done, total), total

    @property
    def completion_code(self) -> str | None:
        return self.participant.get("completion_code")

    def trial_shown_at(self, trial_index: int) -> float:
        """When the trial was first shown to this participant, in any browser session
        (seconds since the epoch).

        The first call stores a :data:`SHOWN_EVENT`; later calls (after a reload, in a
        second tab, days later) read the earliest one back, so reloading the page does
        not restart the response time.
        """
        if trial_index not in self._shown:
            self._shown[trial_index] = self.store.first_event_or_record(
                self.participant_id, trial_index, SHOWN_EVENT, self._shown_payload()
            ).timestamp()
        return self._shown[trial_index]

    def _shown_payload(self) -> dict:
        """The rules the answer will be held to, stored with the moment they start."""
        study = self.stimuli.study
        return {"min_answer_s": study.min_answer_s, "require_watch": study.require_watch}

    # -- answers -----------------------------------------------------------------------
    def submit_background(self, answers: dict) -> bool:
        """Store the background answers; each must be one of the study's choices."""
        clean, missing = {}, []
        for key, choices_key in BACKGROUND_FIELDS.items():
            value = answers.get(key)
            if value not in self.stimuli.study.background[choices_key]:
                missing.append(BACKGROUND_NAMES[key])
            clean[key] = value
        if missing:
            raise InvalidAnswer(
                "Please answer the question"
                + ("s" if len(missing) > 1 else "")
                + " about your "
                + _join(missing)
                + "."
            )
        extra = answers.get("gender_self")
        if isinstance(extra, str) and extra.strip():
            clean["gender_self"] = extra.strip()[:100]
        stored = self.store.set_background(self.participant_id, clean)
        self.participant = (
            {**self.participant, "background": clean}
            if stored
            else self.store.get_participant(self.participant_id)
        )
        return bool(stored)

    def _trial_for(self, trial_index, task: str) -> Trial | None:
        """The trial an answer claims to answer; None if it is already answered."""
        if (
            isinstance(trial_index, bool)
            or not isinstance(trial_index, int)
            or not 0 <= trial_index < len(self.plan)
        ):
            raise InvalidAnswer(f"There is no question number {trial_index!r} in this study.")
        trial = self.plan[trial_index]
        if trial.task != task:
            raise InvalidAnswer("This answer does not belong to the current question.")
        if trial_index in self.answered:
            return None  # a re-sent answer: harmless, nothing changes
        if self.participant.get("background") is None:
            raise InvalidAnswer("Please answer the questions about yourself first.")
        current = self.current_trial  # not None: this trial is not answered yet
        if current is None or trial_index != current.index:
            raise InvalidAnswer("Please answer the questions in order; this page was out of date.")
        return trial

    def _time(self, response_time_s) -> float:
        t = float(response_time_s)
        if not math.isfinite(t) or t < 0:
            raise InvalidAnswer("The response time is not valid.")
        if t < self.stimuli.study.min_answer_s:
            # Too soon after the trial appeared to be about it: typically the second
            # click of a double click, landing on the next trial's button.
            raise TooEarly(
                "That click came before this question was on screen long enough "
                "to be an answer to it; nothing was saved. Please take a look "
                "and answer again."
            )
        return min(t, MAX_RESPONSE_TIME_S)

    def _record(self, row: Answer, trial_events=()) -> bool:
        """Store an answer with ``trial_events`` (``(kind, payload)`` of its trial) and,
        when another trial follows, that trial's :data:`SHOWN_EVENT`, in one transaction:
        the run after an answer shows the next trial at once, so its clock starts with
        the answer (the few milliseconds of that run before the page shows count as
        answering time, as they did when that run stored the event), and that run need
        not write it."""
        i = row["trial_index"]
        events = [(i, kind, payload) for kind, payload in trial_events]
        following = i + 1 if i + 1 < len(self.plan) else None
        if following is not None:
            events.append((following, SHOWN_EVENT, self._shown_payload()))
        at = datetime.now(UTC)
        stored = self.store.record_response(self.participant_id, row, with_events=events, at=at)
        if stored and following is not None:
            self._shown[following] = at.timestamp()
        self.answered.add(row["trial_index"])
        return bool(stored)

    def submit_pose(
        self,
        trial_index: int,
        video_frame,
        *,
        response_time_s: float,
        events=(),
        watched: float | None = None,
        ranges=None,
        client: dict | None = None,
    ) -> bool:
        """Answer a pose task with the confirmed frame of the video.

        The video frame is checked against the scene's frame map and converted to the
        motion frame (source numbering). Returns True if stored, False if this trial was
        already answered (nothing changes).

        Parameters
        ----------
        watched : float, optional
            Share of the animation played in the video player (0-1, the largest the
            player reported in this or an earlier page load of the trial). With the
            study's ``require_watch`` it must reach :data:`WATCHED_ENOUGH`; None means
            the participant used the frame slider (stored as ``picked_with =
            "slider"``, so the analysis can leave it out), and the row's ``watched`` is
            what the stored log says the player played before the video failed (None
            if nothing).
        ranges : list of [float, float], optional
            The video frames played (the player's played ranges), united with the
            stored ones to give the share watched.
        client : dict, optional
            What the answer was given on (:func:`client_fields`).

        Raises
        ------
        InvalidAnswer
            Wrong or out-of-order trial, a frame outside the video, an answer too soon
            after the trial appeared (:class:`TooEarly`) or before the animation was
            watched through. Nothing is written.
        """
        trial = self._trial_for(trial_index, "pose")
        if trial is None:
            return False
        sc = self.stimuli.scenes[trial.scene]
        try:
            v, m = check_video_frame(video_frame, sc.video_to_motion)
        except AnswerError as err:
            raise InvalidAnswer(f"That frame cannot be stored: {err}.") from None
        slider_watched = None
        if watched is None:
            # The slider (the video failed, or the study's picker): what the player did
            # play before it failed stays on the row, not only in its log.
            slider_watched = self.watched(trial.index) or None
        if watched is not None:
            if (
                isinstance(watched, bool)
                or not isinstance(watched, (int, float))
                or not 0 <= watched <= 1
            ):
                raise InvalidAnswer("The player reported an invalid viewing time.")
            watched = max(
                float(watched),
                self.watched(trial.index),
                _share(_ranges(ranges), sc.n_video_frames, self._ranges(trial.index)),
            )
            if self.stimuli.study.require_watch and watched < WATCHED_ENOUGH:
                raise InvalidAnswer(
                    "Please watch the whole animation once before choosing a frame."
                )
        share = watched if watched is not None else slider_watched
        row: Answer = {
            "trial_index": trial.index,
            "task": "pose",
            "scene": trial.scene,
            "stimulus_id": trial.stimulus_id,
            "chosen_frame": m,
            "chosen_video_frame": v,
            "algorithm_frame": sc.algorithm_frame,
            "fps": sc.fps,
            "n_frames": sc.n_frames,
            "response_time_s": self._time(response_time_s),
            "picked_with": "slider" if watched is None else "player",
            "watched": None if share is None else round(min(share, 1.0), 3),
        }
        row = {**row, **client_fields(client, row["response_time_s"])}
        # The picker's log goes with the answer (its "select" entry carries how much was
        # watched), in the same transaction.
        return self._record(row, _picker_items(events, n_video_frames=sc.n_video_frames))

    def record_picker_events(self, trial_index, events) -> int:
        """Store a batch of the picker's log while the trial is open (sent as it happens,
        so a reload loses nothing); return how many were stored.

        Batches for a trial that is answered, not a pose task or not the current one
        are ignored (0), as are entries beyond :data:`MAX_EVENTS_PER_TRIAL` a trial.
        """
        t = self.current_trial
        if t is None or t.task != "pose" or trial_index != t.index or isinstance(trial_index, bool):
            return 0
        sc = self.stimuli.scenes[t.scene]
        items = _picker_items(events, n_video_frames=sc.n_video_frames)
        if not items:
            return 0
        return self.store.record_events(
            self.participant_id, t.index, items, limit=MAX_EVENTS_PER_TRIAL
        )

    def picker_state(self, trial_index: int) -> tuple[int, float]:
        """``(frame, watched)`` to restore the player at: the last frame the stored log
        shows (0 before any) and the share watched so far (the stored played ranges
        united, or the largest share a log entry reports)."""
        frame, watched, _ = self.watch_record(trial_index)
        return frame, watched

    def watch_record(self, trial_index: int) -> tuple[int, float, list]:
        """``(frame, watched, ranges)`` of the stored log of a trial: the last frame, the
        share watched and the video frames played (``[[from, to], ...]``, united)."""
        frame, watched, ranges = 0, 0.0, []
        for e in self.store.events(self.participant_id):
            if e["trial_index"] != trial_index or e["kind"] in (
                SHOWN_EVENT,
                MEDIA_FAILED_EVENT,
                MEDIA_LOADED_EVENT,
            ):
                continue
            p = e["payload"] or {}
            if isinstance(p.get("frame"), int):
                frame = p["frame"]
            if isinstance(p.get("watched"), (int, float)):
                watched = max(watched, float(p["watched"]))
            ranges.extend(_ranges(p.get("ranges")))
        ranges = _unite(ranges)
        t = self.plan[trial_index] if 0 <= trial_index < len(self.plan) else None
        if t is not None and t.task == "pose":
            watched = max(watched, _share(ranges, self.stimuli.scenes[t.scene].n_video_frames))
        return frame, min(watched, 1.0), ranges

    def _ranges(self, trial_index: int) -> list:
        return self.watch_record(trial_index)[2]

    def watched(self, trial_index: int) -> float:
        """The share of the trial's animation the stored log says was watched."""
        return self.picker_state(trial_index)[1]

    def record_media_failure(self, trial_index, what: str, positions=(), tab=None) -> bool:
        """Record that the current trial's media did not load in the participant's
        browser after retries (:data:`MEDIA_FAILED_EVENT`); nothing is answered. An
        image report without positions says they all loaded again after "Try again"
        (:data:`MEDIA_LOADED_EVENT`: their positions can be chosen again). False
        (nothing stored) for a trial that is not the current one."""
        t = self.current_trial
        if (
            t is None
            or isinstance(trial_index, bool)
            or trial_index != t.index
            or what not in ("image", "video")
        ):
            return False
        payload = {
            "what": what,
            "positions": [
                p
                for p in positions or ()
                if isinstance(p, int) and not isinstance(p, bool) and 0 <= p < 8
            ][:8],
        }
        if isinstance(tab, str) and _TAB.match(tab):
            payload["tab"] = tab
        kind = MEDIA_FAILED_EVENT
        if what == "image" and not payload["positions"]:
            if not self.failed_positions(t.index):
                return False  # nothing had failed: nothing to clear
            kind = MEDIA_LOADED_EVENT
        return (
            self.store.record_events(
                self.participant_id,
                t.index,
                [(kind, payload)],
                limit=MAX_EVENTS_PER_TRIAL,
            )
            > 0
        )

    def submit_view(
        self,
        trial_index: int,
        position,
        method=None,
        *,
        response_time_s: float,
        client: dict | None = None,
    ) -> bool:
        """Answer a view task: the screen position clicked.

        The method is looked up in the participant's seeded screen order (the page never
        knows it); a caller that names one must name the method shown there.

        Raises
        ------
        InvalidAnswer
            Wrong trial, a position that does not exist, a method that is not what the
            participant's seeded order put at that position, or an answer too soon
            after the trial appeared (:class:`TooEarly`). Nothing is written.
        """
        trial = self._trial_for(trial_index, "view")
        if trial is None:
            return False
        try:
            p, m = check_view_choice(trial, position, method)
        except AnswerError as err:
            raise InvalidAnswer(f"That choice cannot be stored: {err}.") from None
        if p in self.failed_positions(trial.index):
            raise InvalidAnswer(
                "That picture did not load in your browser, so it cannot be chosen. Please "
                "press “Try again”, or “I can't see the pictures” to go on."
            )
        row = self._view_row(trial, self._time(response_time_s), client)
        row.update({"chosen_method": m, "chosen_position": p})
        return self._record(row)

    def _view_row(self, trial: Trial, response_time_s: float, client) -> Answer:
        """A view trial's row without its answer: what was shown (each picture with the
        methods it stands for), when, on what."""
        sc = self.stimuli.scenes[trial.scene]
        row: Answer = {
            "trial_index": trial.index,
            "task": "view",
            "scene": trial.scene,
            "stimulus_id": trial.stimulus_id,
            "algorithm_frame": sc.algorithm_frame,
            "fps": sc.fps,
            "n_frames": sc.n_frames,
            "shown_order": list(trial.shown_order or ()),
            "shown_groups": [
                list(g) for g in trial.shown_groups or [(m,) for m in trial.shown_order or ()]
            ],
            "response_time_s": response_time_s,
        }
        row = {**row, **client_fields(client, row["response_time_s"])}
        return row

    def failed_positions(self, trial_index: int) -> set[int]:
        """The positions whose pictures the browser last reported as not loading after
        retries (:data:`MEDIA_FAILED_EVENT`; a later :data:`MEDIA_LOADED_EVENT` clears
        them)."""
        last: list = []
        for e in self.store.events(self.participant_id):
            p = e["payload"] or {}
            if e["trial_index"] != trial_index or p.get("what") != "image":
                continue
            if e["kind"] == MEDIA_FAILED_EVENT:
                last = [x for x in p.get("positions") or () if isinstance(x, int)]
            elif e["kind"] == MEDIA_LOADED_EVENT:
                last = []
        return set(last)

    def skip_view(self, trial_index, *, response_time_s: float, client: dict | None = None) -> bool:
        """Pass on a view trial whose pictures did not load: stored as a row with
        ``skipped = "media_failed"`` and no choice (never a vote), so the participant
        can finish. Returns True if stored, False if the trial was already answered.

        Raises
        ------
        InvalidAnswer
            The browser reported no picture of this trial as failed (the way on is
            offered only then), or the trial is not the current view trial.
        """
        trial = self._trial_for(trial_index, "view")
        if trial is None:
            return False
        if not self.failed_positions(trial.index):
            raise InvalidAnswer(
                "All pictures of this question have loaded: please choose the one that "
                "shows best what the figure is doing."
            )
        # Not held to min_answer_s: there was no full set of pictures to look at.
        t = float(response_time_s)
        if not math.isfinite(t) or t < 0:
            raise InvalidAnswer("The response time is not valid.")
        row = self._view_row(trial, min(t, MAX_RESPONSE_TIME_S), client)
        row["skipped"] = "media_failed"
        return self._record(row)

    def submit_attention(
        self, trial_index: int, answer, *, response_time_s: float, client: dict | None = None
    ) -> bool:
        """Answer the attention check (stored with whether it was right, and what it was
        given on: :func:`client_fields`)."""
        trial = self._trial_for(trial_index, "attention")
        if trial is None:
            return False
        try:
            correct = check_attention_answer(self.stimuli.study, answer)
        except AnswerError:
            raise InvalidAnswer("Please choose one of the options.") from None
        row: Answer = {
            "trial_index": trial.index,
            "task": "attention",
            "scene": trial.scene,
            "stimulus_id": trial.stimulus_id,
            "chosen_value": answer,
            "correct": correct,
            "response_time_s": self._time(response_time_s),
        }
        row = {**row, **client_fields(client, row["response_time_s"])}
        return self._record(row)

    def finish(self) -> str:
        """Mark the participant complete; return the completion code (idempotent)."""
        if self.stage is not Stage.DONE:
            raise InvalidAnswer("There are still questions to answer.")
        code = self.store.complete(self.participant_id, code=self.stimuli.study.completion_code)
        self.participant = {**self.participant, "completion_code": code}
        return code

    def redirect(self, code: str) -> str | None:
        """The study's redirect link for ``code`` (e.g. back to Prolific), or None."""
        return redirect_url(self.stimuli.study, code)

    def view_choices(self, trial: Trial) -> list[tuple[str, object]]:
        """``[(method, image path), ...]`` in the participant's screen order (server side
        only: the page gets the images by position)."""
        sc = self.stimuli.scenes[trial.scene]
        return [(m, sc.views[m]) for m in trial.shown_order or ()]
