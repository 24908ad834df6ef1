"""One analysis from either source: `snapshot analyze --db` on the store and `--input` on
its Psych-DS export (after an exclusion and a withdrawal) give the same numbers, and both
say who was left out with the researcher page's counts."""

from __future__ import annotations

import csv
import json
import math
import random
from pathlib import Path

import pandas as pd
import pytest
from app_helpers import fixture_study_doc, write_fixture_stimuli
from click.testing import CliRunner

from snapcore.cli.main import cli

#: People who finished, one who left after three answers, one who only consented.
N_FINISHED = 24
EXCLUSION_REASON = "clicked through in 40 s"


@pytest.fixture(scope="module")
def stimuli(tmp_path_factory) -> Path:
    d = tmp_path_factory.mktemp("stimuli") / "fixture"
    write_fixture_stimuli(d, fixture_study_doc(scene_ids=("walk", "jump", "spin")))
    return d


def populate(url: str, stimuli: Path) -> dict:
    """Real (not simulated) participants answering like the observer model, one of them
    excluded and one withdrawn on the researcher's side; returns who is who."""
    from analysis import simulate as sim
    from study_app.data.monitor import exclude
    from study_app.data.store import Store
    from study_app.data.withdraw import withdraw

    doc = json.loads((stimuli / "manifest.json").read_text())
    design = sim.design_from_stimuli(doc)
    att = doc["study"].get("attention")
    people = sim.simulate_participants(
        design, N_FINISHED + 1, seed=11, attention=att if isinstance(att, dict) else None
    )
    with Store(url) as store:
        ids = []
        for k, p in enumerate(people):
            pid = store.create_participant("fixture", "0" * 64, app_version="test", seed=p["seed"])
            store.set_background(pid, p["background"])
            if k == N_FINISHED:  # left after three answers
                store.record_responses(pid, p["rows"][:3])
            else:
                store.record_responses(pid, p["rows"])
                store.complete(pid)
            ids.append(pid)
        ids.append(store.create_participant("fixture", "0" * 64, app_version="test", seed=7))
        exclude(store, ids[0], EXCLUSION_REASON)
        withdraw(store, participant_id=ids[1], by="page")
    return {"excluded": ids[0], "withdrawn": ids[1], "left": ids[N_FINISHED], "idle": ids[-1]}


def run(*args) -> None:
    res = CliRunner().invoke(cli, [str(a) for a in args])
    assert res.exit_code == 0, res.output


def close(a, b, path="") -> None:
    """Equal JSON documents, numbers to 1e-9 relative (summation order may differ)."""
    if isinstance(a, dict):
        assert isinstance(b, dict) and sorted(a) == sorted(b), (path, a, b)
        for k in a:
            close(a[k], b[k], f"{path}.{k}")
    elif isinstance(a, list):
        assert isinstance(b, list) and len(a) == len(b), (path, a, b)
        for i, (x, y) in enumerate(zip(a, b, strict=True)):
            close(x, y, f"{path}[{i}]")
    elif isinstance(a, float) and not isinstance(a, bool):
        assert isinstance(b, int | float) and math.isclose(a, b, rel_tol=1e-9, abs_tol=1e-12), (
            path,
            a,
            b,
        )
    else:
        assert a == b, (path, a, b)


def same_tables(a: Path, b: Path) -> None:
    names = sorted(p.name for p in (a / "tables").glob("*.csv"))
    assert names == sorted(p.name for p in (b / "tables").glob("*.csv")) and names
    for name in names:
        ta, tb = pd.read_csv(a / "tables" / name), pd.read_csv(b / "tables" / name)
        pd.testing.assert_frame_equal(ta, tb, check_exact=False, rtol=1e-9, obj=name)


def analyses(url: str, stimuli: Path, tmp_path: Path, *, shuffle: bool = False):
    """(summary of --db, summary of --input on the Psych-DS export), and the folders."""
    ds = tmp_path / "ds"
    run("export", "--db", url, "--psych-ds", ds, "--stimuli", stimuli)
    data = ds / "data" / "study-fixture_data.csv"
    if shuffle:  # another row order and other ids: the analysis must not depend on either
        people = ds / "data" / "study-fixture_description-participants_data.csv"
        with people.open(newline="", encoding="utf-8") as fh:
            ids = sorted(r["participant_id"] for r in csv.DictReader(fh))
        new = dict(zip(ids, random.Random(3).sample(ids, len(ids)), strict=True))
        for f in (data, people):
            with f.open(newline="", encoding="utf-8") as fh:
                rows = list(csv.DictReader(fh))
            for r in rows:
                r["participant_id"] = new[r["participant_id"]]
            random.Random(5).shuffle(rows)
            with f.open("w", newline="", encoding="utf-8") as fh:
                w = csv.DictWriter(fh, fieldnames=list(rows[0]))
                w.writeheader()
                w.writerows(rows)
    a, b = tmp_path / "db", tmp_path / "input"
    common = ["--no-figures", "--boot", "200", "--seed", "4"]
    run("analyze", "--db", url, "--stimuli", stimuli, "-o", a, *common)
    # The open dataset alone: its manifest in materials/, exclusions in its participants file.
    run("analyze", "--input", data, "-o", b, *common)
    sa, sb = (json.loads((d / "summary.json").read_text()) for d in (a, b))
    return sa, sb, a, b


def check_same(sa, sb, a, b) -> None:
    assert sa.pop("source") != sb.pop("source")
    close(sa, sb)
    same_tables(a, b)


@pytest.mark.slow
def test_the_open_dataset_reproduces_the_store_analysis(tmp_path, stimuli):
    """--input on the Psych-DS export == --db on the store: every summary number and
    table (votes, tests, intervals), after one exclusion and one withdrawal (SQLite)."""
    url = f"sqlite:///{tmp_path / 'study.db'}"
    populate(url, stimuli)
    sa, sb, a, b = analyses(url, stimuli, tmp_path)
    n = N_FINISHED - 2  # one excluded, one withdrawn
    assert sa["participants"] == n and sum(sa["votes"]["walk"].values()) == n
    check_same(sa, sb, a, b)


@pytest.mark.slow
def test_row_order_and_ids_do_not_change_the_numbers(tmp_path, stimuli):
    """Rows shuffled and participant ids swapped in the export: the same numbers, so the
    analysis rests on column names and the participants file, not on order or ids."""
    url = f"sqlite:///{tmp_path / 'study.db'}"
    populate(url, stimuli)
    check_same(*analyses(url, stimuli, tmp_path, shuffle=True))


@pytest.mark.slow
def test_the_open_dataset_reproduces_the_store_analysis_on_postgresql(tmp_path, stimuli, pg_url):
    """The same equality on PostgreSQL."""
    populate(pg_url, stimuli)
    check_same(*analyses(pg_url, stimuli, tmp_path))


@pytest.mark.slow
def test_report_says_who_was_left_out_with_the_page_counts(tmp_path, stimuli):
    """summary.json and report.html give started, finished, excluded (with the reason)
    and withdrawn, the same counts the researcher page shows, from either source."""
    from study_app.data.monitor import STATES, monitor_rows
    from study_app.data.store import Store

    url = f"sqlite:///{tmp_path / 'study.db'}"
    populate(url, stimuli)
    with Store(url) as store:
        page = monitor_rows(store, "fixture", n_trials=7)
    states = {s: sum(r["state"] == s for r in page) for s in STATES}
    sa, sb, a, b = analyses(url, stimuli, tmp_path)
    expected = {
        "started": N_FINISHED + 1,  # every finisher but the withdrawn one, the leaver, the idle
        "finished": N_FINISHED - 2,
        "excluded": 1,
        "exclusion_reasons": {EXCLUSION_REASON: 1},
        "withdrawn": 1,
        "analysed": N_FINISHED - 2,
    }
    assert len(page) == expected["started"]
    assert states["finished"] == expected["finished"] and states["excluded"] == 1
    for s, folder in ((sa, a), (sb, b)):
        assert {k: s["left_out"][k] for k in expected} == expected
        assert s["participants"] == expected["analysed"]
        html = (folder / "report.html").read_text()
        assert "Who was left out" in html and EXCLUSION_REASON in html
        assert "withdrew" in html


def test_quick_row_check_agrees_with_jsonschema():
    """The compiled check that speeds up reading thousands of rows never accepts a row
    jsonschema refuses (one breach of each kind the schema states) and accepts a valid
    one; a row it refuses goes on to jsonschema, which decides and words the error."""
    import jsonschema

    from snapcore.schema import _validator, quick_check

    row = {
        "participant_id": "9QRsdvyZKL-P6PZRfz3OiQ",
        "study_id": "demo",
        "trial_index": 1,
        "task": "view",
        "scene": "walk",
        "stimulus_id": "walk/view",
        "chosen_method": "ours",
        "chosen_position": 0,
        "shown_order": ["ours", "motion_area", "viewpoint_entropy"],
        "fps": 30.0,
        "n_frames": 91,
        "response_time_s": 3.2,
        "created_at": "2026-12-03",
        "app_version": "t",
        "manifest_sha256": "0" * 64,
        "simulated": False,
    }
    breaches = [
        ("trial_index", True),
        ("trial_index", -1),
        ("trial_index", 1.5),
        ("task", "dance"),
        ("fps", 0),
        ("shown_order", ["ours", "ours", "motion_area"]),
        ("participant_id", "x"),
        ("extra", 1),
        ("chosen_method", "best"),
        ("simulated", "no"),
        ("manifest_sha256", "z" * 64),
    ]
    quick = quick_check("response")
    assert quick is not None
    variants = [row, {**row, "trial_index": 2.0}] + [{**row, k: v} for k, v in breaches]
    variants.append({k: v for k, v in row.items() if k != "task"})
    for doc in variants:
        valid = jsonschema.exceptions.best_match(_validator("response").iter_errors(doc)) is None
        assert quick(doc) <= valid, doc
    assert quick(row) and sum(quick(d) for d in variants) <= 2
