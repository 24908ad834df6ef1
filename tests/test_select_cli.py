"""``snapshot select`` / ``snapshot plot-entropy`` and the Snapshot document."""

from __future__ import annotations

import json
import subprocess
import sys
import warnings

import numpy as np
import pytest
from click.testing import CliRunner

from snapcore import load_scene
from snapcore.cli.main import cli
from snapcore.motion import synth
from snapcore.pipeline import VIEW_FIELDS, Snapshot, ViewParams, take_snapshot
from snapcore.schema import validate
from snapcore.select.pose_methods import PoseParams
from snapcore.select.view_methods import ViewMethod


def _run(args):
    result = CliRunner().invoke(cli, args)
    return result


def test_select_json_follows_the_schema_in_source_numbering(motions_dir):
    """--json: schema-valid; frames, peaks and events are source frame numbers
    (02_03 has an added T-pose frame, so internal i is source i + 1)."""
    path = motions_dir / "walk_run" / "02_03.bvh"
    result = _run(["select", str(path), "--json", "-k", "2", "--no-view", "--pose-method", "paper"])
    assert result.exit_code == 0, result.output
    doc = json.loads(result.stdout)
    validate(doc, "snapshot")
    assert doc["pose_method"] == "paper"
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = take_snapshot(load_scene(path), pose=PoseParams(pose_method="paper", k=2), view=None)
    assert doc["frame_offset"] == 1 and doc["n_frames"] == 173 and doc["fps"] == 120
    assert doc["frame"] == snap.index + 1 == snap.source_frame
    assert doc["frames"] == [i + 1 for i in snap.indices] and len(doc["frames"]) == 2
    assert [p["frame"] for p in doc["peaks"]] == doc["frames"]
    assert doc["pose_entropy"]["first_frame"] == 1
    total = np.array(doc["pose_entropy"]["total"])
    assert total.shape == (173,)
    assert np.argmax(total) + doc["pose_entropy"]["first_frame"] == doc["frame"]
    ent = snap.pose.entropy
    np.testing.assert_allclose(doc["pose_entropy"]["local"], ent.local, atol=1e-6)
    events = snap.pose.entropy.interactions.events
    assert [(e["start"], e["end"]) for e in doc["events"]] == [
        (e.start + 1, e.end + 1) for e in events
    ]
    assert set(doc["timings_s"]) >= {"contacts", "local", "global", "select", "pose", "total"}


def test_select_options_reach_the_method(motions_dir):
    """--w-global 0 selects the local maximum; --events state changes the global term."""
    path = str(motions_dir / "dance" / "05_06.bvh")
    paper = ["--pose-method", "paper"]
    doc = json.loads(
        _run(["select", path, "--json", "--no-view", "--w-global", "0", *paper]).stdout
    )
    local = np.array(doc["pose_entropy"]["local"])
    assert doc["frame"] == int(np.argmax(local)) + doc["frame_offset"]
    trans = json.loads(_run(["select", path, "--json", "--no-view", *paper]).stdout)
    state = json.loads(
        _run(["select", path, "--json", "--no-view", "--events", "state", *paper]).stdout
    )
    assert state["pose_entropy"]["events_mode"] == "state"
    assert state["pose_entropy"]["global"] != trans["pose_entropy"]["global"]
    sep = json.loads(
        _run(["select", path, "--json", "--no-view", "-k", "3", "--min-separation", "2"]).stdout
    )
    f = np.array(sep["frames"])
    gaps = np.abs(f[:, None] - f[None])[~np.eye(3, dtype=bool)]
    assert len(f) == 3 and np.all(gaps >= 2 * 120)  # 2 s at 120 fps


def test_select_human_output(motions_dir, tmp_path):
    """Without --json: the pose with its time, the top-k table, event counts, timings;
    -o writes the JSON document too."""
    a, b = (motions_dir / "two_person" / f"{p}_scaled.bvh" for p in ("60_12", "61_12"))
    out = tmp_path / "snap.json"
    result = _run(["select", str(a), str(b), "--fps", "60", "-k", "3", "--no-view", "-o", str(out)])
    assert result.exit_code == 0, result.output
    text = result.stdout
    doc = json.loads(out.read_text())
    assert f"pose        frame {doc['frame']}" in text
    assert "rank   frame   time_s   total   stance    trunk  novelty   events  strikes" in text
    for rank, frame in enumerate(doc["frames"], start=1):
        assert any(line.split()[:2] == [str(rank), str(frame)] for line in text.splitlines())
    assert "61_12_scaled: ground" in text and "60_12_scaled" in text
    assert "timings" in text and "2 characters" in text


@pytest.mark.parametrize("method", ["story", "paper", "stretch", "fastest", "middle"])
def test_printed_terms_add_up_to_the_total(motions_dir, method):
    """`select` prints 'total = term + term ...' for every method, and the printed numbers
    add up (to the printed rounding); the JSON's pose_scores terms add up per frame; the
    paper keeps its entropy names and block, other methods have no pose_entropy."""
    path = str(motions_dir / "walk_run" / "02_01.bvh")
    r = _run(["select", path, "--no-view", "--pose-method", method])
    assert r.exit_code == 0, r.output
    line = next(ln for ln in r.stdout.splitlines() if ln.startswith("pose "))
    score = line.split(" s)  ", 1)[1]  # after "(t = 1.94 s)": "<what> T = a A + b B ..."
    total = float(score.split(" = ")[0].split()[-1])
    terms = [float(part.split()[-1]) for part in score.split(" = ")[1].split(" + ")]
    assert abs(sum(terms) - total) <= 0.5e-3 * (len(terms) + 1), line
    doc = json.loads(_run(["select", path, "--json", "--no-view", "--pose-method", method]).stdout)
    sc = doc["pose_scores"]
    assert sc["method"] == method
    np.testing.assert_allclose(
        np.sum([sc["terms"][k] for k in sc["terms"]], axis=0), sc["total"], atol=1e-5
    )
    if method == "paper":
        assert "entropy" in line and set(sc["terms"]) == {"local", "global"}
        assert "pose_entropy" in doc
    else:
        assert "entropy" not in line and "pose_entropy" not in doc


def test_select_errors_are_one_line(tmp_path):
    """A missing file or a broken BVH: one 'error:' line on stderr, exit code 2."""
    bad = tmp_path / "broken.bvh"
    bad.write_text("HIERARCHY\nROOT Hips\n{\n  OFFSET 0 0\n")
    for target in (tmp_path / "missing.bvh", bad):
        r = subprocess.run(
            [sys.executable, "-m", "snapcore.cli.main", "select", str(target)],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert r.returncode == 2
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("error:") and "Traceback" not in r.stderr
    r = _run(["select", str(bad), "--events", "onsets"])
    assert r.exit_code == 2 and "onsets" in r.output


def test_plot_entropy_writes_a_figure(tmp_path):
    """plot-entropy writes the library's figure of the scene's snapshot: the same pixels as
    plot_entropy(take_snapshot(scene, pose=PoseParams(k=2)), strip=4) at the command's dpi, whose bottom
    curve is the pose score and whose reported frames are the (up to) top-2 picks."""
    from PIL import Image

    from snapcore.pipeline import take_snapshot
    from snapcore.render.entropy_plot import plot_entropy

    folder = tmp_path / "demo"
    written = synth.write_demo(folder)
    manifest = next(p for p in written if p.name.startswith("push") and p.suffix == ".toml")
    out = tmp_path / "push.png"
    r = _run(["plot-entropy", str(manifest), "-o", str(out), "-k", "2", "--strip", "4"])
    assert r.exit_code == 0, r.output
    snap = take_snapshot(load_scene(manifest), pose=PoseParams(k=2), view=None)
    fig = plot_entropy(snap, strip=4)
    total = [ln for ln in fig.axes[1].lines if ln.get_label().startswith("total")]
    np.testing.assert_array_equal(total[0].get_ydata(), snap.pose.scores.total)
    assert fig.axes[1].get_ylabel() == "story score (bits)"  # named after its method
    fig.savefig(tmp_path / "direct.png", dpi=120)
    got = np.asarray(Image.open(out).convert("RGB"))
    want = np.asarray(Image.open(tmp_path / "direct.png").convert("RGB"))
    assert got.shape == want.shape and np.array_equal(got, want)
    # up to k=2 distinct peaks (the story score of the push has one hump: one pick)
    assert 1 <= len(snap.source_frames) <= 2
    frames = snap.source_frames
    assert f"top {len(frames)}: {', '.join(map(str, frames))}" in r.stdout


def test_snapshot_to_dict_includes_view_fields_when_set():
    """The view fields are absent without the view stage; with it, they serialise the typed
    selections (arrays as lists, plain JSON types) and ``views`` names all three methods."""
    scene = synth.synth_scene("kick", fps=30)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = take_snapshot(scene, pose=PoseParams(k=1), view=None)
    doc = snap.to_dict()
    assert not set(VIEW_FIELDS) & set(doc)
    assert snap.views == {}
    validate(doc, "snapshot")
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = take_snapshot(scene, pose=PoseParams(k=1), view=ViewParams(n_views=162))
    doc = snap.to_dict()
    validate(doc, "snapshot")
    assert set(VIEW_FIELDS) <= set(doc)
    assert set(snap.views) == set(ViewMethod)
    assert doc["view"] == snap.view_selection.view.tolist()
    for m in (ViewMethod.MOTION_AREA, ViewMethod.VIEWPOINT_ENTROPY):
        assert doc["baselines"][m.value]["view"] == snap.views[m].tolist()
        assert type(doc["baselines"][m.value]["score"]) is float
    json.dumps(doc, allow_nan=False)  # plain JSON types throughout
    assert isinstance(snap, Snapshot) and snap.source_frames == [snap.source_frame]


def test_synthetic_kick_pose_is_near_the_kick():
    """synth 'kick': the leg is extended at KICK_IMPACT_S; one of the top-3 poses lies
    within 0.2 s of it (the others: the kicking foot leaving and meeting the floor)."""
    scene = synth.synth_scene("kick", fps=60)
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        snap = take_snapshot(scene, pose=PoseParams(k=3), view=None)
    times = np.array(snap.indices) / scene.fps
    assert np.min(np.abs(times - synth.KICK_IMPACT_S)) <= 0.2, times


@pytest.mark.parametrize(
    "bad", [{"k": 0}, {"min_separation_s": -1.0}, {"w_local": -1.0}, {"events": "onsets"}]
)
def test_bad_options_raise_value_errors(bad):
    """Options are checked at the boundary with a message naming the parameter."""
    scene = synth.synth_scene("idle", fps=30)
    with pytest.raises(ValueError, match=next(iter(bad)).split("_")[0]):
        take_snapshot(scene, pose=PoseParams(**bad), view=None)


#: Modules ``snapshot select`` must not import: pyrender imports trimesh, networkx and
#: PIL (~0.7 s of start-up); the face-id pass of the viewpoint-entropy baseline draws
#: with raw GL in a bare EGL context, and the view sphere is stored.
_NOT_FOR_SELECT = ("pyrender", "trimesh", "networkx", "PIL", "pandas", "matplotlib")


def test_select_with_its_baselines_imports_no_pyrender_nor_trimesh(motions_dir, tmp_path):
    """A whole ``snapshot select`` (both baseline views, so GL runs) in a fresh process,
    then the modules it loaded: guards the start-up time against an eager import."""
    clip = str(motions_dir / "walk_run" / "02_01.bvh")
    out = tmp_path / "modules.json"
    code = (
        "import json, sys\n"
        "from snapcore.cli.main import cli\n"
        f"cli.main(['select', {clip!r}, '--json'], standalone_mode=False)\n"
        f"heavy = [m for m in {_NOT_FOR_SELECT!r} if m in sys.modules]\n"
        f"open({str(out)!r}, 'w').write(json.dumps(heavy))\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=600)
    assert proc.returncode == 0, proc.stderr
    result = json.loads(proc.stdout)
    entropy = result["baselines"]["viewpoint_entropy"]
    assert entropy["n_views"] > 0 and entropy["score"] > 0  # the GL pass did run
    assert json.loads(out.read_text()) == []


def test_help_imports_no_rendering_stack():
    """``snapshot --help`` and ``snapshot select --help`` load no GL, mesh or plotting
    module."""
    heavy = (*_NOT_FOR_SELECT, "OpenGL", "scipy")
    code = (
        "import sys\n"
        "from snapcore.cli.main import cli\n"
        "for args in (['--help'], ['select', '--help'], ['render', '--help']):\n"
        "    try:\n"
        "        cli.main(args, standalone_mode=False)\n"
        "    except SystemExit:\n"
        "        pass\n"
        f"print([m for m in {heavy!r} if m in sys.modules], file=sys.stderr)\n"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr.strip().splitlines()[-1] == "[]"
