"""Loading responses, simulating participants, and the `snapshot analyze / simulate / power /
figures` commands end to end: files written, figures not blank, simulated rows excluded."""

from __future__ import annotations

import json
import re

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import lazy_module

from snapcore.cli.main import cli
from study_app.design.scenes import StudyScene

# the modules under test, imported when a test first uses them (fast collection)
pd = lazy_module("pandas")
ld = lazy_module("analysis.load")
sim = lazy_module("analysis.simulate")


def _rows(n=20, seed=3, **kw):
    return sim.simulated_rows(sim.simulate_participants(sim.paper_design(), n, seed=seed, **kw))


def _png_std(path) -> float:
    from PIL import Image

    return float(np.asarray(Image.open(path).convert("L"), dtype=float).std())


def _check_figures(folder, stems):
    for stem in stems:
        png, pdf = folder / f"{stem}.png", folder / f"{stem}.pdf"
        assert png.exists() and pdf.exists(), stem
        assert _png_std(png) > 10, f"{png} looks blank"  # a white page has std 0
        assert pdf.read_bytes()[:5] == b"%PDF-" and pdf.stat().st_size > 5000


# ----------------------------------------------------------------- load


def test_export_files_round_trip(tmp_path):
    """CSV (shown_order as JSON, empty = null) and JSON lines load to the same tidy frame."""
    rows = _rows(5)
    recs = rows.replace({np.nan: None}).to_dict(orient="records")
    (tmp_path / "r.jsonl").write_text("".join(json.dumps(r) + "\n" for r in recs))
    csv = rows.copy()
    csv["shown_order"] = [json.dumps(v) if isinstance(v, list) else "" for v in csv["shown_order"]]
    csv["simulated"] = "true"
    csv["correct"] = csv["correct"].map({True: "true", False: "false"}).fillna("")
    csv.to_csv(tmp_path / "r.csv", index=False)
    a = ld.load_responses(tmp_path / "r.jsonl", include_simulated=True)
    b = ld.load_responses(tmp_path / "r.csv", include_simulated=True)
    assert len(a) == len(b) == len(rows)
    pd.testing.assert_frame_equal(a.drop(columns="created_at"), b.drop(columns="created_at"))
    v = ld.view_choices(a)
    assert all(isinstance(s, tuple) and len(s) == 3 for s in v["shown_order"])
    # the chosen method is the one shown at the chosen position
    assert all(
        s[p] == m
        for s, p, m in zip(v["shown_order"], v["chosen_position"], v["chosen_method"], strict=True)
    )
    p = ld.pose_choices(a)
    np.testing.assert_allclose(p["error_s"], (p["chosen_frame"] - p["algorithm_frame"]) / p["fps"])


def test_simulated_rows_excluded_unless_asked(tmp_path):
    """Real analyses never see simulated participants by default."""
    rows = _rows(4)
    assert ld.load_responses(rows).empty
    assert len(ld.load_responses(rows, include_simulated=True)) == len(rows)


def test_bad_row_is_named(tmp_path):
    """A row breaking the response schema → LoadError with file, row and field."""
    rows = _rows(2)
    recs = rows.replace({np.nan: None}).to_dict(orient="records")
    recs[3]["task"] = "dance"
    f = tmp_path / "bad.jsonl"
    f.write_text("".join(json.dumps(r) + "\n" for r in recs))
    with pytest.raises(ld.LoadError, match=r"bad.jsonl: row 4 \(participant .*, trial \d+\): task"):
        ld.load_responses(f, include_simulated=True)
    (tmp_path / "x.txt").write_text("")
    with pytest.raises(ld.LoadError, match="cannot tell the format from the suffix"):
        ld.load_responses(tmp_path / "x.txt")


def test_analysis_reads_exports_with_the_study_codec(tmp_path):
    """One codec: what study_app.data.export writes, analysis loads unchanged (CSV, JSON lines,
    a .json list); a bad CSV cell is named by file, line and column."""
    from study_app.data.export import write_export

    rows = [
        {k: (list(v) if isinstance(v, tuple) else v) for k, v in r.items()}
        for r in _rows(3).replace({np.nan: None}).to_dict(orient="records")
    ]
    for name in ("r.csv", "r.jsonl"):
        write_export(rows, tmp_path / name)
    (tmp_path / "r.json").write_text(json.dumps(rows))
    frames = [
        ld.load_responses(tmp_path / n, include_simulated=True)
        for n in ("r.csv", "r.jsonl", "r.json")
    ]
    direct = ld.load_responses(rows, include_simulated=True)
    for df in frames:
        pd.testing.assert_frame_equal(df, direct)
    text = (tmp_path / "r.csv").read_text().splitlines()
    head = text[0].split(",")
    cells = text[2].split(",")
    cells[head.index("trial_index")] = "1.5"
    (tmp_path / "bad.csv").write_text("\n".join([text[0], text[1], ",".join(cells)]) + "\n")
    with pytest.raises(ld.LoadError, match=r"bad.csv:3: trial_index: not an integer"):
        ld.load_responses(tmp_path / "bad.csv")


def test_tables_as_markdown_and_latex():
    """Markdown: a pipe table whose cells read back as the formatted cells (| escaped,
    numbers right-aligned); LaTeX: booktabs, one row per line, specials escaped."""
    from analysis.tables import format_table, to_latex, to_markdown

    df = pd.DataFrame(
        {"scene": ["a|b", "c_d"], "p_value": [1e-5, 0.5], "n": [3, 4], "significant": [True, False]}
    )
    md = to_markdown(df).splitlines()
    assert md[1] == "|:--------|----------:|----:|:--------------|"
    cells = [
        [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", line)[1:-1]]
        for line in md[2:]
    ]
    assert (
        cells
        == format_table(df).values.tolist()
        == [["a|b", "1e-05", "3", "yes"], ["c_d", "0.500", "4", "no"]]
    )
    tex = to_latex(df, caption="Votes & 5% (α)", label="tab:t").splitlines()
    assert tex[:4] == [
        "\\begin{table}[ht]",
        "\\centering",
        "\\caption{Votes \\& 5\\% ($\\alpha$)}",
        "\\small",
    ]
    body = tex[tex.index("\\midrule") + 1 : tex.index("\\bottomrule")]
    assert body == ["a\\textbar{}b & 1e-05 & 3 & yes \\\\", "c\\_d & 0.500 & 4 & no \\\\"]
    assert "\\begin{tabular}{lrrl}" in tex and "\\label{tab:t}" in tex


def test_observer_model_frames():
    """Without lapses the chosen frames scatter around the pick with the given spread."""
    design = [StudyScene("a", 100.0, 2000, 1000)]
    model = sim.ObserverModel(spread_s=0.5, lapse=0.0)
    rows = sim.simulated_rows(sim.simulate_participants(design, 2000, seed=1, model=model))
    f = rows.loc[rows["task"] == "pose", "chosen_frame"].to_numpy(float)
    assert abs(f.mean() - 1000) < 3  # SE = 50 / sqrt(2000) ≈ 1.1 frames
    assert f.std() == pytest.approx(50, rel=0.05)  # 0.5 s at 100 fps
    lapse = sim.simulated_rows(
        sim.simulate_participants(
            design, 2000, seed=2, model=sim.ObserverModel(spread_s=0.1, lapse=0.5)
        )
    )
    g = lapse.loc[lapse["task"] == "pose", "chosen_frame"].to_numpy(float)
    far = np.mean(np.abs(g - 1000) > 100)  # lapses land far with probability 0.5 * 0.9
    assert far == pytest.approx(0.45, abs=0.04)


def test_null_observers_ignore_the_motion():
    """Uniform, centre (Beta(2,2)) and habit observers: clip positions with the stated
    distribution whatever the algorithm's frame; habits differ between observers and
    hold across scenes; always-left viewers take position 0 whatever is shown there."""
    from scipy import stats

    design = [StudyScene("a", 30.0, 1001, 100), StudyScene("b", 30.0, 1001, 900)]

    def positions(**kw):
        people = sim.simulate_participants(design, 1500, seed=3, model=sim.ObserverModel(**kw))
        rows = sim.simulated_rows(people)
        pose = rows[rows["task"] == "pose"]
        return pose.pivot(index="participant_id", columns="scene", values="chosen_frame") / 1000

    u = positions(pose_model="uniform")
    assert stats.kstest(u.to_numpy().ravel(), "uniform").pvalue > 0.001
    c = positions(pose_model="centre")
    assert stats.kstest(c.to_numpy().ravel(), stats.beta(2, 2).cdf).pvalue > 0.001
    assert abs(c["a"].mean() - c["b"].mean()) < 0.02  # the algorithm's frame plays no part
    h = positions(pose_model="habit")
    assert stats.spearmanr(h["a"], h["b"]).statistic > 0.3  # one habit in both scenes
    left = sim.simulated_rows(
        sim.simulate_participants(design, 200, seed=4, model=sim.ObserverModel(view_position=0))
    )
    views = left[left["task"] == "view"]
    assert (views["chosen_position"] == 0).all()
    assert set(views["chosen_method"]) == {str(m) for m in sim.VIEW_METHODS}
    for bad in ({"pose_model": "random"}, {"view_position": 3}):
        with pytest.raises(ValueError):
            sim.ObserverModel(**bad)


def test_simulated_orders_are_the_apps_trial_plan():
    """A simulated participant sees the trial order and screen orders the app's
    trial_plan gives their stored seed (so the position null tests the app's own
    randomisation)."""
    from study_app.design.protocol import trial_plan

    design = sim.paper_design()
    for p in sim.simulate_participants(design, 20, seed=8):
        plan = trial_plan([s.scene for s in design], p["seed"])
        got = [(r["task"], r["scene"], tuple(r.get("shown_order") or ())) for r in p["rows"]]
        want = [(t.task, t.scene, tuple(t.shown_order or ())) for t in plan]
        assert got == want


# ----------------------------------------------------------------- commands


def test_analyze_paper_table2_cli(tmp_path):
    """`snapshot analyze --paper-table2`: every table in three formats, figures, report, claims."""
    out = tmp_path / "paper"
    res = CliRunner().invoke(cli, ["analyze", "--paper-table2", "-o", str(out), "--boot", "100"])
    assert res.exit_code == 0, res.output
    assert (
        "ours is significantly preferred in 4 of 6 scenes ((a) Dancing, (c) Soccer kicking, "
        "(d) Basketball shooting, (f) Two-person boxing); not significant in (b) Running, "
        "(e) Two-person arguing."
    ) in res.output
    assert (
        "ours vs motion_area (exact binomial, Holm-adjusted, alpha=0.05): ours is "
        "significantly preferred in 3 of 6 scenes ((c) Soccer kicking, (e) Two-person arguing, "
        "(f) Two-person boxing)"
    ) in res.output
    for name in ("votes", "chisquare", "pairwise", "strengths", "agreement"):
        for ext in ("csv", "md", "tex"):
            assert (out / "tables" / f"{name}.{ext}").stat().st_size > 50, (name, ext)
    tex = (out / "tables" / "pairwise.tex").read_text()
    assert "\\toprule" in tex and "viewpoint\\_entropy" in tex
    votes = pd.read_csv(out / "tables" / "votes.csv")
    assert votes.loc[(votes.scene == "dancing") & (votes.method == "ours"), "votes"].item() == 52
    _check_figures(out / "figures", ["votes", "strengths"])
    html = (out / "report.html").read_text()
    assert html.count('src="data:image/png;base64,') == 2
    assert not re.search(r'src="(?!data:)', html)  # self-contained: nothing to fetch
    summary = json.loads((out / "summary.json").read_text())
    assert summary["votes"]["basketball_shooting"]["viewpoint_entropy"] == 0


@pytest.mark.slow
def test_simulate_store_analyze_end_to_end(tmp_path):
    """simulate → SQLite store (marked simulated) → analyze, via the CLI."""
    url = f"sqlite:///{tmp_path / 'study.db'}"
    r = CliRunner()
    res = r.invoke(cli, ["simulate", "--n", "40", "--db", url, "--seed", "5", "-q"])
    assert res.exit_code == 0, res.output
    assert "stored 40 simulated participants (520 responses" in res.output
    from study_app.data.store import Store

    store = Store(url)
    assert store.export_rows() == []  # simulated participants are not real data
    rows = store.export_rows(include_simulated=True)
    assert len(rows) == 520 and all(row["simulated"] for row in rows)
    # A real analysis refuses to analyse nothing, in one line.
    res = r.invoke(cli, ["analyze", "--db", url, "-o", str(tmp_path / "real")])
    assert (
        res.exit_code == 2 and "no responses" in res.output and "--include-simulated" in res.output
    )
    out = tmp_path / "sim"
    res = r.invoke(
        cli, ["analyze", "--db", url, "--include-simulated", "-o", str(out), "--boot", "50"]
    )
    assert res.exit_code == 0, res.output
    assert "40 participants (40 simulated), 520 responses" in res.output
    summary = json.loads((out / "summary.json").read_text())
    assert summary["simulated_participants"] == 40
    assert sum(summary["votes"]["dancing"].values()) == 40
    hits = pd.read_csv(out / "tables" / "frame_hits.csv")
    assert set(hits["predictor"]) >= {"algorithm", "middle", "uniform_random"}
    for name in ("frame_hits", "frame_tests", "participants"):
        assert (out / "tables" / f"{name}.md").exists()
    _check_figures(
        out / "figures", ["votes", "strengths", "fig13_frame_histograms", "frame_distances"]
    )
    html = (out / "report.html").read_text()
    assert "SIMULATED" in html and html.count("data:image/png;base64,") == 4
    # --no-figures: the same numbers (summary and every table), nothing drawn
    quick = tmp_path / "quick"
    res = r.invoke(
        cli,
        ["analyze", "--db", url, "--include-simulated", "-o", str(quick), "--boot", "50"]
        + ["--no-figures"],
    )
    assert res.exit_code == 0, res.output
    assert json.loads((quick / "summary.json").read_text()) == summary
    tables = sorted(p.name for p in (out / "tables").iterdir())
    assert sorted(p.name for p in (quick / "tables").iterdir()) == tables
    for name in tables:
        assert (quick / "tables" / name).read_bytes() == (out / "tables" / name).read_bytes()
    assert not (quick / "figures").exists()
    assert "data:image/png" not in (quick / "report.html").read_text()


@pytest.mark.slow
def test_analyze_export_file_and_attention(tmp_path):
    """--input reads an export; failed attention checks are counted and can be excluded."""
    rows = _rows(30, seed=9, model=sim.ObserverModel(attention_pass=0.5))
    rows["simulated"] = False  # pretend they are real people
    f = tmp_path / "responses.jsonl"
    f.write_text(
        "".join(
            json.dumps(r) + "\n" for r in rows.replace({np.nan: None}).to_dict(orient="records")
        )
    )
    failed = int((rows.loc[rows.task == "attention", "correct"] == False).sum())  # noqa: E712
    assert 0 < failed < 30
    res = CliRunner().invoke(
        cli,
        [
            "analyze",
            "--input",
            str(f),
            "-o",
            str(tmp_path / "a"),
            "--boot",
            "20",
            "--exclude-failed-attention",
        ],
    )
    assert res.exit_code == 0, res.output
    s = json.loads((tmp_path / "a" / "summary.json").read_text())
    assert s["failed_attention"] == failed
    assert s["participants"] == 30 - failed


def test_power_cli(tmp_path):
    """`snapshot power --ours --baseline` names the participants needed; -o writes the curve."""
    res = CliRunner().invoke(
        cli,
        [
            "power",
            "--ours",
            "0.52",
            "--baseline",
            "0.40",
            "--comparisons",
            "1",
            "-o",
            str(tmp_path),
        ],
    )
    assert res.exit_code == 0, res.output
    from analysis.power import power_pairwise

    n = int(re.search(r"^(\d+) participants", res.output).group(1))
    assert power_pairwise(n, 0.52, 0.40) >= 0.8 > power_pairwise(n - 1, 0.52, 0.40)
    _check_figures(tmp_path, ["power_curve"])
    res = CliRunner().invoke(cli, ["power"])
    assert res.exit_code == 0 and re.search(r"^\|\s+difference\s+\|", res.output, re.M)
    res = CliRunner().invoke(cli, ["power", "--ours", "0.7", "--baseline", "0.5"])
    assert res.exit_code == 2 and "at most 1" in res.output


def test_figures_cli_table2_and_fig13(tmp_path):
    """`snapshot figures --only table2,fig13`: files written, not blank, Fig. 13 marked simulated."""
    res = CliRunner().invoke(cli, ["figures", "--only", "table2,fig13", "-o", str(tmp_path), "-q"])
    assert res.exit_code == 0, res.output
    _check_figures(tmp_path, ["table2_votes", "fig13_frame_histograms"])
    assert (tmp_path / "table2.tex").exists()
    res = CliRunner().invoke(cli, ["figures", "--only", "fig99", "-o", str(tmp_path)])
    assert res.exit_code == 2 and "unknown figure" in res.output


def test_frames_print_as_whole_numbers():
    """Frame numbers and counts print as 54, not 54.000 (even in float columns)."""
    from analysis.tables import format_table

    t = format_table(
        pd.DataFrame({"algorithm_frame": [54.0, np.nan], "votes": [3.0, 1.0], "share": [0.5, 0.25]})
    )
    assert list(t["algorithm_frame"]) == ["54", ""] and list(t["votes"]) == ["3", "1"]
    assert list(t["share"]) == ["0.500", "0.250"]


@pytest.mark.slow
def test_completed_participants_only_by_default(tmp_path):
    """Participants who left before the end are counted as started, not analysed; with
    include-incomplete they are; the participants table shows both counts."""
    from analysis.report import analyze

    rows = _rows(12, seed=4)
    left = rows["participant_id"].unique()[:2]
    # two participants left after their first three answers (no attention check)
    rows = rows[~rows["participant_id"].isin(left) | (rows["trial_index"] < 3)]
    s = analyze(rows, tmp_path / "a", include_simulated=True, n_boot=10, figures=False)
    assert (s["participants"], s["started_participants"], s["completed_participants"]) == (
        10,
        12,
        10,
    )
    assert sum(s["votes"]["dancing"].values()) <= 10
    parts = pd.read_csv(tmp_path / "a" / "tables" / "participants.csv")
    assert (parts["started"].sum(), parts["completed"].sum()) == (12, 10)
    s = analyze(
        rows, tmp_path / "b", include_simulated=True, n_boot=10, completed_only=False, figures=False
    )
    assert s["participants"] == 12


def _near_duplicate_manifest(scenes) -> dict:
    """A minimal manifest: in the first scene ours and motion area are 3.5° apart."""
    entries = []
    for k, sc in enumerate(scenes):
        a = np.radians(3.5 if k == 0 else 60.0)
        entries.append(
            {
                "id": sc,
                "fps": 30.0,
                "n_frames": 300,
                "frame_offset": 0,
                "picks": {
                    "frame": 100,
                    "view": [1.0, 0.0, 0.0],
                    "viewpoint_entropy": [0.0, 0.0, 1.0],
                    "motion_area": [float(np.cos(a)), float(np.sin(a)), 0.0],
                },
            }
        )
    return {"study": {"study": {"id": "paper", "near_duplicate_deg": 15}}, "scenes": entries}


@pytest.mark.slow
def test_near_duplicate_scenes_reported_with_sensitivity(tmp_path):
    """With a stimuli manifest whose candidates nearly coincide, the report names the
    scene, counts the pair as one option, and restates the claims without it."""
    from analysis.report import analyze
    from analysis.stimuli import near_duplicate_scenes

    rows = _rows(20, seed=5)
    scenes = list(dict.fromkeys(rows["scene"]))
    manifest = _near_duplicate_manifest(scenes)
    d = near_duplicate_scenes(manifest)
    assert list(d["scene"]) == [scenes[0]] and d["angle_deg"].iloc[0] == pytest.approx(3.5)
    s = analyze(
        rows, tmp_path / "r", include_simulated=True, n_boot=50, stimuli=manifest, figures=False
    )
    assert s["near_duplicate_scenes"] == [scenes[0]]
    merged = pd.read_csv(tmp_path / "r" / "tables" / "votes_duplicates_merged.csv")
    assert "ours = motion_area" in set(merged.loc[merged["scene"] == scenes[0], "option"])
    html = (tmp_path / "r" / "report.html").read_text()
    assert (
        "Near-duplicate candidates: sensitivity analysis" in html and "Without those scenes" in html
    )


@pytest.mark.slow
def test_analyze_uses_the_study_stimuli_by_default(tmp_path, monkeypatch):
    """Without --stimuli, the study's stimuli folder (var/stimuli/<study id>) is used."""
    from analysis import report

    rows = _rows(20, seed=6)
    (study,) = rows["study_id"].unique()
    assert report.default_stimuli(rows, root=tmp_path) is None  # not built: nothing
    (tmp_path / study).mkdir()
    (tmp_path / study / "manifest.json").write_text("{}")
    assert report.default_stimuli(rows, root=tmp_path) == tmp_path / study
    manifest = _near_duplicate_manifest(list(dict.fromkeys(rows["scene"])))
    monkeypatch.setattr(report, "default_stimuli", lambda df, **kw: manifest)
    s = report.analyze(rows, tmp_path / "o", include_simulated=True, n_boot=50, figures=False)
    assert s["near_duplicate_scenes"]  # the default manifest was read
