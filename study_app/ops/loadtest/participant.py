"""One simulated participant: consent to completion code through :class:`StreamlitClient`.

The participant acts as a person on the study's pages would, one widget at a time (each
change of a widget is a script run, as in the browser), thinking ``think_s`` seconds
(drawn around the mean, seeded) before each answer. Its answers come from the suite's one
participant model, :class:`analysis.simulate.SimulatedParticipant` with
:data:`LOADTEST_OBSERVER` (the page tells neither the algorithm's pick, nor which method
is where, nor the attention check's answer, so choices are valid and uniform): an age
band, a gender and an experience from the page's own options, a frame inside the video
after a log batch that says the animation was watched, a view position, an attention
option. A share of participants also reload the page, go Back to the study link, or
double-click an answer; the study must end the same way for them.

Every interaction's time (send to the end of the last script run it caused) is kept by
action name, for the report.
"""

from __future__ import annotations

import asyncio
import random
from dataclasses import dataclass, field

import numpy as np

from analysis.simulate import ObserverModel, SimulatedParticipant
from study_app.session import STALE_TAB_TEXT

from .client import Element, Page, ProtocolError, StreamlitClient

__all__ = [
    "Behaviour",
    "ParticipantResult",
    "run_participant",
    "page_kind",
    "ACTIONS",
    "LOADTEST_OBSERVER",
    "answering_person",
]

#: Action names in the latency report.
ACTIONS = (
    "open",
    "consent_agree",
    "consent_start",
    "background_field",
    "background_submit",
    "pose_log",
    "pose_confirm",
    "view_choose",
    "attention_choice",
    "attention_submit",
    "reload",
    "back",
    "double_click",
)
#: Keys of the app's widgets (study_app.web.screens.keys; copied, as the driver must not
#: import the UI layer).
K_AGREE, K_START = "consent.agree", "consent.start"
K_AGE, K_GENDER, K_EXP = "background.age_band", "background.gender", "background.experience"
K_BG_SUBMIT = "background.submit"
K_PICKER, K_CHOOSER = "pose.picker", "view.chooser"
K_ATT_CHOICE, K_ATT_SUBMIT = "attention.choice", "attention.submit"
#: The background choice that opens a free-text box (left out: the box is optional).
SELF_DESCRIBE = "Prefer to self-describe"
#: Most pages a correct run can take (consent, background, trials, stale pages).
MAX_STEPS = 200
#: How a load-test participant answers: a frame anywhere in the clip (the page does not
#: tell the algorithm's pick), views by equal strengths (nor which method is where).
LOADTEST_OBSERVER = ObserverModel(pose_model="uniform")


def answering_person(rng: random.Random) -> SimulatedParticipant:
    """The participant model behind one load-test participant's answers, seeded from its
    own ``rng`` (so a run's seed gives the same answers)."""
    return SimulatedParticipant(np.random.default_rng(rng.getrandbits(64)), LOADTEST_OBSERVER)


@dataclass(frozen=True)
class Behaviour:
    """What one participant does besides answering.

    Attributes
    ----------
    reload, back, double_click : bool
        Reload the page once mid-study; go Back once to the study link (no ``pid``);
        double-click one answer (the second click while the first still runs).
    """

    reload: bool = False
    back: bool = False
    double_click: bool = False


@dataclass
class ParticipantResult:
    """What happened to one participant."""

    index: int
    prolific_pid: str
    participant_id: str | None = None
    completion_code: str | None = None
    latencies: dict = field(default_factory=dict)  # action -> [seconds]
    errors: list = field(default_factory=list)
    reconnects: int = 0
    answers: dict = field(default_factory=dict)  # trial index -> what was sent
    started: float = 0.0
    finished: float = 0.0

    def add(self, action: str, seconds: float) -> None:
        self.latencies.setdefault(action, []).append(seconds)


def page_kind(page: Page) -> str:
    """Which step a page shows: consent, background, pose, view, attention, done or unknown."""
    if page.widget(K_PICKER):
        return "pose"
    if page.widget(K_CHOOSER):
        return "view"
    if page.widget(K_ATT_SUBMIT):
        return "attention"
    if page.widget(K_BG_SUBMIT):
        return "background"
    if page.widget(K_START):
        return "consent"
    if page.has_text("Thank you"):
        return "done"
    return "unknown"


def _need(page: Page, key: str) -> Element:
    """The page's widget ``key``; a page without it is not the page its kind promised."""
    w = page.widget(key)
    if w is None:
        raise ProtocolError(f"no widget {key!r} on the page: {page.texts()[:3]}")
    return w


def _attention_index(result: ParticipantResult) -> int:
    """The attention check's trial index: the trial after the last pose or view trial
    answered (the page does not show its index; the plan puts it after them). An answer
    refused as too early leaves the same page on screen: the next one is for the same
    trial, not the one after."""
    return max((i for i, a in result.answers.items() if a["task"] != "attention"), default=-1) + 1


class _Run:
    """The participant's state while running (kept small: hundreds run at once)."""

    def __init__(
        self,
        client: StreamlitClient,
        result: ParticipantResult,
        rng: random.Random,
        think_s: float,
        behaviour: Behaviour,
        reconnect,
    ):
        self.c, self.r, self.rng = client, result, rng
        self.person = answering_person(rng)  # the answers; rng: timing and behaviour
        self.think_s, self.b, self.reconnect = think_s, behaviour, reconnect
        self.did_reload = self.did_back = self.did_double = False

    async def think(self, scale: float = 1.0) -> None:
        # Uniform in [0.5, 1.5] x the mean: participants do not click in lockstep.
        await asyncio.sleep(self.think_s * scale * self.rng.uniform(0.5, 1.5))

    async def act(self, action: str, *, triggers=None, history=False) -> Page:
        """One user action; on a dropped connection (a replica died), reconnect and
        reload as the browser does, and report the page the reload shows."""
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        try:
            page = await self.c.rerun(triggers=triggers, history=history)
        except (TimeoutError, ProtocolError, OSError) as err:
            self.r.errors.append(f"{action}: {type(err).__name__}: {err}")
            page = await self.reconnect(self)
            self.r.reconnects += 1
        self.r.add(action, loop.time() - t0)
        return page

    async def open(self) -> Page:
        loop = asyncio.get_running_loop()
        t0 = loop.time()
        try:
            await self.c.connect()
            page = await self.c.rerun()
        except (TimeoutError, ProtocolError, OSError) as err:
            # The server went away while the page loaded: the browser retries.
            self.r.errors.append(f"open: {type(err).__name__}: {err}")
            page = await self.reconnect(self)
            self.r.reconnects += 1
        self.r.add("open", loop.time() - t0)
        return page

    async def step(self, page: Page) -> Page:
        kind = page_kind(page)
        if (
            kind in ("pose", "view", "attention", "background")
            and self.b.reload
            and not self.did_reload
            and self.rng.random() < 0.3
        ):
            self.did_reload = True
            t0 = asyncio.get_running_loop().time()
            page = await self.c.reload()
            self.r.add("reload", asyncio.get_running_loop().time() - t0)
            return page
        if (
            kind in ("pose", "view")
            and self.b.back
            and not self.did_back
            and self.rng.random() < 0.3
        ):
            self.did_back = True
            # Back to the study link the participant came from: no pid in the address.
            pid = self.c.query_params().get("pid")
            self.c.query = "&".join(
                f"{k}={v}" for k, v in self.c.query_params().items() if k != "pid"
            )
            page = await self.act("back", history=True)
            if pid and "pid=" not in self.c.query:
                self.r.errors.append("back: the app did not put the pid back into the URL")
            return page
        if kind == "consent":
            await self.think(0.5)
            self.c.set_value(_need(page, K_AGREE), True)
            page = await self.act("consent_agree")
            await self.think(0.25)
            return await self.act("consent_start", triggers=[self.c.click(_need(page, K_START))])
        if kind == "background":
            for key in (K_AGE, K_GENDER, K_EXP):
                w = _need(page, key)
                options = [o for o in w.options if o != SELF_DESCRIBE]
                await self.think(0.3)
                self.c.set_value(w, self.person.choose(options))
                page = await self.act("background_field")
            await self.think(0.3)
            return await self.submit(
                "background_submit",
                _need(page, K_BG_SUBMIT),
                self.c.click(_need(page, K_BG_SUBMIT)),
            )
        if kind == "pose":
            w = _need(page, K_PICKER)
            d = w.data or {}
            trial, n = int(d["trial"]), int(d["n_frames"])
            frame = self.person.pose_frame(0, n - 1)
            await self.think()
            # The player sends its log while the participant watches and steps.
            log = [
                {"kind": "play", "t": 0.0, "frame": 0},
                {
                    "kind": "ended",
                    "t": round(n / max(d.get("fps", 24.0), 1.0), 3),
                    "frame": n - 1,
                    "watched": 1.0,
                },
                {"kind": "seek", "t": 5.0, "frame": frame},
            ]
            page = await self.act(
                "pose_log",
                triggers=[self.c.component_event(w, "log", {"trial": trial, "events": log})],
            )
            w = page.widget(K_PICKER) or w
            await self.think(0.5)
            value = {
                "trial": trial,
                "frame": frame,
                "watched": 1.0,
                "events": [{"kind": "select", "t": 6.0, "frame": frame, "watched": 1.0}],
            }
            self.r.answers[trial] = {"task": "pose", "video_frame": frame}
            return await self.submit("pose_confirm", w, self.c.component_event(w, "confirm", value))
        if kind == "view":
            w = _need(page, K_CHOOSER)
            d = w.data or {}
            trial = int(d["trial"])
            position = self.person.view_position(len(d["views"]))
            await self.think()
            self.r.answers[trial] = {"task": "view", "position": position}
            return await self.submit(
                "view_choose",
                w,
                self.c.component_event(w, "choice", {"trial": trial, "position": position}),
            )
        if kind == "attention":
            w = _need(page, K_ATT_CHOICE)
            choice = self.person.attention_answer(w.options)
            await self.think()
            self.c.set_value(w, choice)
            d = {"task": "attention", "value": choice}
            page = await self.act("attention_choice")
            self.r.answers[_attention_index(self.r)] = d
            await self.think(0.25)
            b = _need(page, K_ATT_SUBMIT)
            # "Continue" is the answer button (a component): its press reports the client.
            press = {"client": {"viewport": [1366, 768], "dpr": 1, "input": "mouse"}}
            return await self.submit(
                "attention_submit", b, self.c.component_event(b, "press", press)
            )
        raise ProtocolError(f"unexpected page: {page.texts()[:3]}")

    async def submit(self, action: str, widget, trigger) -> Page:
        """Send an answer; a double-clicker sends it twice, the second click while the
        first one's script still runs (the browser sends both)."""
        if self.b.double_click and not self.did_double and self.rng.random() < 0.3:
            self.did_double = True
            loop = asyncio.get_running_loop()
            t0 = loop.time()
            await self.c.rerun(triggers=[trigger], wait=False)
            page = await self.act(action, triggers=[trigger])
            self.r.add("double_click", loop.time() - t0)
            if page.has_text(STALE_TAB_TEXT):
                # The second click repeats this tab's own answer: nothing to tell.
                self.r.errors.append(
                    f"{action}: a double click was told its answer came from another window"
                )
            return page
        return await self.act(action, triggers=[trigger])


async def run_participant(
    url: str,
    index: int,
    *,
    seed: int,
    think_s: float,
    behaviour: Behaviour = Behaviour(),
    prolific: bool = True,
    timeout_s: float = 120.0,
    max_reconnects: int = 5,
) -> ParticipantResult:
    """Drive one participant from the study link to the completion code.

    Parameters
    ----------
    url : str
        The study's address (a server, or nginx in front of replicas).
    index : int
        The participant's number in the run (part of its Prolific id and seed).
    seed : int
        The run's seed; this participant's choices come from ``(seed, index)``.
    think_s : float
        Mean seconds between actions on a trial page (less on the form pages).
    behaviour : Behaviour
        Reload / Back / double-click once.
    prolific : bool
        Open the study link with Prolific parameters (a launch on Prolific).

    Returns
    -------
    ParticipantResult
        Latencies, errors, the completion code (None when the participant did not
        finish).
    """
    rng = random.Random(f"{seed}:{index}")
    prolific_pid = f"{rng.getrandbits(96):024x}"
    result = ParticipantResult(index=index, prolific_pid=prolific_pid)
    query = (
        f"PROLIFIC_PID={prolific_pid}&STUDY_ID=loadtest&SESSION_ID=s{index:05d}" if prolific else ""
    )
    client = StreamlitClient(url, query=query, timeout_s=timeout_s)
    loop = asyncio.get_running_loop()
    result.started = loop.time()

    async def reconnect(run: _Run) -> Page:
        # The browser reconnects to the same address; behind nginx that may be another
        # replica, which resumes the participant from the pid in the URL.
        for attempt in range(max_reconnects):
            await asyncio.sleep(0.5 * (attempt + 1))
            try:
                return await client.reload()
            except (TimeoutError, ProtocolError, OSError) as err:
                result.errors.append(f"reconnect: {type(err).__name__}: {err}")
        raise ProtocolError("could not reconnect")

    run = _Run(client, result, rng, think_s, behaviour, reconnect)
    try:
        page = await run.open()
        for _ in range(MAX_STEPS):
            kind = page_kind(page)
            if kind == "done":
                codes = page.texts("code")
                result.completion_code = codes[0] if codes else ""
                break
            page = await run.step(page)
        else:
            result.errors.append("did not finish within the step limit")
    except Exception as err:  # noqa: BLE001 - one participant's failure is data, not a crash
        import traceback

        where = traceback.extract_tb(err.__traceback__)
        at = " <- ".join(f"{f.name}:{f.lineno}" for f in reversed(where[-4:]))
        result.errors.append(f"fatal: {type(err).__name__}: {err} (at {at})")
    finally:
        result.participant_id = client.query_params().get("pid")
        result.finished = loop.time()
        try:
            await client.close()
        except Exception:  # noqa: BLE001
            pass
    return result
