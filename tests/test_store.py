"""The study store (study_app.data.store), on SQLite and real PostgreSQL (exports and
`snapshot export`: ``test_store_export.py``).

Backend-parametrised tests run twice: on a SQLite file in a temp folder and on a fresh
database of a throw-away PostgreSQL server (tests/pg.py; skipped locally, failed in
CI when the server binaries are missing).
"""

from __future__ import annotations

import random
import socket
import sqlite3
import threading
from concurrent.futures import ThreadPoolExecutor
from datetime import UTC, datetime
from pathlib import Path

import pytest
import sqlalchemy as sa

import study_app
from snapcore.errors import SnapshotError
from snapcore.select.view_methods import VIEW_METHODS
from study_app.data.database import SQLITE_BUSY_TIMEOUT_MS
from study_app.data.errors import StoreError
from study_app.data.store import Store, default_url, mask_url, normalize_url

SHA = "ab" * 32
METHODS = [str(m) for m in VIEW_METHODS]


# ----------------------------------------------------------------------------- fixtures
@pytest.fixture
def sqlite_url(tmp_path) -> str:
    return f"sqlite:///{tmp_path / 'study.db'}"


@pytest.fixture(params=["sqlite", pytest.param("postgresql", marks=pytest.mark.postgres)])
def store_url(request, tmp_path) -> str:
    """A URL of an empty database, on each backend."""
    if request.param == "sqlite":
        return f"sqlite:///{tmp_path / 'study.db'}"
    return request.getfixturevalue("pg_url")


@pytest.fixture
def store(store_url):
    s = Store(store_url)
    yield s
    s.close()


def pose_row(trial: int, *, frame: int = 40, rt: float = 3.5) -> dict:
    return {
        "trial_index": trial,
        "task": "pose",
        "scene": f"scene{trial}",
        "stimulus_id": f"scene{trial}-pose",
        "chosen_frame": frame,
        "chosen_video_frame": frame // 2,
        "algorithm_frame": 52,
        "fps": 60.0,
        "n_frames": 300,
        "response_time_s": rt,
    }


def view_row(
    trial: int,
    *,
    position: int = 1,
    order=("motion_area", "ours", "viewpoint_entropy"),
    rt: float = 2.0,
) -> dict:
    return {
        "trial_index": trial,
        "task": "view",
        "scene": f"scene{trial}",
        "stimulus_id": f"scene{trial}-view",
        "chosen_method": order[position],
        "chosen_position": position,
        "shown_order": list(order),
        "response_time_s": rt,
    }


def attention_row(trial: int, *, answer: str = "blue", correct: bool = True) -> dict:
    return {
        "trial_index": trial,
        "task": "attention",
        "scene": "attention",
        "stimulus_id": "attention-colour",
        "chosen_value": answer,
        "correct": correct,
        "response_time_s": 1.25,
    }


def new_participant(store, **kw) -> str:
    kw.setdefault("app_version", "0.1.0")
    kw.setdefault("seed", 7)
    return store.create_participant("demo", SHA, **kw)


def count_rows(store, table: str) -> int:
    with store.engine.connect() as conn:
        return conn.exec_driver_sql(f"SELECT COUNT(*) FROM {table}").scalar()


def tampered(pid: str) -> str:
    """The same id with its last character changed (still well-formed)."""
    return pid[:-1] + ("A" if pid[-1] != "A" else "B")


# ----------------------------------------------------------------------------- opening
def test_default_url_is_repo_var_and_env_overrides(monkeypatch, tmp_path):
    """Default: sqlite at <repo>/var/study.db (repo = parent of study_app); $SNAPSHOT_DB wins."""
    monkeypatch.delenv("SNAPSHOT_DB", raising=False)
    repo = Path(study_app.__file__).resolve().parent.parent
    assert default_url() == f"sqlite:///{repo / 'var' / 'study.db'}"
    target = tmp_path / "elsewhere" / "deep" / "env.db"
    monkeypatch.setenv("SNAPSHOT_DB", f"sqlite:///{target}")
    with Store() as s:
        pid = new_participant(s)
    assert target.exists(), "the folder of the SQLite file is created"
    assert sqlite3.connect(target).execute(
        "SELECT participant_id FROM participants"
    ).fetchall() == [(pid,)]


def test_url_normalisation_and_masking():
    """postgresql:// maps to psycopg; passwords never appear in what we print."""
    u = normalize_url("postgresql://alice:s3cret@db.example:5433/study")
    assert u.drivername == "postgresql+psycopg" and u.port == 5433 and u.database == "study"
    assert (
        mask_url("postgresql+psycopg://alice:s3cret@h/db") == "postgresql+psycopg://alice:***@h/db"
    )
    assert "s3cret" not in mask_url("weird://alice:s3cret@h:not-a-port/db")
    assert normalize_url("some/where/study.db").drivername == "sqlite"
    with pytest.raises(StoreError, match="not a database URL"):
        normalize_url("postgres-typo-without-scheme")


def test_sqlite_pragmas(sqlite_url):
    """Every SQLite connection: WAL journal, busy timeout, foreign keys enforced."""
    with Store(sqlite_url) as s:
        with s.engine.connect() as conn:
            assert conn.exec_driver_sql("PRAGMA journal_mode").scalar() == "wal"
            assert conn.exec_driver_sql("PRAGMA busy_timeout").scalar() == SQLITE_BUSY_TIMEOUT_MS
            assert conn.exec_driver_sql("PRAGMA foreign_keys").scalar() == 1
        # Foreign keys really enforced: a response of nobody is refused by the database.
        with pytest.raises(sa.exc.IntegrityError), s.engine.begin() as conn:
            conn.exec_driver_sql(
                "INSERT INTO responses (participant_id, trial_index, task, scene, stimulus_id,"
                " response_time_s, created_at, app_version, manifest_sha256)"
                " VALUES ('nobody-nobody-nobody', 0, 'pose', 's', 's', 1, '2020-01-01', 'v', 'x')"
            )


@pytest.mark.parametrize(
    "url, expect",
    [
        ("nosuchdb://user:pw@host/db", "unknown database type"),
        ("sqlite:///{tmp}/a-file/study.db", "cannot create folder"),  # parent is a file
        ("sqlite:///{tmp}/a-dir.db", "unable to open database file"),  # the path is a folder
        ("postgresql://alice:s3cret@127.0.0.1:{port}/db", "Connection refused"),
    ],
)
def test_broken_url_is_one_line_store_error(url, expect, tmp_path):
    """A broken URL gives one line naming the (masked) URL, and nothing else."""
    (tmp_path / "a-file").write_text("not a folder")
    (tmp_path / "a-dir.db").mkdir()
    with socket.socket() as sock:  # a loopback port that nobody listens on
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    url = url.format(tmp=tmp_path, port=port)
    with pytest.raises(StoreError) as info:
        Store(url)
    message = str(info.value)
    assert expect in message and "\n" not in message
    shown = normalize_url(url).render_as_string(hide_password=True)  # postgresql → +psycopg
    assert shown in message and "s3cret" not in message and "pw@" not in message


@pytest.mark.postgres
def test_postgres_wrong_password(request):
    """A wrong password is an authentication error, reported with the password masked."""
    url = request.getfixturevalue("pg_server").url("postgres", password="wrong-password")
    with pytest.raises(StoreError) as info:
        Store(url)
    message = str(info.value)
    assert "password authentication failed" in message
    assert "wrong-password" not in message and "***" in message and "\n" not in message


def test_reopening_never_drops_data(store_url):
    """create_all on an existing database keeps every row (and other tables)."""
    with Store(store_url) as s:
        pid = new_participant(s)
        assert s.record_response(pid, pose_row(0))
        with s.engine.begin() as conn:
            conn.exec_driver_sql("CREATE TABLE lab_notes (note VARCHAR(20))")
            conn.exec_driver_sql("INSERT INTO lab_notes VALUES ('keep me')")
    with Store(store_url) as again:
        assert again.answered_trials(pid) == {0}
        assert again.get_participant(pid)["seed"] == 7
        with again.engine.connect() as conn:
            assert conn.exec_driver_sql("SELECT note FROM lab_notes").scalar() == "keep me"


def test_reader_does_not_create_databases(tmp_path):
    """Store(create=False) (export) refuses a missing SQLite file instead of making one."""
    missing = tmp_path / "typo.db"
    with pytest.raises(StoreError, match="no such file"):
        Store(f"sqlite:///{missing}", create=False)
    assert not missing.exists()
    sqlite3.connect(tmp_path / "other.db").execute("CREATE TABLE t (x)").connection.close()
    with pytest.raises(StoreError, match="no study tables"):
        Store(f"sqlite:///{tmp_path / 'other.db'}", create=False)


# ----------------------------------------------------------------------------- participants
def test_participants(store):
    """Ids are unguessable and distinct; every given field is stored; unknown id → None."""
    before = datetime.now(UTC)
    pid = new_participant(
        store, seed=2**62, prolific={"PROLIFIC_PID": "5f1a", "STUDY_ID": "st9", "SESSION_ID": "se3"}
    )
    after = datetime.now(UTC)
    other = new_participant(store, simulated=True)
    assert pid != other and len(pid) >= 22  # token_urlsafe(16): 128 random bits
    p = store.get_participant(pid)
    assert (p["study_id"], p["seed"], p["manifest_sha256"], p["app_version"]) == (
        "demo",
        2**62,
        SHA,
        "0.1.0",
    )
    assert (p["prolific_pid"], p["prolific_study_id"], p["prolific_session_id"]) == (
        "5f1a",
        "st9",
        "se3",
    )
    assert p["simulated"] is False and store.get_participant(other)["simulated"] is True
    assert p["completed_at"] is None and p["completion_code"] is None and p["background"] is None
    created = datetime.fromisoformat(p["created_at"])
    assert created.utcoffset().total_seconds() == 0 and before <= created <= after
    assert store.get_participant(tampered(pid)) is None
    assert store.get_participant("../../etc/passwd") is None
    with pytest.raises(StoreError, match="seed"):
        new_participant(store, seed=-1)
    with pytest.raises(StoreError, match="manifest_sha256"):
        store.create_participant("demo", "not-a-hash", app_version="1", seed=1)


def test_background_first_answers_stay(store):
    pid = new_participant(store)
    answers = {"age_band": "25-34", "gender": "woman", "experience": "some"}
    assert store.set_background(pid, answers) is True
    assert store.set_background(pid, {"age_band": "65+"}) is False
    assert store.get_participant(pid)["background"] == answers


def test_complete_is_idempotent(store):
    """complete() twice: the same code, the first completion time kept."""
    pid = new_participant(store)
    code = store.complete(pid)
    first = store.get_participant(pid)
    assert store.complete(pid) == code and store.complete(pid, code="OTHER") == code
    assert store.get_participant(pid)["completed_at"] == first["completed_at"] is not None
    assert len(code) == 8 and code.isalnum()
    fixed = new_participant(store)
    assert store.complete(fixed, code="C1PROLIFIC") == "C1PROLIFIC"
    assert store.progress()["completed"] == 2


# ----------------------------------------------------------------------------- responses
def test_resend_is_harmless(store):
    """The second answer to a trial returns False and the first row stays unchanged."""
    pid = new_participant(store)
    first = pose_row(0, frame=40, rt=3.5)
    assert store.record_response(pid, first) is True
    assert store.record_response(pid, pose_row(0, frame=99, rt=9.0)) is False
    assert store.record_response(pid, first) is False
    (row,) = store.export_rows()
    assert (row["chosen_frame"], row["response_time_s"]) == (40, 3.5)
    assert count_rows(store, "responses") == 1


def test_batch_skips_answered(store):
    """record_responses: one transaction, new trials only; a bad row writes nothing."""
    pid = new_participant(store)
    assert store.record_response(pid, pose_row(1))
    assert store.record_responses(pid, [pose_row(0), pose_row(1, frame=5), view_row(2)]) == 2
    assert store.answered_trials(pid) == {0, 1, 2}
    with pytest.raises(StoreError, match="chosen_method"):
        store.record_responses(pid, [pose_row(3), view_row(4) | {"chosen_method": "forged"}])
    assert store.answered_trials(pid) == {0, 1, 2}


def test_resume_sees_answers_after_reopen(store_url):
    """A reload (or a restarted server: a new Store) resumes from the stored answers."""
    with Store(store_url) as s:
        pid = new_participant(s)
        for row in (pose_row(0), pose_row(1), view_row(3)):
            assert s.record_response(pid, row)
        assert s.answered_trials(pid) == {0, 1, 3}
    with Store(store_url) as s2:
        answered = s2.answered_trials(pid)
        assert answered == {0, 1, 3}
        # the first unanswered trial of a 5-trial protocol is 2
        assert min(set(range(5)) - answered) == 2
        assert s2.answered_trials(new_participant(s2)) == set()


def test_unknown_or_tampered_id_writes_nothing(store):
    """Every write with an unknown, tampered or malformed id raises and writes nothing."""
    pid = new_participant(store)
    assert store.record_response(pid, pose_row(0))
    for bad in (tampered(pid), "x" * 22, "'; DROP TABLE responses; --", "", None, 42):
        with pytest.raises(StoreError, match="unknown participant"):
            store.record_response(bad, pose_row(1))
        with pytest.raises(StoreError, match="unknown participant"):
            store.record_event(bad, 1, "play", {})
        with pytest.raises(StoreError, match="unknown participant"):
            store.set_background(bad, {"age_band": "18-24"})
        with pytest.raises(StoreError, match="unknown participant"):
            store.complete(bad)
        with pytest.raises(StoreError, match="unknown participant"):
            store.answered_trials(bad)
    assert count_rows(store, "responses") == 1
    assert count_rows(store, "events") == 0
    assert count_rows(store, "participants") == 1
    assert store.get_participant(pid)["background"] is None


@pytest.mark.parametrize(
    "change, field",
    [
        ({"chosen_method": "forged"}, "chosen_method"),  # a forged method label
        ({"chosen_method": "ours", "chosen_position": 0}, "chosen_method"),  # not shown there
        ({"chosen_position": 3}, "chosen_position"),
        ({"shown_order": ["ours", "ours", "motion_area"]}, "shown_order"),
        ({"shown_order": ["ours", "mine", "motion_area"]}, "shown_order"),
        ({"chosen_position": -1}, "chosen_position"),
        ({"task": "quiz"}, "task"),
        ({"response_time_s": float("nan")}, "response_time_s"),
        ({"shown_order": "ours"}, "shown_order"),
        ({"participant_id": "someone-else-entirely"}, "participant_id"),  # not a trial field
        ({"trial_index": None}, "trial_index"),
        ({"task": "pose", "chosen_frame": -3}, "chosen_frame"),
    ],
)
def test_bad_row_is_refused(sqlite_url, change, field):
    """A row that breaks the schema names the field and writes nothing."""
    with Store(sqlite_url) as s:
        pid = new_participant(s)
        with pytest.raises(StoreError, match=field):
            s.record_response(pid, view_row(0) | change)
        assert count_rows(s, "responses") == 0


def test_events(store):
    pid = new_participant(store)
    store.record_event(pid, 0, "play", {"t": 0.0})
    store.record_event(pid, 0, "seek", {"from": 1.5, "to": 0.25})
    store.record_event(pid, None, "page", {"name": "consent"})
    got = store.events(pid)
    assert [(e["kind"], e["trial_index"], e["payload"]) for e in got] == [
        ("play", 0, {"t": 0.0}),
        ("seek", 0, {"from": 1.5, "to": 0.25}),
        ("page", None, {"name": "consent"}),
    ]
    with pytest.raises(StoreError, match="payload"):
        store.record_event(pid, 0, "seek", {"to": float("inf")})
    assert len(store.events()) == 3
    # a batch: all or nothing
    assert store.record_events(pid, 1, [("play", {}), ("step", {"frame": 3})]) == 2
    with pytest.raises(StoreError, match="payload"):
        store.record_events(pid, 2, [("play", {}), ("seek", {"to": float("nan")})])
    assert [(e["kind"], e["trial_index"]) for e in store.events(pid)[3:]] == [
        ("play", 1),
        ("step", 1),
    ]
    with pytest.raises(StoreError, match="unknown participant"):
        store.record_events(tampered(pid), 1, [("play", {})])
    assert len(store.events()) == 5


def test_event_limit_per_trial(store):
    """A trial holds at most ``limit`` events: a batch past it is cut, other trials and
    participants do not count."""
    pid, other = new_participant(store), new_participant(store)
    store.record_events(other, 0, [("play", {})] * 4)
    store.record_events(pid, 1, [("play", {})] * 4)
    assert store.record_events(pid, 0, [("step", {"i": i}) for i in range(4)], limit=6) == 4
    assert store.record_events(pid, 0, [("seek", {"i": i}) for i in range(4)], limit=6) == 2
    assert store.record_events(pid, 0, [("play", {})], limit=6) == 0
    mine = [(e["kind"], e["payload"]) for e in store.events(pid) if e["trial_index"] == 0]
    assert mine == [("step", {"i": i}) for i in range(4)] + [("seek", {"i": 0}), ("seek", {"i": 1})]


def test_first_event_at(store):
    """The earliest event of a kind per trial, as an aware UTC time, on each backend."""
    from datetime import UTC, datetime, timedelta

    pid = new_participant(store)
    assert store.first_event_at(pid, 0, "shown") is None
    before = datetime.now(UTC)
    store.record_event(pid, 0, "shown")
    first = store.first_event_at(pid, 0, "shown")
    store.record_event(pid, 0, "shown")  # a second tab: the first one still counts
    store.record_event(pid, 1, "shown")
    assert store.first_event_at(pid, 0, "shown") == first
    assert first.tzinfo is not None
    assert before - timedelta(seconds=1) <= first <= datetime.now(UTC)
    assert store.first_event_at(pid, 1, "shown") >= first
    assert store.first_event_at(pid, None, "shown") is None
    with pytest.raises(StoreError, match="unknown participant|participant id"):
        store.first_event_at(tampered(pid) + "!", 0, "shown")


def test_first_event_or_record(store):
    """Stores the event only when there is none, with its payload; returns the earliest."""
    pid = new_participant(store)
    first = store.first_event_or_record(pid, 0, "shown", {"min_answer_s": 1.0})
    assert store.first_event_or_record(pid, 0, "shown", {"min_answer_s": 9.0}) == first
    assert store.first_event_at(pid, 0, "shown") == first
    got = [(e["trial_index"], e["payload"]) for e in store.events(pid)]
    assert got == [(0, {"min_answer_s": 1.0})]  # one event: the second call only read
    assert store.first_event_or_record(pid, 1, "shown") >= first
    assert len(store.events(pid)) == 2
    with pytest.raises(StoreError, match="unknown participant|participant id"):
        store.first_event_or_record(tampered(pid), 0, "shown")
    assert len(store.events()) == 2


def test_participant_state_is_the_record_and_the_answered_trials(store):
    pid = new_participant(store)
    assert store.participant_state(pid) == (store.get_participant(pid), set())
    store.record_responses(pid, [pose_row(0), view_row(2)])
    part, answered = store.participant_state(pid)
    assert part == store.get_participant(pid) and answered == {0, 2}
    assert store.participant_state(tampered(pid)) == (None, set())
    assert store.participant_state("x; drop table participants") == (None, set())


def test_progress_counts(store):
    real = [new_participant(store) for _ in range(3)]
    sim = new_participant(store, simulated=True)
    store.record_responses(real[0], [pose_row(0), pose_row(1), view_row(2)])
    store.record_responses(real[1], [pose_row(0)])
    store.record_responses(sim, [pose_row(0), attention_row(1)])
    store.complete(real[0])
    assert store.progress() == {
        "participants": 3,
        "completed": 1,
        "responses": 4,
        "by_task": {"pose": 3, "view": 1},
        "simulated": 1,
    }
    assert store.progress(include_simulated=True)["by_task"] == {
        "attention": 1,
        "pose": 4,
        "view": 1,
    }


# ----------------------------------------------------------------------------- load
N_PARTICIPANTS = 50
N_TRIALS = 10  # answered one by one by each participant's own thread
RESENT = (2, 5, 9)  # trials each participant re-sends (a double click, a retry)


def test_concurrent_participants(store):
    """50 participants answer at once (threads), re-sending some answers, and two racing
    requests per participant send the same last trial: exactly one row per trial."""
    start = threading.Barrier(N_PARTICIPANTS)
    stored_first = {}  # (pid, trial) -> the row whose send returned True
    lock = threading.Lock()
    n_false = [0]

    def send(pid, row):
        ok = store.record_response(pid, row)
        with lock:
            if ok:
                assert (pid, row["trial_index"]) not in stored_first
                stored_first[(pid, row["trial_index"])] = row
            else:
                n_false[0] += 1
        return ok

    def participant(k: int) -> str:
        rng = random.Random(k)
        start.wait()
        pid = store.create_participant("load", SHA, app_version="0.1.0", seed=k)
        for t in range(N_TRIALS):
            row = (
                pose_row(t, frame=rng.randrange(300), rt=rng.uniform(0.5, 9))
                if t % 2 == 0
                else view_row(t, position=rng.randrange(3), order=rng.sample(METHODS, 3))
            )
            assert send(pid, row)
            if t in RESENT:
                assert not send(pid, row | {"response_time_s": 99.0})
            if t % 3 == 0:
                store.record_event(pid, t, "play", {"k": k})
        return pid

    with ThreadPoolExecutor(max_workers=N_PARTICIPANTS) as pool:
        pids = list(pool.map(participant, range(N_PARTICIPANTS)))

    # Phase 2: per participant two requests race on the same new trial (barrier: both
    # start together); exactly one must win.
    race = threading.Barrier(2 * N_PARTICIPANTS)

    def racer(arg):
        pid, j = arg
        race.wait()
        return send(pid, attention_row(N_TRIALS, answer=f"racer{j}"))

    with ThreadPoolExecutor(max_workers=2 * N_PARTICIPANTS) as pool:
        wins = list(pool.map(racer, [(p, j) for p in pids for j in (0, 1)]))
    assert sum(wins) == N_PARTICIPANTS

    expected = N_PARTICIPANTS * (N_TRIALS + 1)
    rows = store.export_rows(validate=True)
    assert len(rows) == expected == len(stored_first) == count_rows(store, "responses")
    assert n_false[0] == N_PARTICIPANTS * (len(RESENT) + 1)
    keys = [(r["participant_id"], r["trial_index"]) for r in rows]
    assert len(set(keys)) == expected  # none duplicated
    assert set(keys) == {(p, t) for p in pids for t in range(N_TRIALS + 1)}  # none lost
    for r in rows:  # the first answer is the one kept
        src = stored_first[(r["participant_id"], r["trial_index"])]
        assert all(r[k] == v for k, v in src.items())
    assert count_rows(store, "events") == N_PARTICIPANTS * len(range(0, N_TRIALS, 3))
    assert store.progress()["participants"] == N_PARTICIPANTS
    print(
        f"\n[{store.dialect}] {len(rows)} rows from {N_PARTICIPANTS} concurrent participants; "
        f"{n_false[0]} duplicate sends refused"
    )


def test_store_error_is_snapshot_error():
    assert issubclass(StoreError, SnapshotError)


def test_one_participant_per_prolific_id_under_concurrency(store_url):
    """Eight threads on two Store objects register the same Prolific id: one participant,
    every caller gets its id; the database itself refuses a second row (unique index)."""
    a, b = Store(store_url), Store(store_url)
    prolific = {"PROLIFIC_PID": "60a1b2c3d4e5f60718293a4b", "STUDY_ID": "s", "SESSION_ID": "x"}

    def register(k):
        s = (a, b)[k % 2]
        return s.participant_for_prolific(
            "demo", SHA, app_version="0.1.0", seed=k, prolific=prolific
        )

    with ThreadPoolExecutor(8) as pool:
        got = list(pool.map(register, range(8)))
    assert len({pid for pid, _ in got}) == 1 and sum(created for _, created in got) == 1
    assert a.find_prolific("demo", prolific["PROLIFIC_PID"]) == got[0][0]
    assert a.find_prolific("other-study", prolific["PROLIFIC_PID"]) is None
    with pytest.raises(StoreError):  # the index, not only the look-up, keeps it unique
        a.create_participant("demo", SHA, app_version="0.1.0", seed=1, prolific=prolific)
    # no Prolific id: as many participants as consents (NULLs do not collide)
    new_participant(a)
    new_participant(a)
    assert len(a.participants()) == 3
    a.close()
    b.close()


def test_old_database_gets_the_prolific_index(sqlite_url):
    """A database made before the index existed gets it when the app opens it."""
    s = Store(sqlite_url)
    with s.engine.begin() as conn:
        conn.exec_driver_sql("DROP INDEX uq_participants_study_prolific")
    s.close()
    s = Store(sqlite_url)
    with s.engine.connect() as conn:
        names = {i["name"] for i in sa.inspect(conn).get_indexes("participants")}
    assert "uq_participants_study_prolific" in names
    s.close()
