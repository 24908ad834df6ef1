"""`snapshot calibrate`: the report's tests on whole simulated studies hold their level
under the nulls, the check has teeth, and it runs the report's own analysis."""

from __future__ import annotations

import json

import numpy as np
import pytest
from click.testing import CliRunner
from conftest import lazy_module
from test_analysis_stimuli import _manifest

from snapcore.cli.main import cli

pd = lazy_module("pandas")
cb = lazy_module("analysis.calibrate")
fr = lazy_module("analysis.frames")

# The demo study's five scenes (study_app/configs/demo.toml as built): length, the
# algorithm's frame and the fastest / stretch selectors' picks, 30 fps, offset 0.
DEMO = {
    "walk": (91, 62, 32, 21),
    "jump": (91, 45, 53, 39),
    "kick": (76, 32, 29, 9),
    "punch": (76, 38, 32, 36),
    "push": (91, 50, 42, 51),
}


def demo_manifest():
    """A schema-valid manifest with the demo's scenes (no files needed)."""
    return _manifest(
        [
            {
                "id": sid,
                "title": sid.title(),
                "source": {"demo": sid},
                "fps": 30.0,
                "n_frames": n,
                "frame_offset": 0,
                "picks": {
                    "frame": a,
                    "frames": [a],
                    "by_method": {"story": [a], "fastest": [f], "stretch": [s]},
                },
            }
            for sid, (n, a, f, s) in DEMO.items()
        ]
    )


@pytest.mark.filterwarnings("ignore::RuntimeWarning")
def test_small_calibration_every_null_holds_its_level():
    """CI calibration: 30 studies of 40 participants under each null (random clickers,
    centre-biased ignorers, personal habits, always-left viewers): every frame and view
    family's false-positive rate, as reported and without Holm, is within its bound."""
    res = cb.calibrate(
        demo_manifest(),
        conditions=("uniform", "centre", "habit", "position"),
        n_participants=40,
        n_studies=30,
        n_permutations=99,
        seed=11,
    )
    summary = cb.summarise(res)
    assert set(summary["role"]) == {"null"}
    assert len(summary) == 4 * len(cb.FAMILIES)
    bad = summary[~summary["holds"].astype(bool)]
    assert bad.empty, bad[["condition", "family", "rate", "unadjusted", "bound"]]
    # The frame families are tested in every scene (fastest/stretch/middle differ from
    # the algorithm's frame except jump's middle, which is the algorithm's).
    tests = summary.set_index(["condition", "family"])["tests"]
    assert tests[("uniform", "agreement")] == 30 * 5
    assert tests[("uniform", "middle")] == 30 * 4


def _legacy_uniform_test(pose, scenes):
    """The test of issue 35: each person's expected distance to a uniformly random frame
    minus their distance to the algorithm's, one-sided Wilcoxon over participants."""
    from scipy import stats

    rows = []
    for sid, info in scenes.items():
        c = pose.loc[pose["scene"] == sid, "chosen_frame"].to_numpy(float)
        f = info.source_frames
        d = np.abs(c[:, None] - f[None, :]).mean(axis=1) - np.abs(c - info.algorithm_frame)
        p = stats.wilcoxon(d, alternative="greater").pvalue
        rows.append({"task": "pose", "family": "legacy", "scene": sid, "p_value": p})
    return pd.DataFrame(rows)


def test_the_level_check_catches_a_centrality_confounded_test():
    """The same bound flags the old "closer than a uniformly random frame" test on the
    same simulated random clickers (it rejects in most scenes), so a passing calibration
    means something."""
    from analysis.load import pose_choices

    doc = demo_manifest()
    design = __import__("analysis.simulate", fromlist=["x"]).design_from_stimuli(doc)
    extra = fr.baselines_from_stimuli(doc)
    parts = []
    for j in range(15):
        df = cb.simulate_study(design, cb.CONDITIONS["uniform"], 40, seed=j)
        pose = pose_choices(df)
        t = _legacy_uniform_test(pose, fr.scene_frames_from_rows(pose, extra=extra))
        t["significant"] = t["for_algorithm"] = t["p_value"] < 0.05
        parts.append(t.assign(condition="uniform", study=j))
    s = cb.summarise(pd.concat(parts, ignore_index=True)).iloc[0]
    assert s["role"] == "null" and not s["holds"]
    assert s["unadjusted"] > 0.5


def test_calibration_runs_the_reports_own_tests(tmp_path):
    """One simulated study through `analyze` and through the calibration: the frame
    tests' and the pairwise view tests' p-values and verdicts are identical."""
    from analysis.report import analyze

    doc = demo_manifest()
    design = __import__("analysis.simulate", fromlist=["x"]).design_from_stimuli(doc)
    rows = cb.simulate_study(design, cb.CONDITIONS["track_0.5s"], 30, seed=5)
    analyze(rows, tmp_path, include_simulated=True, stimuli=doc, n_boot=0, seed=3, figures=False)
    from analysis.load import pose_choices, view_choices

    pose, views = pose_choices(rows), view_choices(rows)
    order = list(DEMO)
    scenes = fr.scene_frames_from_rows(pose, extra=fr.baselines_from_stimuli(doc), order=order)
    ours = cb.report_tests(pose, views, scenes, order=order, seed=3)
    frames = pd.read_csv(tmp_path / "tables" / "frame_tests.csv").dropna(subset=["p_value"])
    got = ours[ours["task"] == "pose"].reset_index(drop=True)
    np.testing.assert_allclose(got["p_value"], frames["p_value"], rtol=1e-12)
    assert list(got["significant"]) == list(frames["significant"])
    pair = pd.read_csv(tmp_path / "tables" / "pairwise.csv")
    mine = ours[ours["family"].str.startswith("ours vs")].reset_index(drop=True)
    np.testing.assert_allclose(mine["p_value"], pair["p_value"], rtol=1e-12)
    assert list(mine["significant"]) == list(pair["significant"])
    assert (got["p_value"] < 0.05).any()  # trackers at 0.5 s: the tests see something


def test_calibrate_cli_writes_docs_and_refuses_bad_input(tmp_path):
    """`snapshot calibrate`: a table, a Markdown file with the command line; an unknown
    condition or a missing manifest is one line with exit code 2."""
    path = tmp_path / "manifest.json"
    path.write_text(json.dumps(demo_manifest()))
    docs = tmp_path / "docs" / "calibration.md"
    args = ["calibrate", "--stimuli", str(path), "--studies", "3", "--participants", "12"]
    res = CliRunner().invoke(
        cli, [*args, "--conditions", "uniform,ours_3", "--write-docs", str(docs), "-q"]
    )
    assert res.exit_code == 0, res.output
    text = docs.read_text()
    assert "--participants 12 --studies 3" in text
    assert "False-positive rates under the nulls" in text and "Power under the alternatives" in text
    assert "| ours_3 | view: ours vs motion_area |" in text
    res = CliRunner().invoke(cli, [*args, "--conditions", "uniform,nope"])
    assert res.exit_code == 2 and "nope" in res.output and "Traceback" not in res.output
    res = CliRunner().invoke(cli, ["calibrate", "--stimuli", str(tmp_path / "missing.json")])
    assert res.exit_code == 2 and "missing.json" in res.output
