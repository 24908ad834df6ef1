"""Exports of the study store and `snapshot export`, on SQLite and real PostgreSQL: the
rows as sent, CSV and JSON lines round trips, the schemas of every export file, refused
rows named by row and field, and one-line errors for broken URLs and outputs. The store
itself is tested in ``test_store.py`` (whose fixtures and row builders this file uses).
"""

from __future__ import annotations

import json
import socket
import subprocess
import sys

import pytest
import test_store
from click.testing import CliRunner
from pg import PG_PASSWORD
from test_store import SHA, attention_row, new_participant, pose_row, view_row

from snapcore.cli.main import cli
from snapcore.errors import SchemaError
from snapcore.schema import validate
from study_app.data.export import export_columns, read_export, write_export
from study_app.data.store import Store

#: A SQLite file, and a store on SQLite and on PostgreSQL (the store tests' fixtures).
sqlite_url = test_store.sqlite_url
store_url = test_store.store_url
store = test_store.store


# ----------------------------------------------------------------------------- export
def populate(store) -> tuple[dict, str]:
    """Two real participants and one simulated; returns {(pid, trial): sent row}, sim id."""
    sent = {}
    a = new_participant(store, prolific={"PROLIFIC_PID": "p-a"})
    store.set_background(a, {"age_band": "25-34", "gender": "man", "experience": "none"})
    b = new_participant(store, seed=11)
    store.set_background(
        b, {"age_band": "18-24", "gender": "woman", "experience": ["animation", "art"]}
    )
    sim = new_participant(store, simulated=True)
    for pid, rows in (
        (a, [pose_row(0, frame=12), view_row(1, position=2), attention_row(2)]),
        (
            b,
            [
                view_row(0, position=0, order=("ours", "motion_area", "viewpoint_entropy")),
                pose_row(1, frame=0),
                attention_row(2, answer="red", correct=False),
            ],
        ),
        (sim, [pose_row(0)]),
    ):
        for row in rows:
            assert store.record_response(pid, row)
            sent[(pid, row["trial_index"])] = row
    return sent, sim


def test_export_rows_match_what_was_sent(store):
    """Each export row = the sent trial fields + the participant's fields; schema-valid."""
    sent, sim = populate(store)
    rows = store.export_rows(validate=True)
    assert len(rows) == 6 and all(list(r) == export_columns() for r in rows)
    assert all(r["participant_id"] != sim for r in rows)
    for r in rows:
        validate(r, "response")
        src = sent[(r["participant_id"], r["trial_index"])]
        for key in export_columns():
            if key in src:
                assert r[key] == src[key], key
            elif key in ("chosen_frame", "chosen_method", "shown_order", "correct", "fps"):
                assert r[key] is None, key
        assert r["manifest_sha256"] == SHA and r["app_version"] == "0.1.0"
        assert r["simulated"] is False and r["study_id"] == "demo"
    by_pid = {r["participant_id"]: r for r in rows}
    assert {r["prolific_pid"] for r in by_pid.values()} == {"p-a", None}
    assert sorted(r["experience"] for r in by_pid.values()) == ["animation; art", "none"]
    assert len(store.export_rows(include_simulated=True)) == 7


@pytest.mark.parametrize("suffix", [".csv", ".jsonl"])
def test_export_file_round_trip(store, tmp_path, suffix):
    """export → read back → equals the stored rows (CSV: shown_order parsed back from JSON)."""
    populate(store)
    rows = store.export_rows(include_simulated=True)
    out = tmp_path / f"responses{suffix}"
    assert write_export(rows, out) == 7
    back = read_export(out)
    assert back == rows
    if suffix == ".csv":
        header = out.read_text().splitlines()[0].split(",")
        assert header == export_columns()
        # shown_order is a JSON array string in its cell (csv-quoted)
        assert '"[""motion_area"", ""ours"", ""viewpoint_entropy""]"' in out.read_text()


def test_export_refuses_invalid_rows(tmp_path):
    """A row breaking the schema: the error names file, row number and field; no file."""
    good = {c: None for c in export_columns()} | {
        "participant_id": "p" * 22,
        "study_id": "demo",
        "trial_index": 0,
        "task": "pose",
        "scene": "s",
        "stimulus_id": "s-pose",
        "chosen_frame": 3,
        "response_time_s": 1.0,
        "created_at": "2025-01-01T00:00:00+00:00",
        "app_version": "1",
        "manifest_sha256": SHA,
        "simulated": False,
    }
    rows = [good, good | {"trial_index": 1, "chosen_frame": 2.5}]
    with pytest.raises(
        SchemaError,
        match=r"x.csv: row 2 \(participant 'p+', trial 1\): "
        r"chosen_frame: 2.5 is not of type",
    ):
        write_export(rows, tmp_path / "x.csv")
    assert not (tmp_path / "x.csv").exists()


# ----------------------------------------------------------------------------- CLI
def run_cli(*args):
    result = CliRunner().invoke(cli, list(args))
    return result.exit_code, result.stdout, result.stderr


def test_cli_export(sqlite_url, tmp_path):
    """`snapshot export` writes validated CSV / JSON lines and the participants table."""
    with Store(sqlite_url) as s:
        sent, sim = populate(s)
    out, parts = tmp_path / "out" / "responses.csv", tmp_path / "participants.csv"
    out.parent.mkdir()
    # --identifiers: the raw ids, to match the rows sent (pseudonyms: tests/test_open_data.py)
    code, _, err = run_cli(
        "export", "--db", sqlite_url, "-o", str(out), "--participants", str(parts), "--identifiers"
    )
    assert code == 0, err
    rows = read_export(out)
    assert {(r["participant_id"], r["trial_index"]) for r in rows} == {
        k for k in sent if k[0] != sim
    }
    n_sim = sum(1 for k in sent if k[0] == sim)
    assert f"note: {n_sim} responses of simulated participants were left out" in err
    import csv

    table = list(csv.DictReader(parts.open()))
    assert len(table) == 2 and {t["n_responses"] for t in table} == {"3"}
    code, _, err = run_cli(
        "export",
        "--db",
        sqlite_url,
        "-o",
        str(tmp_path / "all.json"),
        "--include-simulated",
        "--events",
        str(tmp_path / "ev.jsonl"),
    )
    assert code == 0, err
    assert "left out" not in err
    lines = (tmp_path / "all.json").read_text().splitlines()
    assert len(lines) == 7 and all(json.loads(x)["trial_index"] >= 0 for x in lines)


def test_participant_and_event_exports_follow_their_schemas(store, tmp_path):
    """Every line of the participants and events exports validates against
    participant.schema.json / event.schema.json (checked here with jsonschema directly);
    a record that does not is refused, naming the row and field, and no file is left."""
    import jsonschema

    from data_schema import schema_path
    from study_app.data.export import write_events, write_participants

    pid = new_participant(store)
    store.set_background(pid, {"age_band": "18-24", "gender": "x", "experience": ["a", "b"]})
    store.record_events(pid, 0, [("shown", {}), ("step", {"frame": 3, "by": 1, "t": 0.5})])
    store.record_event(pid, None, "page", {})
    parts, evs = tmp_path / "participants.jsonl", tmp_path / "events.jsonl"
    assert write_participants(store.participants(), parts) == 1
    assert write_events(store.events(), evs) == 3
    for path, name in ((parts, "participant"), (evs, "event")):
        schema = json.loads(schema_path(name).read_text())
        for line in path.read_text().splitlines():
            jsonschema.validate(json.loads(line), schema)
    row = json.loads(parts.read_text())
    assert row["experience"] == "a; b" and row["background"]["experience"] == ["a", "b"]
    bad = [{**store.events()[0], "trial_index": -2}]
    with pytest.raises(SchemaError, match=r"row 1 .*trial_index"):
        write_events(bad, tmp_path / "bad.jsonl")
    assert not (tmp_path / "bad.jsonl").exists()


def test_cli_unwritable_output(sqlite_url, tmp_path):
    with Store(sqlite_url) as s:
        populate(s)
    (tmp_path / "file").write_text("x")
    code, out, err = run_cli("export", "--db", sqlite_url, "-o", str(tmp_path / "file" / "r.csv"))
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: cannot write")
    assert "Traceback" not in out + err


def test_cli_bad_row_names_row_and_field(sqlite_url, tmp_path):
    """A row tampered in the database (bypassing the store) stops the export, naming it."""
    with Store(sqlite_url) as s:
        populate(s)
        with s.engine.begin() as conn:
            conn.exec_driver_sql(
                "UPDATE responses SET chosen_method = 'forged' "
                "WHERE task = 'view' AND chosen_position = 2"
            )
    out = tmp_path / "r.csv"
    # With --identifiers the rows are in arrival order: the forged one is the second.
    code, _, err = run_cli("export", "--db", sqlite_url, "-o", str(out), "--identifiers")
    assert code == 2 and err.count("\n") == 2  # the identifiers warning, the error
    assert "row 2" in err and "chosen_method" in err and "'forged'" in err
    assert f"{out}: row" in err  # the file asked for, not a temp name
    assert not out.exists()
    # A shared export (rows ordered by pseudonym) names the row by its pseudonym.
    code, _, err = run_cli("export", "--db", sqlite_url, "-o", str(out))
    assert code == 2 and err.count("\n") == 1 and f"{out}: row" in err
    assert "(participant 'p-" in err and "chosen_method" in err and "'forged'" in err
    assert not out.exists()


@pytest.mark.parametrize(
    "url, expect",
    [
        ("bogus://u:hunter2@h/db", "unknown database type"),
        ("sqlite:///{tmp}/missing/study.db", "no such file"),
        ("postgresql://u:hunter2@127.0.0.1:{port}/db", "Connection refused"),
    ],
)
def test_cli_broken_url(url, expect, tmp_path):
    """A broken --db URL: one line, password masked, exit code 2, no traceback."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        port = sock.getsockname()[1]
    url = url.format(tmp=tmp_path, port=port)
    code, out, err = run_cli("export", "--db", url, "-o", str(tmp_path / "r.csv"))
    assert code == 2 and err.count("\n") == 1 and err.startswith("error: ")
    assert expect in err and "hunter2" not in err and "Traceback" not in out + err


def test_cli_broken_url_real_process(tmp_path):
    """The same through the real console entry point (no test runner in between)."""
    proc = subprocess.run(
        [
            sys.executable,
            "-m",
            "snapcore.cli.main",
            "export",
            "--db",
            "postgresql://me:topsecret@127.0.0.1:1/x",
            "-o",
            str(tmp_path / "r.csv"),
        ],
        capture_output=True,
        text=True,
    )
    assert proc.returncode == 2
    assert proc.stderr.startswith("error: cannot open database postgresql+psycopg://me:***@")
    assert proc.stderr.count("\n") == 1 and "topsecret" not in proc.stderr


@pytest.mark.postgres
def test_cli_export_postgres(request, tmp_path):
    """`snapshot export` on PostgreSQL (plain postgresql:// URL); wrong password → one line."""
    url = request.getfixturevalue("pg_url")
    with Store(url) as s:
        populate(s)
    plain = url.replace("postgresql+psycopg://", "postgresql://")
    code, _, err = run_cli("export", "--db", plain, "-o", str(tmp_path / "r.jsonl"))
    assert code == 0, err
    assert len(read_export(tmp_path / "r.jsonl")) == 6
    bad = url.replace(f":{PG_PASSWORD}@", ":not-it@")
    code, _, err = run_cli("export", "--db", bad, "-o", str(tmp_path / "r2.csv"))
    assert code == 2 and err.count("\n") == 1 and "password authentication failed" in err
    assert "not-it" not in err
