"""Open and ethical data: withdrawal, pseudonymised exports, backups, the Psych-DS dataset.

What is checked comes from outside the code under test: the database is read back by
reflection (every table it has, not the project's table list), pseudonyms are
recomputed from the documented formula with the secret read straight from the
database, exports are grepped as bytes, and the Psych-DS folder is checked against
``data_schema/psychds_layout.schema.json`` (our reading of the Psych-DS rules).
"""

from __future__ import annotations

import csv
import hashlib
import hmac
import io
import json
import sqlite3
import threading
import time
from datetime import UTC, datetime
from pathlib import Path

import jsonschema
import pytest
import sqlalchemy as sa
from app_helpers import fixture_study_doc, write_fixture_stimuli
from click.testing import CliRunner

from data_schema import schema_path
from snapcore.cli.main import cli
from study_app.data.backup import backup, find_pg_tool, restore
from study_app.data.errors import StoreError
from study_app.data.export import read_export
from study_app.data.pseudonym import Pseudonymiser, study_secret
from study_app.data.store import Store, normalize_url
from study_app.design.protocol import DEFAULT_CONTACT, consent_text, study_from_dict

SHA = "cd" * 32
#: Distinctive raw identifiers, so that a grep of the exports cannot hit anything else.
PROLIFIC = {"A": "5f1e2d3c4b5a69788796aaaa", "B": "5f1e2d3c4b5a69788796bbbb"}
SESSIONS = {"A": "SESSaaaa1111", "B": "SESSbbbb2222"}
BACKGROUND = {"age_band": "25–34", "gender": "Woman", "experience": "No experience"}


def pose(trial: int, frame: int = 30) -> dict:
    return {
        "trial_index": trial,
        "task": "pose",
        "scene": "walk",
        "stimulus_id": "walk/pose",
        "chosen_frame": frame,
        "chosen_video_frame": frame // 2,
        "algorithm_frame": 20,
        "fps": 48.0,
        "n_frames": 48,
        "response_time_s": 2.5,
    }


def view(trial: int) -> dict:
    order = ["motion_area", "ours", "viewpoint_entropy"]
    return {
        "trial_index": trial,
        "task": "view",
        "scene": "walk",
        "stimulus_id": "walk/view",
        "chosen_method": "ours",
        "chosen_position": 1,
        "shown_order": order,
        "response_time_s": 1.5,
    }


def populate(store, study_id: str = "fixture") -> dict:
    """Three participants (two from Prolific), each with background, answers and events."""
    pids = {}
    for name in ("A", "B", "C"):
        prolific = (
            {"PROLIFIC_PID": PROLIFIC[name], "STUDY_ID": "STUDYzz", "SESSION_ID": SESSIONS[name]}
            if name in PROLIFIC
            else None
        )
        pid = store.create_participant(
            study_id, SHA, app_version="0.1.0", seed=len(pids), prolific=prolific
        )
        store.set_background(pid, BACKGROUND)
        store.record_responses(pid, [pose(0, 10 + len(pids)), view(1)])
        store.record_events(pid, 0, [("play", {"t": 0.0}), ("pause", {"t": 0.5})])
        store.complete(pid)
        pids[name] = pid
    return pids


def dump(url) -> dict[str, list[tuple]]:
    """Every row of every table the database has (found by reflection), as text."""
    engine = sa.create_engine(normalize_url(url))
    meta = sa.MetaData()
    meta.reflect(engine)
    with engine.connect() as conn:
        out = {
            name: sorted(tuple(str(v) for v in row) for row in conn.execute(sa.select(t)))
            for name, t in meta.tables.items()
        }
    engine.dispose()
    return out


def cli_run(*args):
    result = CliRunner().invoke(cli, [str(a) for a in args])
    if result.exit_code not in (0, 2):
        raise result.exception
    return result.exit_code, result.stdout, result.stderr


@pytest.fixture
def url(tmp_path) -> str:
    return f"sqlite:///{tmp_path / 'study.db'}"


# ----------------------------------------------------------------------------- withdrawal
def test_withdraw_leaves_only_the_withdrawal_record(url):
    """After `snapshot withdraw --pid`, no table holds a row naming the participant but the
    withdrawal record; the others are untouched; export and analysis no longer count them."""
    from analysis.load import load_responses

    with Store(url) as s:
        pids = populate(s)
    before = dump(url)
    t0 = time.time()
    code, _, err = cli_run("withdraw", "--db", url, "--pid", pids["A"])
    assert code == 0, err
    assert "deleted 2 responses, 2 events" in err
    after = dump(url)
    gone = (pids["A"], PROLIFIC["A"], SESSIONS["A"])
    for table, rows in after.items():
        naming = [r for r in rows if any(g in cell for g in gone for cell in r)]
        assert len(naming) == (1 if table == "withdrawals" else 0), (table, naming)
    # The record: which id, which study, the Prolific id, by whom, when; no answers.
    con = sqlite3.connect(url.removeprefix("sqlite:///"))
    con.row_factory = sqlite3.Row
    (rec,) = con.execute("SELECT * FROM withdrawals").fetchall()
    assert (rec["participant_id"], rec["study_id"], rec["prolific_pid"], rec["requested_by"]) == (
        pids["A"],
        "fixture",
        PROLIFIC["A"],
        "cli",
    )
    at = datetime.fromisoformat(rec["withdrawn_at"]).replace(tzinfo=UTC)
    assert t0 - 1 <= at.timestamp() <= time.time() + 1
    assert set(rec.keys()) == {
        "id",
        "participant_id",
        "study_id",
        "prolific_pid",
        "requested_by",
        "withdrawn_at",
        "completion_code",  # A had finished: kept for payment only (issue 37)
        "completed_at",
    }
    assert rec["completion_code"] in {r[-1] for r in before["participants"]}
    # Everyone else's rows are exactly as before.
    for table in ("participants", "responses", "events"):
        assert [r for r in before[table] if not any(g in c for g in gone for c in r)] == after[
            table
        ]
    # Export and analysis count the two others only.
    code, _, err = cli_run(
        "export", "--db", url, "-o", Path(url[10:]).with_name("r.csv"), "--identifiers"
    )
    assert code == 0 and "exported 4 responses of 2 participants" in err
    df = load_responses(url)
    assert set(df["participant_id"]) == {pids["B"], pids["C"]} and len(df) == 4


def test_withdraw_by_prolific_id_and_unknown_ids(url):
    """--prolific-pid withdraws that person; an unknown or already withdrawn id is one
    `error:` line, exit 2, and changes nothing; so is giving both ids or none."""
    with Store(url) as s:
        pids = populate(s)
    code, _, err = cli_run("withdraw", "--db", url, "--prolific-pid", PROLIFIC["B"])
    assert code == 0, err
    with Store(url) as s:
        assert s.get_participant(pids["B"]) is None
        assert {p["participant_id"] for p in s.participants()} == {pids["A"], pids["C"]}
    state = dump(url)
    cases = [
        (["--pid", "Zz" * 11], "unknown participant id"),
        (["--prolific-pid", "nobody42"], "unknown Prolific id"),
        (["--pid", pids["B"]], "already withdrawn"),
        (["--prolific-pid", PROLIFIC["B"]], "already withdrawn"),
        (["--pid", pids["A"], "--prolific-pid", PROLIFIC["A"]], "exactly one"),
        ([], "exactly one"),
    ]
    for args, says in cases:
        code, out, err = cli_run("withdraw", "--db", url, *args)
        assert code == 2, (args, err)
        assert err.startswith("error:") and len(err.strip().splitlines()) == 1, err
        assert says in err, (args, err)
        assert "Traceback" not in out + err
    assert dump(url) == state


def test_consent_names_the_contact():
    """The default consent text says how to withdraw and whom to write to."""
    doc = fixture_study_doc()
    with_contact = study_from_dict(
        {**doc, "study": {**doc["study"], "contact": "ethics@uni.example"}}
    )
    text = consent_text(with_contact, 5)
    assert "withdraw" in text and "ethics@uni.example" in text and "{contact}" not in text
    assert DEFAULT_CONTACT in consent_text(study_from_dict(doc), 5)


# ----------------------------------------------------------------------------- pseudonyms
def expected_pseudonym(url: str, study: str, column: str, value: str) -> str:
    """The documented formula, with the secret read from the database directly."""
    con = sqlite3.connect(url.removeprefix("sqlite:///"))
    (secret,) = con.execute(
        "SELECT secret FROM study_secrets WHERE study_id = ?", (study,)
    ).fetchone()
    mac = hmac.new(secret.encode(), f"{column}\x00{value}".encode(), hashlib.sha256)
    return "p-" + mac.hexdigest()[:16]


@pytest.fixture(scope="module")
def stimuli(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("stimuli") / "fixture"
    write_fixture_stimuli(d, fixture_study_doc(scene_ids=("walk",)))
    return d


def test_no_export_holds_a_raw_identifier(url, tmp_path, stimuli):
    """Every file of every export is free of the Prolific, session and participant ids
    made here; the pseudonyms follow the formula and are the same in a second export;
    --identifiers writes the raw ids and warns."""
    with Store(url) as s:
        pids = populate(s)
    raw = [*PROLIFIC.values(), *SESSIONS.values(), *pids.values()]
    out = [tmp_path / "one", tmp_path / "two", tmp_path / "raw"]
    for folder, extra in zip(out, ([], [], ["--identifiers"])):
        folder.mkdir()
        code, _, err = cli_run(
            "export",
            "--db",
            url,
            "-o",
            folder / "r.csv",
            "--participants",
            folder / "p.jsonl",
            "--events",
            folder / "e.jsonl",
            "--psych-ds",
            folder / "ds",
            "--stimuli",
            stimuli,
            *extra,
        )
        assert code == 0, err
        assert ("--identifiers" in err and "personal data" in err) == bool(extra)
    for folder in out[:2]:
        files = [f for f in folder.rglob("*") if f.is_file()]
        assert len(files) == 3 + 5  # r, p, e; description, 3 data files, manifest
        for f in files:
            data = f.read_bytes()
            assert not [r for r in raw if r.encode() in data], f
    for name in ("r.csv", "p.jsonl", "e.jsonl"):  # stable across exports
        assert (out[0] / name).read_bytes() == (out[1] / name).read_bytes()
    rows = read_export(out[0] / "r.csv")
    assert {r["participant_id"] for r in rows} == {
        expected_pseudonym(url, "fixture", "participant_id", p) for p in pids.values()
    }
    people = [json.loads(line) for line in (out[0] / "p.jsonl").read_text().splitlines()]
    assert {p["prolific_session_id"] for p in people} == {
        expected_pseudonym(url, "fixture", "prolific_session_id", v) for v in SESSIONS.values()
    } | {None}
    assert {r["prolific_pid"] for r in rows} == {
        expected_pseudonym(url, "fixture", "prolific_pid", v) for v in PROLIFIC.values()
    } | {None}
    raw_files = b"".join(f.read_bytes() for f in out[2].rglob("*") if f.is_file())
    assert all(r.encode() in raw_files for r in raw)


# ----------------------------------------------------------------------------- Psych-DS
def layout(folder: Path) -> dict:
    """The summary of a dataset folder that psychds_layout.schema.json describes."""
    files = []
    for f in sorted((folder / "data").rglob("*")):
        if f.is_file():
            table = list(csv.reader(io.StringIO(f.read_text(encoding="utf-8"), newline="")))
            files.append(
                {
                    "path": f.relative_to(folder).as_posix(),
                    "header": table[0],
                    "row_cells": [len(r) for r in table[1:]],
                }
            )
    return {
        "top_level": sorted(p.name for p in folder.iterdir()),
        "description": json.loads((folder / "dataset_description.json").read_text()),
        "data_files": files,
    }


def check_psych_ds(folder: Path) -> None:
    schema = json.loads(schema_path("psychds_layout").read_text())
    doc = layout(folder)
    jsonschema.validate(
        doc,
        schema,
        cls=jsonschema.Draft202012Validator,
        format_checker=jsonschema.Draft202012Validator.FORMAT_CHECKER,
    )
    described = {
        v if isinstance(v, str) else v["name"] for v in doc["description"]["variableMeasured"]
    }
    for f in doc["data_files"]:
        assert set(f["row_cells"]) <= {len(f["header"])}, f["path"]  # HeaderRowMismatch
        assert set(f["header"]) <= described, (f["path"], set(f["header"]) - described)


def test_psych_ds_dataset_follows_the_rules(url, tmp_path, stimuli):
    """`export --psych-ds` writes the standard layout; it passes the layout schema and the
    column rule; its data read back to the store's rows; the manifest is in materials/."""
    with Store(url) as s:
        populate(s)
        populate(s, study_id="second-study.v2")  # a study id with '-' and '.'
        n_rows = len(s.export_rows())
    ds = tmp_path / "ds"
    code, _, err = cli_run("export", "--db", url, "--psych-ds", ds, "--stimuli", stimuli)
    assert code == 0, err
    check_psych_ds(ds)
    assert sorted(p.relative_to(ds).as_posix() for p in ds.rglob("*") if p.is_file()) == [
        "data/study-fixture_data.csv",
        "data/study-fixture_description-events_data.csv",
        "data/study-fixture_description-participants_data.csv",
        "data/study-secondstudyv2_data.csv",
        "data/study-secondstudyv2_description-events_data.csv",
        "data/study-secondstudyv2_description-participants_data.csv",
        "dataset_description.json",
        "materials/manifest.json",
    ]
    desc = json.loads((ds / "dataset_description.json").read_text())
    assert desc["name"] == "Fixture study"  # the manifest's study title
    # variableMeasured is the response schema's columns first, each with its description.
    response = json.loads(schema_path("response").read_text())["properties"]
    vm = desc["variableMeasured"][: len(response)]
    assert [(v["name"], v["description"]) for v in vm] == [
        (k, spec["description"]) for k, spec in response.items()
    ]
    assert (ds / "materials/manifest.json").read_bytes() == (stimuli / "manifest.json").read_bytes()
    rows = read_export(ds / "data/study-fixture_data.csv") + read_export(
        ds / "data/study-secondstudyv2_data.csv"
    )
    assert len(rows) == n_rows == 12
    # An existing, non-empty folder is refused with one line.
    code, _, err = cli_run("export", "--db", url, "--psych-ds", ds)
    assert code == 2 and "not an empty folder" in err and len(err.strip().splitlines()) == 1


def test_psych_ds_checks_are_not_vacuous(url, tmp_path):
    """The layout check refuses what Psych-DS refuses: bad file names, a missing
    required field, a column not in variableMeasured, a short row."""
    with Store(url) as s:
        populate(s)
    ds = tmp_path / "ds"
    assert cli_run("export", "--db", url, "--psych-ds", ds)[0] == 0
    check_psych_ds(ds)
    data = ds / "data" / "study-fixture_data.csv"
    for bad in (
        "study_fixture_data.csv",
        "Study-fixture_data.csv",
        "study-fix-ture_data.csv",
        "study-fixture.csv",
        "mood-happy_data.csv",
    ):
        renamed = data.rename(data.with_name(bad))
        with pytest.raises(jsonschema.ValidationError):
            check_psych_ds(ds)
        data = renamed.rename(data)
    desc_path = ds / "dataset_description.json"
    good = desc_path.read_text()
    for key in ("name", "schemaVersion", "variableMeasured", "@type"):
        doc = json.loads(good)
        del doc[key]
        desc_path.write_text(json.dumps(doc))
        with pytest.raises(jsonschema.ValidationError):
            check_psych_ds(ds)
    doc = json.loads(good)
    doc["variableMeasured"] = [v for v in doc["variableMeasured"] if v["name"] != "scene"]
    desc_path.write_text(json.dumps(doc))
    with pytest.raises(AssertionError):
        check_psych_ds(ds)
    desc_path.write_text(good)
    data.write_text(data.read_text() + "short,row\n")
    with pytest.raises(AssertionError):
        check_psych_ds(ds)


# ----------------------------------------------------------------------------- backups
N_WRITERS = 20
BATCH = 2  # responses per transaction: a torn copy would hold a partial batch


def backup_under_load(url, out: Path, method: str):
    """20 participants write batches of 2 answers in threads; back up in the middle.

    Returns the batches written as ``{pid: [(batch, t_start, t_end), ...]}`` and the
    backup's ``(t0, t1)`` (monotonic clock).
    """
    store = Store(url)
    study_secret(store, "load")  # the secret must travel with the backup
    log: dict[str, list] = {}
    lock = threading.Lock()
    stop = threading.Event()
    created = threading.Barrier(N_WRITERS)
    errors = []

    def writer(k: int):
        try:
            pid = store.create_participant(
                "load",
                SHA,
                app_version="0.1.0",
                seed=k,
                prolific={"PROLIFIC_PID": f"LOADpid{k:04d}"},
            )
            with lock:
                log[pid] = []
            created.wait(timeout=60)  # all 20 write at once from here on
            b = 0
            while not stop.is_set():
                rows = [pose(BATCH * b + i, frame=k) for i in range(BATCH)]
                t_start = time.monotonic()
                assert store.record_responses(pid, rows) == BATCH
                t_end = time.monotonic()
                with lock:
                    log[pid].append((b, t_start, t_end))
                b += 1
        except Exception as err:  # noqa: BLE001 - reported by the test thread
            errors.append(err)

    threads = [threading.Thread(target=writer, args=(k,)) for k in range(N_WRITERS)]
    for t in threads:
        t.start()

    def written() -> int:
        """Batches committed so far (0 until every participant exists). SQLite's busy
        wait is not fair, so some writers may lag: count all batches, not each's."""
        with lock:
            return sum(len(v) for v in log.values()) if len(log) == N_WRITERS else 0

    deadline = time.monotonic() + 60
    while written() < 2 * N_WRITERS and time.monotonic() < deadline and not errors:
        time.sleep(0.005)
    t0 = time.monotonic()
    result = backup(url, out, method=method)
    t1 = time.monotonic()
    at_t1 = written()
    while written() < at_t1 + N_WRITERS and time.monotonic() < deadline and not errors:
        time.sleep(0.005)
    stop.set()
    for t in threads:
        t.join()
    store.close()
    assert not errors, errors
    return result, log, (t0, t1)


def check_snapshot(restored_url, log, t0, t1) -> int:
    """The restored rows are the database at one moment between t0 and t1: complete
    batches only, a prefix of each writer's batches, everything finished before t0,
    nothing started after t1, and one cut in time separating kept from missing."""
    with Store(restored_url, create=False) as s:
        rows = s.export_rows(include_simulated=True)
        people = {p["participant_id"] for p in s.participants()}
    assert people == set(log)  # all were registered before the backup began
    kept: dict[str, dict[int, int]] = {pid: {} for pid in people}
    for r in rows:
        per = kept[r["participant_id"]]
        per[r["trial_index"] // BATCH] = per.get(r["trial_index"] // BATCH, 0) + 1
    latest_kept_start, earliest_missing_end, n_missing = 0.0, float("inf"), 0
    for pid, batches in log.items():
        have = kept[pid]
        assert set(have.values()) <= {BATCH}, f"torn batch of {pid}: {have}"
        assert sorted(have) == list(range(len(have))), f"not a prefix: {sorted(have)}"
        for b, start, end in batches:
            if b in have:
                assert start < t1
                latest_kept_start = max(latest_kept_start, start)
            else:
                assert end > t0, "a batch committed before the backup began is missing"
                earliest_missing_end = min(earliest_missing_end, end)
                n_missing += 1
    assert latest_kept_start < earliest_missing_end
    assert n_missing > 0, "the writers went on after the backup"
    return len(rows)


def restore_target(kind: str, request, tmp_path) -> str:
    if kind == "sqlite":
        return f"sqlite:///{tmp_path / 'restored.db'}"
    return request.getfixturevalue("pg_server").create_database()


CASES = [
    ("sqlite", "native"),
    ("sqlite", "logical"),
    pytest.param("postgresql", "native", marks=pytest.mark.postgres),
    pytest.param("postgresql", "logical", marks=pytest.mark.postgres),
]


@pytest.mark.parametrize(("backend", "method"), CASES)
def test_backup_during_concurrent_writes_restores_a_consistent_copy(
    backend, method, request, tmp_path
):
    """A backup taken while 20 participants write restores, into a fresh database, to
    exactly the rows committed before one moment of the backup: no torn state; the
    restored database takes new answers and exports the same pseudonyms."""
    if backend == "postgresql" and method == "native" and find_pg_tool("pg_dump") is None:
        pytest.skip("pg_dump is not installed")
    source = (
        f"sqlite:///{tmp_path / 'live.db'}"
        if backend == "sqlite"
        else request.getfixturevalue("pg_url")
    )
    out = tmp_path / "backup.bin"
    result, log, (t0, t1) = backup_under_load(source, out, method)
    expected_method = {
        ("sqlite", "native"): "sqlite-backup",
        ("postgresql", "native"): "pg_dump",
    }.get((backend, method), "logical")
    assert result.method == expected_method
    # pg_dump archives go back into PostgreSQL; SQLite backups into SQLite.
    target = restore_target(backend, request, tmp_path)
    restored = restore(out, target, withdrawals_from=source)
    n = check_snapshot(target, log, t0, t1)
    with Store(source, create=False) as live, Store(target, create=False) as back:
        assert n < len(live.export_rows())
        # Every restored row is the live row, unchanged (timestamps included).
        live_rows = {(r["participant_id"], r["trial_index"]): r for r in live.export_rows()}
        assert all(
            live_rows[(r["participant_id"], r["trial_index"])] == r for r in back.export_rows()
        )
        people = [{"participant_id": p, "study_id": "load"} for p in log]
        assert Pseudonymiser(back).records(people) == Pseudonymiser(live).records(people)
        pid = next(iter(log))
        assert back.record_response(pid, view(10_000))  # ids continue past the copy
    if restored.rows:
        assert restored.rows["responses"] == n


def test_restore_refuses_what_it_cannot_restore(url, tmp_path):
    """Restore into a database holding data, from a file that is no backup, or a SQLite
    backup with no study tables: one line, exit 2, the target unchanged."""
    with Store(url) as s:
        populate(s)
    good = tmp_path / "b.db"
    assert cli_run("backup", "--db", url, "-o", good)[0] == 0
    code, _, err = cli_run("backup", "--db", url, "-o", good)
    assert code == 2 and "already exists" in err
    state = dump(url)
    junk = tmp_path / "junk.db"
    junk.write_text("not a database")
    empty = tmp_path / "empty.db"
    sqlite3.connect(empty).execute("CREATE TABLE other (x)").connection.commit()
    for args, says in (
        ([good, "--db", url], "already holds data"),
        ([junk, "--db", f"sqlite:///{tmp_path / 'n1.db'}"], "not a backup"),
        ([empty, "--db", f"sqlite:///{tmp_path / 'n2.db'}"], "not a study backup"),
        ([tmp_path / "missing.db", "--db", url], "no such backup file"),
    ):
        code, _, err = cli_run("restore", *args)
        assert code == 2 and says in err and len(err.strip().splitlines()) == 1, err
    assert dump(url) == state
    with pytest.raises(StoreError, match="restores only into PostgreSQL"):
        pg = tmp_path / "fake.dump"
        pg.write_bytes(b"PGDMP\x01\x0e")
        restore(pg, f"sqlite:///{tmp_path / 'n3.db'}")
