"""The researcher's data: what an ethics board asks of exports, withdrawals and backups.

Issue 27, items 2–5 and the data side of 8: study ids that differ only in punctuation,
the pseudonym secret made with the study's first participant, open exports that cannot
be joined back to an identifiers file (no seed, no exact times), withdrawal by
pseudonym, restores that keep withdrawals, ``snapshot backup --verify``. Checks read
the files and the database directly (csv, sqlite3), not through the code under test.
"""

from __future__ import annotations

import csv
import sqlite3
from pathlib import Path

import pytest
from click.testing import CliRunner
from test_open_data import PROLIFIC, populate

from snapcore.cli.main import cli
from study_app.data.store import Store


def run(*args):
    result = CliRunner().invoke(cli, [str(a) for a in args])
    if result.exit_code not in (0, 2):
        raise result.exception
    return result.exit_code, result.stderr


def read_csv(path) -> list[dict]:
    with open(path, newline="", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def secrets_of(path) -> list[tuple]:
    with sqlite3.connect(path) as con:
        return con.execute("SELECT * FROM study_secrets ORDER BY study_id").fetchall()


@pytest.fixture
def db(tmp_path) -> Path:
    path = tmp_path / "study.db"
    with Store(f"sqlite:///{path}") as store:
        populate(store)
    return path


# ----------------------------------------------------------------------------- item 2
def test_psych_ds_keeps_studies_whose_ids_differ_only_in_punctuation(tmp_path):
    """pilot-1 and pilot_1 both reduce to 'pilot1': each keeps its own data file."""
    path = tmp_path / "two.db"
    with Store(f"sqlite:///{path}") as store:
        populate(store, "pilot-1")
        populate(store, "pilot_1")
        n = store.progress()["responses"]
    code, err = run("export", "--db", path, "--psych-ds", tmp_path / "ds")
    assert code == 0, err
    data = sorted((tmp_path / "ds" / "data").glob("*_data.csv"))
    responses = [p for p in data if "_description-" not in p.name]
    assert len(responses) == 2, [p.name for p in data]
    by_study = {read_csv(p)[0]["study_id"]: len(read_csv(p)) for p in responses}
    assert by_study == {"pilot-1": n // 2, "pilot_1": n // 2}


def test_psych_ds_of_an_empty_database_is_an_error(tmp_path):
    path = tmp_path / "empty.db"
    Store(f"sqlite:///{path}").close()
    code, err = run("export", "--db", path, "--psych-ds", tmp_path / "ds")
    assert code == 2
    assert "no responses" in err and "Traceback" not in err


# ----------------------------------------------------------------------------- item 3
def test_secret_exists_from_the_first_participant_and_exports_never_write(db, tmp_path):
    """A backup taken before any export pseudonymises like the live database, and
    exporting from the backup writes no secret into it."""
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT count(*) FROM study_secrets").fetchone()[0] == 1
    copy = tmp_path / "before-export.db"
    assert run("backup", "--db", db, "-o", copy)[0] == 0
    before = secrets_of(copy)
    assert run("export", "--db", db, "-o", tmp_path / "live.csv")[0] == 0
    assert run("export", "--db", copy, "-o", tmp_path / "copy.csv")[0] == 0
    live = {r["participant_id"] for r in read_csv(tmp_path / "live.csv")}
    assert live == {r["participant_id"] for r in read_csv(tmp_path / "copy.csv")}
    assert secrets_of(copy) == before == secrets_of(db)


# ----------------------------------------------------------------------------- item 4
def test_open_exports_cannot_be_joined_to_the_identifiers_file(db, tmp_path):
    """Neither the participants file nor the Psych-DS folder has the seed or an exact
    time: a join on any column the identifiers file shares with them, other than the
    study-wide ones, finds nobody; with --identifiers the exact values are there."""
    ids, open_ = tmp_path / "ids.csv", tmp_path / "open.csv"
    assert (
        run("export", "--db", db, "-o", tmp_path / "r.csv", "--participants", ids, "--identifiers")[
            0
        ]
        == 0
    )
    assert run("export", "--db", db, "-o", tmp_path / "r2.csv", "--participants", open_)[0] == 0
    assert run("export", "--db", db, "--psych-ds", tmp_path / "ds")[0] == 0
    secret_rows = read_csv(ids)
    assert all(r["seed"] != "" and "T" in r["created_at"] for r in secret_rows)
    ds = next((tmp_path / "ds" / "data").glob("*_description-participants_data.csv"))
    for shared in (read_csv(open_), read_csv(ds)):
        assert "seed" not in shared[0]
        for column in ("created_at", "completed_at"):
            assert all(len(r[column]) == 7 for r in shared), column  # YYYY-MM
            joined = {r[column] for r in shared} & {r[column] for r in secret_rows}
            assert not joined, column
    responses = read_csv(tmp_path / "r2.csv")
    assert all(len(r["created_at"]) == 7 for r in responses)


# ----------------------------------------------------------------------------- item 5
def test_withdraw_by_the_pseudonym_a_published_dataset_shows(db, tmp_path):
    assert (
        run(
            "export", "--db", db, "-o", tmp_path / "open.csv", "--participants", tmp_path / "p.csv"
        )[0]
        == 0
    )
    person = next(r for r in read_csv(tmp_path / "p.csv") if r["prolific_pid"])
    code, err = run("withdraw", "--db", db, "--pseudonym", person["participant_id"])
    assert code == 0, err
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT count(*) FROM participants").fetchone()[0] == 2
        assert con.execute("SELECT count(*) FROM withdrawals").fetchone()[0] == 1
    # Their Prolific id's pseudonym names the same person: now already gone.
    code, err = run("withdraw", "--db", db, "--pseudonym", person["prolific_pid"])
    assert code == 2 and "unknown pseudonym" in err
    code, err = run("withdraw", "--db", db, "--pseudonym", "p-zz")
    assert code == 2 and "not a pseudonym" in err


def test_restore_reapplies_withdrawals_made_after_the_backup(db, tmp_path):
    copy = tmp_path / "backup.db"
    assert run("backup", "--db", db, "-o", copy)[0] == 0
    assert run("withdraw", "--db", db, "--prolific-pid", PROLIFIC["A"])[0] == 0
    plain = tmp_path / "plain.db"
    code, err = run("restore", copy, "--db", plain)
    # No withdrawal log of the new target and no source named: refused, not silent.
    assert code == 2 and "--withdrawals-from" in err and not plain.exists()
    kept = tmp_path / "kept.db"
    code, err = run("restore", copy, "--db", kept, "--withdrawals-from", db)
    assert code == 0, err
    with sqlite3.connect(kept) as con:
        pids = {r[0] for r in con.execute("SELECT prolific_pid FROM participants")}
        assert PROLIFIC["A"] not in pids and PROLIFIC["B"] in pids
        assert con.execute("SELECT count(*) FROM withdrawals").fetchone()[0] == 1
        gone = con.execute("SELECT participant_id FROM withdrawals").fetchone()[0]
        for table in ("responses", "events"):
            n = con.execute(
                f"SELECT count(*) FROM {table} WHERE participant_id = ?", (gone,)
            ).fetchone()[0]
            assert n == 0, table


# ----------------------------------------------------------------------------- item 8
def test_backup_verify_and_a_corrupt_backup(db, tmp_path):
    good = tmp_path / "good.db"
    assert run("backup", "--db", db, "-o", good)[0] == 0
    code, err = run("backup", "--verify", good)
    assert code == 0 and "sound" in err
    bad = tmp_path / "corrupt.db"
    data = bytearray(good.read_bytes())
    data[len(data) // 2 :] = b"\x5a" * (len(data) - len(data) // 2)  # half the pages overwritten
    bad.write_bytes(bytes(data))
    code, err = run("backup", "--verify", bad)
    assert code == 2 and str(bad) in err and "Traceback" not in err
    target = tmp_path / "target.db"
    code, err = run("restore", bad, "--db", target)
    assert code == 2 and str(bad) in err and "target" not in err
    assert not target.exists()  # no empty database left behind


# ----------------------------------------------------------------------------- item 8: analyze
def test_analyze_refuses_an_export_without_chosen_method(db, tmp_path):
    full = tmp_path / "full.csv"
    assert run("export", "--db", db, "-o", full)[0] == 0
    rows = read_csv(full)
    cut = tmp_path / "cut.csv"
    with open(cut, "w", newline="", encoding="utf-8") as f:
        w = csv.DictWriter(f, [c for c in rows[0] if c != "chosen_method"], extrasaction="ignore")
        w.writeheader()
        w.writerows(rows)
    code, err = run("analyze", "--input", cut, "-o", tmp_path / "out", "--include-incomplete")
    assert code == 2 and "chosen_method" in err and str(cut) in err
    assert not (tmp_path / "out").exists()


def test_analyze_never_creates_a_database(tmp_path):
    missing = tmp_path / "missing" / "dir" / "x.db"
    code, err = run("analyze", "--db", f"sqlite:///{missing}", "-o", tmp_path / "out")
    assert code == 2 and "no such file" in err
    assert not missing.parent.exists() and not (tmp_path / "out").exists()


def test_analyze_takes_a_bare_db_path_like_export(db, tmp_path):
    code, err = run(
        "analyze", "--db", db, "-o", tmp_path / "out", "--include-incomplete", "--boot", "0", "-q"
    )
    assert code == 0, err
    assert (tmp_path / "out" / "report.html").is_file()


@pytest.mark.postgres
def test_analyze_on_an_empty_postgresql_database_creates_nothing(pg_url, tmp_path):
    import sqlalchemy as sa

    from study_app.data.database import normalize_url

    code, err = run("analyze", "--db", pg_url, "-o", tmp_path / "out")
    assert code == 2 and "no study tables" in err
    engine = sa.create_engine(normalize_url(pg_url))
    with engine.connect() as conn:
        assert sa.inspect(conn).get_table_names() == []
    engine.dispose()


def test_psych_ds_metadata_comes_from_the_study_config(tmp_path):
    """Licence, creators and citation from the config; the description is the dataset's,
    not the text participants read."""
    import json

    from app_helpers import fixture_study_doc, write_fixture_stimuli

    from study_app.design.stimuli import load_stimuli

    doc = fixture_study_doc()
    doc["study"].update(
        license="CC-BY-4.0",
        creators=["A. Researcher", "B. Researcher"],
        citation="Researcher et al. (2026). Action Snapshot study data.",
        description="Thank you for helping us with this study!",
    )
    stim_dir = tmp_path / "stim"
    write_fixture_stimuli(stim_dir, doc)
    stim = load_stimuli(stim_dir)
    db = tmp_path / "s.db"
    with Store(f"sqlite:///{db}") as store:
        populate(store, stim.study.id)
    assert run("export", "--db", db, "--psych-ds", tmp_path / "ds", "--stimuli", stim_dir)[0] == 0
    desc = json.loads((tmp_path / "ds" / "dataset_description.json").read_text())
    assert desc["license"] == "CC-BY-4.0"
    assert [c["name"] for c in desc["author"]] == ["A. Researcher", "B. Researcher"]
    assert desc["citation"].startswith("Researcher et al.")
    assert "Thank you" not in desc["description"]


def test_exclusion_keeps_the_data_marks_the_export_and_leaves_the_analysis(db, tmp_path):
    from study_app.data import monitor

    with Store(f"sqlite:///{db}") as store:
        people = store.participants()
        who = people[0]["participant_id"]
        monitor.exclude(store, who, "  failed the\nattention check ")
        with pytest.raises(Exception, match="already excluded"):
            monitor.exclude(store, who, "again")
        with pytest.raises(Exception, match="needs a reason"):
            monitor.exclude(store, people[1]["participant_id"], " ")
        n_rows = store.progress()["responses"]
    code, err = run(
        "export",
        "--db",
        db,
        "-o",
        tmp_path / "r.csv",
        "--participants",
        tmp_path / "p.csv",
        "--identifiers",
    )
    assert code == 0, err
    assert len(read_csv(tmp_path / "r.csv")) == n_rows  # the data stay
    marks = {p["participant_id"]: p["excluded"] for p in read_csv(tmp_path / "p.csv")}
    assert marks[who] == "failed the attention check"
    assert [v for k, v in marks.items() if k != who] == ["", ""]
    from analysis.load import rows_from_store

    assert who not in {r["participant_id"] for r in rows_from_store(f"sqlite:///{db}")}
    # Withdrawing an excluded participant deletes the exclusion with the rest.
    assert run("withdraw", "--db", db, "--pid", who)[0] == 0
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT count(*) FROM exclusions").fetchone()[0] == 0
