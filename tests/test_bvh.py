"""BVH reading and writing: real files, round-trips, and malformed input."""

from __future__ import annotations

import subprocess
import sys
import warnings

import numpy as np
import pytest

from snapcore.motion.bvh import BVHError, format_bvh, parse_bvh, read_bvh, write_bvh

GOOD = """HIERARCHY
ROOT Hips
{
\tOFFSET 0 0 0
\tCHANNELS 6 Xposition Yposition Zposition Zrotation Xrotation Yrotation
\tJOINT Spine
\t{
\t\tOFFSET 0 10 0
\t\tCHANNELS 3 Zrotation Xrotation Yrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 5 0
\t\t}
\t}
\tJOINT Leg
\t{
\t\tOFFSET 2 -9 0
\t\tCHANNELS 3 Xrotation Yrotation Zrotation
\t\tEnd Site
\t\t{
\t\t\tOFFSET 0 -8 1
\t\t}
\t}
}
MOTION
Frames: 3
Frame Time: 0.0333333
0 90 0 0 0 0 0 0 0 0 0 0
1 90 0 10 0 0 5 0 0 0 0 -5
2 90 0 20 0 0 10 0 0 0 0 -10
"""


def test_real_files_round_trip_exactly(all_bvh):
    """read → write → read reproduces names, offsets, channels, frame time and every value."""
    for path in all_bvh:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            a = read_bvh(path)
        b = parse_bvh(format_bvh(a))
        assert b.names == a.names, path
        assert b.channels == a.channels, path
        assert np.array_equal(b.parents, a.parents), path
        assert np.array_equal(b.offsets, a.offsets), path
        assert np.array_equal(b.end_site, a.end_site), path
        assert b.frame_time == a.frame_time, path
        assert np.array_equal(b.motion, a.motion), path


def test_real_file_features(motions_dir):
    """The quirks named in the data README are read as the README says."""
    # Mixed channel orders: ZYX at the root, ZXY elsewhere (Daz-style soccer file).
    doc = read_bvh(motions_dir / "soccer" / "10_01.bvh")
    assert doc.channels[0][3:] == ("Zrotation", "Yrotation", "Xrotation")
    assert doc.channels[1] == ("Zrotation", "Xrotation", "Yrotation")
    # Bandai: every joint has 6 channels.
    doc = read_bvh(motions_dir / "walk_run" / "dataset-2_run_normal_001.bvh")
    assert all(len(c) == 6 for c, e in zip(doc.channels, doc.end_site) if not e)
    # Boxing_Toes: one data row more than the header says → header count, with a warning.
    with pytest.warns(UserWarning, match="beyond the header"):
        doc = read_bvh(motions_dir / "boxing_jump" / "Boxing_Toes.bvh")
    assert doc.n_frames == 3069
    # 02_03 was reconstructed with CRLF stripped; the salsa files keep their line ends:
    # both parse to the MANIFEST's frame counts.
    assert read_bvh(motions_dir / "walk_run" / "02_03.bvh").n_frames == 174
    assert read_bvh(motions_dir / "two_person" / "60_01_scaled.bvh").n_frames == 2242


def test_crlf_and_lf_agree(tmp_path):
    """CRLF line ends parse to the same document as LF."""
    a = parse_bvh(GOOD)
    b = parse_bvh(GOOD.replace("\n", "\r\n"))
    assert a.names == b.names and np.array_equal(a.motion, b.motion)


def test_byte_order_mark_is_ignored(tmp_path):
    """Windows tools start UTF-8 files with a byte order mark; the file still reads."""
    (tmp_path / "bom.bvh").write_bytes(b"\xef\xbb\xbf" + GOOD.encode())
    assert read_bvh(tmp_path / "bom.bvh").names == parse_bvh(GOOD).names


def test_joint_names_may_contain_spaces():
    """3ds Max writes its Biped's names with spaces (``JOINT Bip01 L Thigh``): the name is
    the rest of the line, up to the brace."""
    doc = parse_bvh(
        GOOD.replace("JOINT Leg", "JOINT Bip01 L Thigh")
        .replace("ROOT Hips", "ROOT Bip01 {")
        .replace("ROOT Bip01 {\n{", "ROOT Bip01 {")
    )
    assert doc.names == ("Bip01", "Spine", "Spine_End", "Bip01 L Thigh", "Bip01 L Thigh_End")
    assert doc.motion.shape == (3, 12)


def test_keywords_in_any_case():
    """Keywords and channel names written in another case (``joint``, ``End site``,
    ``XROTATION``, ``Frame time:``) read as the same document; joint names keep theirs."""
    text = (
        GOOD.replace("JOINT", "Joint")
        .replace("OFFSET", "offset")
        .replace("CHANNELS", "Channels")
        .replace("End Site", "end site")
        .replace("Xrotation", "XROTATION")
        .replace("MOTION", "Motion")
        .replace("Frame Time:", "Frame time:")
        .replace("ROOT Hips", "root Hips")
    )
    a, b = parse_bvh(GOOD), parse_bvh(text)
    assert b.names == a.names and b.channels == a.channels
    assert np.array_equal(b.motion, a.motion) and b.frame_time == a.frame_time


def test_end_sites_are_joints():
    """End sites become channel-less joints named after their parent."""
    doc = parse_bvh(GOOD)
    assert doc.names == ("Hips", "Spine", "Spine_End", "Leg", "Leg_End")
    assert doc.end_site.tolist() == [False, False, True, False, True]
    assert doc.parents.tolist() == [-1, 0, 1, 0, 3]
    assert doc.motion.shape == (3, 12)


def test_write_read_file(tmp_path):
    """write_bvh then read_bvh round-trips through the file system."""
    doc = parse_bvh(GOOD)
    write_bvh(doc, tmp_path / "x.bvh")
    back = read_bvh(tmp_path / "x.bvh")
    assert np.array_equal(back.motion, doc.motion) and back.names == doc.names


# GOOD's lines: 25 MOTION, 26 Frames, 27 Frame Time, 28-30 the three data rows.
MALFORMED = {
    # name: (text, expected line or None, fragment of the message)
    "empty file": ("", 1, "empty"),
    "no HIERARCHY keyword": (GOOD.replace("HIERARCHY", "HIERARCHIES"), 1, "expected 'HIERARCHY'"),
    "truncated hierarchy": (GOOD[: GOOD.index("\tJOINT Leg")], None, "unexpected end of file"),
    "missing MOTION": (GOOD[: GOOD.index("MOTION")], None, "MOTION"),
    "fewer values than channels": (
        GOOD.replace("1 90 0 10 0 0 5 0 0 0 0 -5", "1 90 0 10 0 0 5 0 0 0 0"),
        29,
        "11 values, fewer than the 12",
    ),
    "more values than channels": (
        GOOD.replace("0 90 0 0 0 0 0 0 0 0 0 0", "0 90 0 0 0 0 0 0 0 0 0 0 7"),
        28,
        "13 values, more than the 12",
    ),
    "non-numeric value": (
        GOOD.replace("2 90 0 20", "2 90 zero 20"),
        30,
        "expected a number, found 'zero'",
    ),
    "NaN value": (
        GOOD.replace("2 90 0 20", "2 90 nan 20"),
        30,
        "channel 2 is not a finite number (nan)",
    ),
    "infinite value": (GOOD.replace("1 90 0 10", "1 90 inf 10"), 29, "not a finite number"),
    "zero frames": (GOOD.replace("Frames: 3", "Frames: 0"), 26, "0 frames"),
    "negative frame time": (
        GOOD.replace("Frame Time: 0.0333333", "Frame Time: -0.03"),
        27,
        "frame time must be a positive",
    ),
    "unknown channel name": (
        GOOD.replace("Xrotation Yrotation Zrotation", "Xrotation Yrotation Wrotation"),
        18,
        "unknown channel 'Wrotation'",
    ),
    "duplicate joint names": (
        GOOD.replace("JOINT Leg", "JOINT Spine"),
        15,
        "duplicate joint name 'Spine'",
    ),
    "fewer data rows than frames": (
        GOOD.replace("Frames: 3", "Frames: 5"),
        None,
        "expected 5 frames",
    ),
    "channel count too large": (
        GOOD.replace(
            "CHANNELS 3 Zrotation Xrotation Yrotation", "CHANNELS 4 Zrotation Xrotation Yrotation"
        ),
        None,
        "unknown channel",
    ),
    "non-numeric offset": (GOOD.replace("OFFSET 0 10 0", "OFFSET 0 ten 0"), 8, "expected OFFSET y"),
    "non-integer frame count": (
        GOOD.replace("Frames: 3", "Frames: three"),
        26,
        "integer frame count",
    ),
    "garbage after hierarchy": (GOOD.replace("MOTION", "}\nMOTION"), 25, "expected 'MOTION'"),
}


@pytest.mark.parametrize("case", sorted(MALFORMED))
def test_malformed_input_names_the_line(case):
    """Each malformed file raises BVHError naming the line and what was expected."""
    text, line, fragment = MALFORMED[case]
    with pytest.raises(BVHError) as info:
        parse_bvh(text, path="bad.bvh")
    err = info.value
    assert fragment in str(err)
    assert str(err).startswith("bad.bvh:")
    if line is not None:
        assert err.line == line, f"{case}: reported line {err.line}, expected {line}"


def test_cli_reports_malformed_files_in_one_line(tmp_path):
    """`snapshot info` on every malformed case: one line on stderr, exit code 2, no traceback."""
    cases = sorted(MALFORMED)
    assert len(cases) >= 12
    for i, case in enumerate(cases):
        p = tmp_path / f"case{i}.bvh"
        p.write_text(MALFORMED[case][0], encoding="utf-8")
    # One process for all cases keeps this fast; each file is a separate invocation.
    code = (
        "import sys\n"
        "from snapcore.cli.main import main\n"
        "for p in sys.argv[1:]:\n"
        "    rc = main(['info', p])\n"
        "    print('RC', rc, flush=True)\n"
        "    sys.stderr.write('@@END\\n'); sys.stderr.flush()\n"
    )
    files = [str(tmp_path / f"case{i}.bvh") for i in range(len(cases))]
    out = subprocess.run(
        [sys.executable, "-c", code, *files], capture_output=True, text=True, timeout=120
    )
    rcs = [line.split()[1] for line in out.stdout.splitlines() if line.startswith("RC")]
    blocks = out.stderr.split("@@END\n")[: len(cases)]
    assert rcs == ["2"] * len(cases), out.stdout + out.stderr
    for case, f, block in zip(cases, files, blocks):
        lines = [ln for ln in block.splitlines() if ln.strip()]
        assert len(lines) == 1, f"{case}: {block!r}"
        assert lines[0].startswith(f"error: {f}"), f"{case}: {lines[0]}"
        assert "Traceback" not in block


def test_cli_missing_file_and_binary(tmp_path):
    """A missing file and a binary file are one-line errors with exit code 2."""
    binary = tmp_path / "junk.bvh"
    binary.write_bytes(bytes(range(256)) * 4)
    for p in (tmp_path / "nope.bvh", binary):
        r = subprocess.run(
            [sys.executable, "-m", "snapcore.cli.main", "info", str(p)],
            capture_output=True,
            text=True,
            timeout=60,
        )
        assert r.returncode == 2
        assert r.stderr.count("\n") == 1 and r.stderr.startswith("error: ")
        assert "Traceback" not in r.stderr
