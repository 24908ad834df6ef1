"""`snapshot loadtest` against a real `snapshot study` server: both drivers, the report
schema, the database afterwards, and bad input in one line.

The protocol driver's participants include ones who reload, go Back to the study link
and double-click answers; whatever they do, the database must hold each participant
once and each answer they sent exactly once, as sent. The browser driver (headless
Chromium) goes through the same server and must agree.
"""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import jsonschema
import pytest
from app_helpers import tiny_demo_stimuli
from click.testing import CliRunner
from test_e2e import CHROMIUM, start_study, stop_process

from data_schema import schema_path
from snapcore.cli.main import cli
from study_app.data.store import Store

pytestmark = [pytest.mark.slow]

SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
#: The tiny study: two scenes, so 2 pose + 2 view trials + the attention check.
N_TRIALS = 5


def _schema() -> dict:
    return json.loads(schema_path("loadtest").read_text(encoding="utf-8"))


@pytest.fixture(scope="module")
def study(tmp_path_factory):
    """`snapshot study` on the tiny stimuli writing its script-run timings; yields
    (base url, database url, timings file)."""
    stimuli, r = tiny_demo_stimuli(tmp_path_factory)
    if r is not None:
        assert r.returncode == 0, r.stderr
    folder = tmp_path_factory.mktemp("loadtest")
    db = f"sqlite:///{folder / 'study.db'}"
    timings = folder / "timings.jsonl"
    old = os.environ.get("SNAPSHOT_TIMINGS")
    os.environ["SNAPSHOT_TIMINGS"] = str(timings)  # start_study passes os.environ on
    try:
        proc, base = start_study(stimuli, db, folder / "server.log")
    finally:
        if old is None:
            os.environ.pop("SNAPSHOT_TIMINGS", None)
        else:
            os.environ["SNAPSHOT_TIMINGS"] = old
    yield base, db, timings
    stop_process(proc)


def _run(args, tmp_path) -> tuple[subprocess.CompletedProcess, dict]:
    out = tmp_path / "report.json"
    r = subprocess.run(
        [SNAPSHOT, "loadtest", *args, "--json", str(out)],
        capture_output=True,
        text=True,
        timeout=300,
    )
    assert r.returncode == 0, r.stdout + r.stderr
    report = json.loads(out.read_text())
    jsonschema.validate(report, _schema(), cls=jsonschema.Draft202012Validator)
    return r, report


def _assert_stored_once(db: str, results_prolific: set[str]) -> None:
    """Straight from the database: each participant once, each trial answered once."""
    store = Store(db)
    try:
        parts = [p for p in store.participants() if p["prolific_pid"] in results_prolific]
        assert len(parts) == len(results_prolific)
        for p in parts:
            assert p["completion_code"]
            trials = [row["trial_index"] for row in store.responses(p["participant_id"])]
            assert sorted(trials) == list(range(N_TRIALS))
    finally:
        store.close()


def _prolific_ids(db: str, session_prefix: str) -> set[str]:
    store = Store(db)
    try:
        return {
            p["prolific_pid"]
            for p in store.participants()
            if (p.get("prolific_session_id") or "").startswith(session_prefix)
        }
    finally:
        store.close()


def test_protocol_driver_every_answer_stored_once(study, tmp_path):
    """Four participants (reloading, going Back, double-clicking) all finish; every
    answer is stored once as sent; the report follows its schema."""
    base, db, timings = study
    _, report = _run(
        [
            "--url",
            base,
            "-n",
            "4",
            "--ramp",
            "1",
            "--think",
            "1.5",
            "--seed",
            "7",
            "--reload",
            "1",
            "--back",
            "1",
            "--double-click",
            "1",
            "--db",
            db,
            "--timings",
            str(timings),
        ],
        tmp_path,
    )
    assert report["completed"] == 4 and report["errors"]["count"] == 0
    db_check = report["database"]
    assert db_check["ok"], db_check["problems"]
    assert db_check["answers_stored_once"] == db_check["answers_sent"] == 4 * N_TRIALS
    # The odd behaviours happened (seeded), and the server's own timings were read.
    for action in ("reload", "back", "double_click", "pose_confirm", "view_choose"):
        assert report["latency"][action]["n"] > 0, action
    assert report["server_script_runs"]["n"] > 0
    assert report["server"]["processes"] == 1  # found by the URL's port
    pids = _prolific_ids(db, "s")
    _assert_stored_once(db, pids)
    # Choosing a background answer and the player's log batches rerun only their
    # st.fragment, as in a browser: the server timed such runs, and the log batches
    # those runs received are in the database (play, ended, seek for every animation).
    runs = [json.loads(line) for line in timings.read_text().splitlines()]
    fragment_stages = {r["stage"] for r in runs if r.get("fragment")}
    assert {"background", "pose"} <= fragment_stages, fragment_stages
    store = Store(db)
    try:
        for p in store.participants():
            if p["prolific_pid"] not in pids:
                continue
            pose = {
                r["trial_index"]
                for r in store.responses(p["participant_id"])
                if r["task"] == "pose"
            }
            logged = {(e["trial_index"], e["kind"]) for e in store.events(p["participant_id"])}
            for t in pose:
                assert {(t, "play"), (t, "ended"), (t, "seek"), (t, "select")} <= logged, t
    finally:
        store.close()


def test_protocol_driver_answers_refused_as_too_early_are_sent_again(study, tmp_path):
    """Participants who click faster than the study's minimum answer time (1 s) have
    answers refused and answer again on the same page: the driver must expect the
    second answer on the same trial (the attention check shows no trial index), so the
    database check holds."""
    base, db, _ = study
    _, report = _run(
        [
            "--url",
            base,
            "-n",
            "2",
            "--ramp",
            "0",
            "--think",
            "0.3",
            "--seed",
            "3",
            "--reload",
            "0",
            "--back",
            "0",
            "--double-click",
            "0",
            "--db",
            db,
        ],
        tmp_path,
    )
    assert report["completed"] == 2
    db_check = report["database"]
    assert db_check["ok"], db_check["problems"]
    assert db_check["answers_stored_once"] == db_check["answers_sent"] == 2 * N_TRIALS
    # Some answers did come too early (0.15-0.45 s after the page), and were sent again.
    assert report["latency"]["attention_submit"]["n"] > 2


@pytest.mark.browser
def test_browser_driver_agrees(study, tmp_path):
    """Two participants in headless Chromium: same report shape, same database check."""
    pytest.importorskip("playwright.async_api")
    if not os.path.exists(CHROMIUM):
        pytest.skip(f"no Chromium at {CHROMIUM}")
    base, db, _ = study
    _, report = _run(
        [
            "--url",
            base,
            "-n",
            "2",
            "--ramp",
            "1",
            "--think",
            "1",
            "--seed",
            "8",
            "--driver",
            "browser",
            "--db",
            db,
        ],
        tmp_path,
    )
    assert report["completed"] == 2
    assert report["database"]["ok"], report["database"]["problems"]
    assert report["database"]["answers_stored_once"] == 2 * N_TRIALS
    assert report["latency"]["pose_confirm"]["n"] == 2 * 2
    _assert_stored_once(db, _prolific_ids(db, "b"))


def test_report_schema_rejects_a_report_without_latency():
    """The schema is not empty: a report missing its latencies is refused."""
    doc = {
        "config": {
            "url": "x",
            "participants": 1,
            "ramp_s": 0,
            "think_s": 0,
            "seed": 0,
            "driver": "protocol",
        },
        "elapsed_s": 1,
        "participants": 1,
        "completed": 1,
        "reconnects": 0,
        "errors": {"count": 0, "first": []},
        "server": {},
    }
    with pytest.raises(jsonschema.ValidationError):
        jsonschema.validate(doc, _schema(), cls=jsonschema.Draft202012Validator)
    doc["latency"] = {"all": {"n": 0, "p50": None, "p95": None, "max": None}}
    jsonschema.validate(doc, _schema(), cls=jsonschema.Draft202012Validator)


@pytest.mark.parametrize(
    "args, says",
    [
        (["--url", "http://127.0.0.1:9"], "cannot reach the study"),
        (["--url", "not a url"], "cannot reach the study"),
    ],
)
def test_unreachable_study_is_one_line_exit_2(args, says):
    """An address where no study answers: one line, exit code 2, no traceback."""
    r = CliRunner().invoke(cli, ["loadtest", *args, "-n", "1"])
    assert r.exit_code == 2, r.output
    assert says in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_broken_database_url_is_one_line_exit_2(study):
    """A database that cannot be opened: one line, exit code 2, before any participant."""
    base, _, _ = study
    r = CliRunner().invoke(
        cli,
        [
            "loadtest",
            "--url",
            base,
            "-n",
            "1",
            "--db",
            "postgresql+psycopg://nobody@127.0.0.1:9/none",
        ],
    )
    assert r.exit_code == 2, r.output
    assert "cannot open database" in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_server_warm_up_imports_what_the_first_runs_need():
    """The server's warm-up thread (study_app.web.server) loads, before any participant
    arrives, the modules the first player page would import inside a script run:
    pandas and pyarrow (Streamlit scans component data for frames), SQLAlchemy, the
    pages. Run in a fresh interpreter, so nothing was imported before."""
    code = (
        "import sys; from study_app.web.server import warm_up; warm_up(); "
        "print(' '.join(m for m in ('pandas', 'pyarrow', 'sqlalchemy', "
        "'study_app.web.screens.pose_task', 'study_app.session') if m in sys.modules))"
    )
    before = subprocess.run(
        [sys.executable, "-c", "import sys, study_app.web.server; print('pandas' in sys.modules)"],
        capture_output=True,
        text=True,
        check=True,
    )
    assert before.stdout.strip() == "False"  # importing the launcher alone loads nothing
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert r.stdout.split() == [
        "pandas",
        "pyarrow",
        "sqlalchemy",
        "study_app.web.screens.pose_task",
        "study_app.session",
    ]


def test_server_warm_up_hides_the_imports_from_the_garbage_collector():
    """After the warm-up, the objects the imports made are frozen (gc.freeze): full
    collections under load then walk only what the sessions made (they paused the
    server 150-240 ms each before). Run in a fresh interpreter."""
    code = (
        "import gc; from study_app.web.server import _warm_in_background; "
        "print(gc.get_freeze_count()); _warm_in_background(); print(gc.get_freeze_count())"
    )
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    before, after = map(int, r.stdout.split())
    assert before == 0 and after > 100_000, (before, after)


def test_indexed_config_sections_give_what_streamlit_gives():
    """The server's section index returns, for every configuration section, exactly what
    Streamlit's own walk over all options returns, also after a value changes and after
    the configuration is parsed again. Run in a fresh interpreter (it patches Streamlit)."""
    code = """
import json
from streamlit import config
from study_app.web.server import index_config_sections
original = config.get_options_for_section
sections = sorted({o.section for o in config.get_config_options().values()})
def both():
    return [(original(s), config.get_options_for_section(s)) for s in sections]
index_config_sections()
assert config.get_options_for_section is not original
out = [a == b for a, b in both()]
config.set_option("theme.primaryColor", "#123456")
out += [a == b for a, b in both()]
assert config.get_options_for_section("theme")["primaryColor"] == "#123456"
config.get_config_options(force_reparse=True)
out += [a == b for a, b in both()]
print(json.dumps([len(sections), all(out)]))
"""
    r = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    n_sections, same = json.loads(r.stdout)
    assert n_sections > 10 and same


def _get(url: str, accept: str):
    """(status, Location header) of one GET that does not follow redirects."""
    import urllib.error
    import urllib.request

    class NoRedirect(urllib.request.HTTPRedirectHandler):
        def redirect_request(self, *args, **kwargs):
            return None

    opener = urllib.request.build_opener(NoRedirect)
    try:
        with opener.open(urllib.request.Request(url, headers={"Accept": accept}), timeout=10) as r:
            return r.status, r.headers.get("Location")
    except urllib.error.HTTPError as err:
        return err.code, err.headers.get("Location")


def test_deep_page_addresses_go_to_the_study_with_their_query(study):
    """A participant's browser asking for a page two folders deep (an old or mistyped link:
    /pages/consent) is sent to the study with the same query, instead of Streamlit's page
    that takes /pages for the app's base path and stays blank. Streamlit's own routes and
    non-page requests are untouched."""
    base, *_ = study
    html = "text/html,application/xhtml+xml,application/xml;q=0.9,*/*;q=0.8"
    assert _get(f"{base}/pages/consent?PROLIFIC_PID=p1&STUDY_ID=s", html) == (
        307,
        "/?PROLIFIC_PID=p1&STUDY_ID=s",
    )
    assert _get(f"{base}/study/a/b", html) == (307, "/")
    # One segment that is not a page of the app (every step is at the root; issue 29:
    # Streamlit showed "Page not found" over /study), with its query; the researcher
    # page is one.
    assert _get(f"{base}/study?pid=x1", html) == (307, "/?pid=x1")
    assert _get(f"{base}/researcher", html)[0] == 200
    assert _get(f"{base}/_stcore/health", html)[0] == 200
    assert _get(f"{base}/pages/consent", "*/*")[0] != 307  # a script's fetch: not a page
