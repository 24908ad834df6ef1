"""Every JSON document the suite prints or writes follows its schema in ``data_schema/``.

Each output is produced by the real command (``snapshot info / bench / relief / video /
analyze``) and checked with ``jsonschema`` against the schema file read here, apart from
``snapcore.schema``; each schema must also reject a wrong document (so an empty schema
fails), and a writer whose document breaks its schema stops with one ``error:`` line.
"""

from __future__ import annotations

import copy
import json

import jsonschema
import pytest
from click.testing import CliRunner

from data_schema import SCHEMA_DIR, schema_path
from snapcore.cli.main import cli

OUTPUT_SCHEMAS = ("info", "bench", "relief", "frame_map", "analysis_summary")


def _schema(name: str) -> dict:
    return json.loads(schema_path(name).read_text(encoding="utf-8"))


def _valid(doc, name: str) -> None:
    jsonschema.validate(doc, _schema(name), cls=jsonschema.Draft202012Validator)


def _rejects(doc, name: str) -> None:
    with pytest.raises(jsonschema.ValidationError):
        _valid(doc, name)


#: A change that removes the item (see :func:`_rejects_changes`).
_DELETE = object()


def _rejects_changes(doc, name: str, *changes) -> None:
    """The schema refuses ``doc`` with each change made alone: ``(path, value)`` sets the
    item at ``path`` (keys and indices) to ``value``, or removes it for :data:`_DELETE`."""
    for path, value in changes:
        bad = copy.deepcopy(doc)
        *head, last = path
        target = bad
        for key in head:
            target = target[key]
        if value is _DELETE:
            del target[last]
        else:
            target[last] = value
        _rejects(bad, name)


def _run(args):
    result = CliRunner().invoke(cli, args)
    assert result.exit_code == 0, result.output
    return result


@pytest.fixture(scope="module")
def walk_bvh(motions_dir):
    """02_03 starts with an added T-pose frame: internal frame i is source frame i + 1."""
    return motions_dir / "walk_run" / "02_03.bvh"


# ----------------------------------------------------------------- every schema


@pytest.mark.parametrize("path", sorted(SCHEMA_DIR.glob("*.schema.json")), ids=lambda p: p.name)
def test_every_schema_is_valid_draft_2020_12(path):
    schema = json.loads(path.read_text(encoding="utf-8"))
    jsonschema.Draft202012Validator.check_schema(schema)
    assert schema["$schema"] == "https://json-schema.org/draft/2020-12/schema"
    assert schema["$id"] == f"https://action-snapshot.example/schema/{path.name}"
    assert schema.get("title") and schema.get("description")


def test_output_schemas_exist():
    for name in OUTPUT_SCHEMAS:
        assert schema_path(name).exists(), name


# ----------------------------------------------------------------- snapshot info


def test_info_json_follows_schema(walk_bvh):
    doc = json.loads(_run(["info", str(walk_bvh), "--json"]).stdout)
    _valid(doc, "info")
    assert doc["frame_offset"] == 1 and doc["n_characters"] == len(doc["characters"]) == 1
    assert doc["characters"][0]["unit"] == "cmu"
    _rejects_changes(
        doc,
        "info",
        (("frame_offset",), _DELETE),
        (("characters", 0, "n_joints"), "38"),
        (("bounds_m", "min"), [0.0, 0.0]),
    )


def test_info_units_cover_every_known_unit():
    """The schema's unit enum follows snapcore.motion.scene.KNOWN_UNITS (+ fitted, given)."""
    from snapcore.motion.scene import KNOWN_UNITS

    enum = _schema("info")["properties"]["characters"]["items"]["properties"]["unit"]["enum"]
    assert set(enum) == set(KNOWN_UNITS) | {"fitted", "given"}


def test_writer_with_a_broken_document_fails_in_one_line(walk_bvh, monkeypatch):
    """A bug that changes the output's shape stops the command with `error:`, no JSON."""
    from snapcore.cli import info as info_cmd

    real = info_cmd.scene_summary
    monkeypatch.setattr(info_cmd, "scene_summary", lambda scene: real(scene) | {"n_frames": -1})
    result = CliRunner().invoke(cli, ["info", str(walk_bvh), "--json"])
    assert result.exit_code == 2
    assert (
        "error: snapshot info output: n_frames: -1 is less than the minimum of 1" in result.output
    )
    assert "{" not in result.stdout and "Traceback" not in result.output


# ----------------------------------------------------------------- snapshot bench


@pytest.fixture
def bench_env(monkeypatch):
    """`snapshot bench` sets BLAS threads for the process: undo it after the test."""
    from threadpoolctl import threadpool_limits

    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        monkeypatch.delenv(var, raising=False)
    with threadpool_limits(limits=None):  # restores the original limits on exit
        yield monkeypatch


def test_bench_json_follows_schema(bench_env):
    doc = json.loads(_run(["bench", "--only", "synth walk", "--json", "-n", "1"]).stdout)
    _valid(doc, "bench")
    assert len(doc) == 1 and doc[0]["repeats"] == 1 and doc[0]["status"] in ("ok", "SLOW")
    _rejects_changes(
        doc,
        "bench",
        ((0, "median_ms"), _DELETE),
        ((0, "min_ms"), None),  # a case that ran has times
        ((0, "status"), "fine"),
    )


def test_bench_only_matching_nothing_is_an_error(bench_env):
    """A mistyped --only does not pass silently: one line, exit code 2, nothing run."""
    from click.testing import CliRunner

    from snapcore.cli.main import cli

    result = CliRunner().invoke(cli, ["bench", "--only", "no such case", "--json"])
    assert result.exit_code == 2
    assert result.output.strip() == (
        "error: --only 'no such case': no benchmark case has that in its name"
    )
    _rejects([], "bench")


def test_bench_json_skipped_case_follows_schema(bench_env, tmp_path):
    """A case whose data is missing is listed as skipped, with null times."""
    bench_env.setenv("SNAPSHOT_DATA", str(tmp_path))  # an empty data folder
    doc = json.loads(_run(["bench", "--only", "parse+FK Boxing", "--json", "-n", "1"]).stdout)
    _valid(doc, "bench")
    assert [(r["status"], r["min_ms"], r["repeats"]) for r in doc] == [("skipped", None, 0)]
    _rejects_changes(doc, "bench", ((0, "min_ms"), 1.0))


# ----------------------------------------------------------------- snapshot relief


def test_relief_json_follows_schema(walk_bvh, tmp_path):
    """Pose and view picked by the pipeline; a 120 x 80 mm footprint gives a [ny, nx] grid."""
    stl = tmp_path / "walk.stl"
    doc = json.loads(
        _run(
            [
                "relief",
                str(walk_bvh),
                "--resolution",
                "16",
                "--size",
                "120x80",
                "-o",
                str(stl),
                "--json",
            ]
        ).stdout
    )
    _valid(doc, "relief")
    assert doc["selected"] == ["frame", "view"] and doc["frame"] >= 1  # source numbering
    assert doc["grid"] == [11, 16] and doc["size_mm"] == [120.0, 80.0]
    assert doc["stl"] == str(stl) and stl.exists() and (tmp_path / "walk.png").exists()
    _rejects_changes(
        doc,
        "relief",
        (("method",), "poisson"),
        (("grid",), [11.5, 16]),
        (("n_triangles",), _DELETE),
    )


# ----------------------------------------------------------------- snapshot video --frame-map


def test_video_frame_map_follows_schema(walk_bvh, tmp_path):
    """--frames A:B are source frames; the map lists the source frame of each video frame."""
    fm = tmp_path / "map.json"
    _run(
        [
            "video",
            str(walk_bvh),
            "-o",
            str(tmp_path / "walk.mp4"),
            "--fps",
            "30",
            "--size",
            "64x48",
            "--frames",
            "5:35",
            "--view",
            "0,0,1",
            "--quiet",
            "--frame-map",
            str(fm),
        ]
    )
    doc = json.loads(fm.read_text())
    _valid(doc, "frame_map")
    assert doc["source_frames"][0] == 5 and doc["source_frames"][-1] <= 35
    assert doc["size"] == [64, 48] and doc["fps"] == 30 and doc["motion_fps"] == 120
    _rejects_changes(
        doc,
        "frame_map",
        (("source_frames",), []),
        (("size",), [64, 47]),  # videos have even sizes
        (("source_frames", 0), 5.5),
    )


# ----------------------------------------------------------------- snapshot analyze summary.json


def test_analysis_summary_of_paper_table2_follows_schema(tmp_path):
    """--paper-table2: the vote part only (no participants)."""
    out = tmp_path / "paper"
    _run(["analyze", "--paper-table2", "-o", str(out), "--boot", "20", "--no-figures", "-q"])
    doc = json.loads((out / "summary.json").read_text())
    _valid(doc, "analysis_summary")
    assert "participants" not in doc and len(doc["pairwise"]) == 12
    _rejects_changes(
        doc,
        "analysis_summary",
        (("fleiss_kappa",), _DELETE),  # the vote part comes whole
        (("votes", "dancing", "ours"), 52.5),
        (("pairwise", 0, "p_value"), 1.5),
    )


@pytest.mark.slow
def test_analysis_summary_of_study_responses_follows_schema(tmp_path):
    """analyze on simulated responses: votes, frames and the participant counts."""
    from analysis import simulate as sim
    from analysis.report import analyze

    rows = sim.simulated_rows(sim.simulate_participants(sim.paper_design(), 12, seed=3))
    out = tmp_path / "sim"
    analyze(rows, out, include_simulated=True, n_boot=20, n_permutations=200, figures=False)
    doc = json.loads((out / "summary.json").read_text())
    _valid(doc, "analysis_summary")
    assert doc["participants"] == doc["simulated_participants"] == 12
    assert {"claims", "frames", "frame_verdict"} <= set(doc)
    _rejects_changes(
        doc,
        "analysis_summary",
        (("responses",), _DELETE),
        (("frames", 0, "hit_0.5s"), "50%"),
        (("participants",), -1),
    )


def test_analysis_summary_is_validated_before_writing(tmp_path):
    """A summary that breaks the schema raises SchemaError and writes no summary.json."""
    from analysis.report import _write_summary
    from snapcore.errors import SchemaError

    with pytest.raises(SchemaError, match=r"summary.json: .*fleiss_kappa"):
        _write_summary(
            tmp_path,
            {
                "source": "x",
                "claims": [],
                "votes": {},
                "chisquare_p": {},
                "pairwise": [],
                "fleiss_kappa": "high",
            },
        )
    assert not (tmp_path / "summary.json").exists()


def test_analysis_summary_of_one_participant_is_strict_json(tmp_path):
    """One participant: no scene has two votes, so Fleiss' kappa is undefined. The file
    stays strict JSON (no bare NaN, which json parsers in other languages reject) and
    says null there."""
    from analysis import simulate as sim
    from analysis.report import analyze

    def no_constants(name):
        raise AssertionError(f"summary.json holds {name}, which is not JSON")

    rows = sim.simulated_rows(sim.simulate_participants(sim.paper_design(), 1, seed=5))
    out = tmp_path / "one"
    with pytest.warns(UserWarning, match="no scene with two or more votes"):
        analyze(rows, out, include_simulated=True, n_boot=20, n_permutations=200, figures=False)
    doc = json.loads((out / "summary.json").read_text(), parse_constant=no_constants)
    _valid(doc, "analysis_summary")
    assert doc["participants"] == 1 and doc["fleiss_kappa"] is None
