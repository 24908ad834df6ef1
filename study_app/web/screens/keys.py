"""Every name the app gives to Streamlit's session state, the URL and the environment.

One constant per key, so a page, the app script and the tests spell a key one way (the
load test's driver copies a few of them: it must not import the UI).
"""

from __future__ import annotations

__all__ = [
    "QUERY_PID",
    "KEY_SESSION",
    "KEY_PARTICIPANT_ID",
    "KEY_ON_SCREEN",
    "KEY_PROBLEM",
    "KEY_WITHDRAWN",
    "KEY_ANSWERS_KEPT",
    "KEY_TRIAL_SHOWN",
    "KEY_PICKER_START",
    "KEY_ATTEMPT",
    "KEY_ANSWERED_HERE",
    "KEY_FRESH_SESSION",
    "KEY_FLASH",
    "KEY_FRAMES_FALLBACK",
    "KEY_CONSENT_AGREE",
    "KEY_CONSENT_START",
    "KEY_BG_FORM",
    "KEY_BG_SUBMIT",
    "KEY_BG_AGE",
    "KEY_BG_GENDER",
    "KEY_BG_EXPERIENCE",
    "KEY_BG_GENDER_SELF",
    "KEY_ATTENTION_CHOICE",
    "KEY_ATTENTION_SUBMIT",
    "KEY_PICKER",
    "KEY_CHOOSER",
    "KEY_FRAME_SLIDER",
    "KEY_FRAME_CONFIRM",
    "KEY_ADMIN_TOKEN",
    "KEY_DOWNLOAD",
    "KEY_WITHDRAW_KIND",
    "KEY_WITHDRAW_ID",
    "KEY_WITHDRAW_CONFIRM",
    "KEY_WITHDRAW_BUTTON",
    "KEY_RESTART",
    "ENV_STIMULI",
    "ENV_DB",
    "ENV_ADMIN_TOKEN",
]

#: URL query parameter carrying the participant id.
QUERY_PID = "pid"

# -- session-state keys (one place, named) --------------------------------------------
#: The run's ParticipantSession (or None before consent), set by app.py.
KEY_SESSION = "snapshot.session"
#: The participant id this browser tab started or resumed: Back to the study link
#: (an address without ``pid``) resumes them instead of showing the consent page.
KEY_PARTICIPANT_ID = "snapshot.participant_id"
#: (participant id, step) this browser tab showed on its previous run; a step that
#: moved on without this tab answering was answered in another tab or browser.
KEY_ON_SCREEN = "snapshot.on_screen"
#: Why the participant id in the URL was refused (shown by the invalid-link page).
KEY_PROBLEM = "snapshot.problem"
#: True when the refused link is that of a participant who withdrew.
KEY_WITHDRAWN = "snapshot.withdrawn"
#: True when the refused link is that of a participant whose answers are stored but
#: whose stimuli are gone (the page must not say nothing was recorded).
KEY_ANSWERS_KEPT = "snapshot.answers_kept"
#: {(participant id, trial index): wall-clock time the trial was first shown}.
KEY_TRIAL_SHOWN = "snapshot.trial_shown"
#: {(participant id, player widget key): (frame, share watched)} the player starts
#: from in this browser session (read from the stored log once per mount).
KEY_PICKER_START = "snapshot.picker_start"
#: {trial index: attempt number}; a rejected answer remounts the widget fresh.
KEY_ATTEMPT = "snapshot.attempt"
#: {(participant id, step)} this browser tab answered itself (see claim_step).
KEY_ANSWERED_HERE = "snapshot.answered_here"
#: The session an answer's callback (or a fragment) read and updated just now, for the
#: full run that follows, which then need not read it again (see take_fresh_session).
KEY_FRESH_SESSION = "snapshot.fresh_session"
#: A message to show once on the next run (kind, text).
KEY_FLASH = "snapshot.flash"
#: {(participant id, trial index)} whose video this browser could not play (after
#: retries): that trial uses the frame slider (its answer says so); the next trial tries
#: the player again.
KEY_FRAMES_FALLBACK = "snapshot.frames_fallback"
#: Widget keys (AppTest drives widgets by these).
KEY_CONSENT_AGREE = "consent.agree"
KEY_CONSENT_START = "consent.start"
KEY_BG_FORM = "background.form"
KEY_BG_SUBMIT = "background.submit"
KEY_BG_AGE = "background.age_band"
KEY_BG_GENDER = "background.gender"
KEY_BG_EXPERIENCE = "background.experience"
KEY_BG_GENDER_SELF = "background.gender_self"
KEY_ATTENTION_CHOICE = "attention.choice"
KEY_ATTENTION_SUBMIT = "attention.submit"
KEY_PICKER = "pose.picker"
KEY_CHOOSER = "view.chooser"
KEY_FRAME_SLIDER = "pose.slider"
KEY_FRAME_CONFIRM = "pose.confirm"
KEY_ADMIN_TOKEN = "researcher.token"
KEY_DOWNLOAD = "researcher.download"
#: Withdrawal on the researcher page: which id, the id, the confirmation (its key ends
#: with the id, so a confirmation never carries over to another id), the button.
KEY_WITHDRAW_KIND = "researcher.withdraw.kind"
KEY_WITHDRAW_ID = "researcher.withdraw.id"
KEY_WITHDRAW_CONFIRM = "researcher.withdraw.confirm"
KEY_WITHDRAW_BUTTON = "researcher.withdraw.button"
KEY_RESTART = "invalid.restart"

# -- environment (set by `snapshot study`) -------------------------------------------
#: Stimuli folder to serve (default: the demo's, ``var/stimuli/demo``).
ENV_STIMULI = "SNAPSHOT_STIMULI"
#: Database URL (read by the store; default SQLite under ``var/``).
ENV_DB = "SNAPSHOT_DB"
#: Token that opens the researcher page; without it the page shows nothing.
ENV_ADMIN_TOKEN = "SNAPSHOT_ADMIN_TOKEN"
