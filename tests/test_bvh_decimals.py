"""The BVH reader's fast decimal path: the same doubles as Python's ``float``, bit for bit,
and a hand-over to NumPy's parser for everything it does not read."""

from __future__ import annotations

import numpy as np
import pytest

from snapcore.motion.bvh import _plain_decimals, parse_bvh


def _bits(x: np.ndarray) -> np.ndarray:
    return np.asarray(x, dtype=np.float64).view(np.int64)


def _reference(rows: list[str]) -> np.ndarray:
    """Python's correctly rounding ``float`` on every token."""
    return np.array([[float(t) for t in row.split()] for row in rows])


def _random_rows(rng, n_rows: int, n_chan: int) -> list[str]:
    """Rows in the forms exporters write: %f with 0-8 decimals, integers, signs, -0."""
    rows = []
    for _ in range(n_rows):
        toks = []
        for _ in range(n_chan):
            kind = rng.integers(6)
            mag = 10.0 ** rng.integers(-3, 8)
            x = rng.uniform(-mag, mag)
            if kind == 0:
                toks.append(str(int(x)))  # "0", "-17"
            elif kind == 1:
                toks.append(f"{x:+.{rng.integers(1, 7)}f}")  # "+1.25"
            elif kind == 2:
                toks.append(f"-{0.0:.{rng.integers(0, 9)}f}")  # "-0.000000", "-0"
            else:
                digits = int(rng.integers(0, 9))
                t = f"{x:.{digits}f}"
                if len(t.replace("-", "").replace(".", "")) <= 15:
                    toks.append(t)
                else:
                    toks.append(f"{x:.2f}")
        sep = "\t" if rng.random() < 0.1 else " "
        rows.append(("  " if rng.random() < 0.2 else "") + sep.join(toks) + " ")
    return rows


@pytest.mark.parametrize("seed", range(5))
def test_random_decimals_are_pythons_floats_bit_for_bit(seed):
    rng = np.random.default_rng(seed)
    rows = _random_rows(rng, 300, 17)
    got = _plain_decimals(rows, 17)
    assert got is not None  # the fast path read them: otherwise this test shows nothing
    assert np.array_equal(_bits(got), _bits(_reference(rows)))


def test_edge_forms_and_signed_zero():
    rows = ["-0.000000 0.000000 -0 +0 .5 -.25", "5. +7. 12345678.1234567 0.00000001 99999999 -1"]
    got = _plain_decimals(rows, 6)
    assert got is not None
    ref = _reference(rows)
    assert np.array_equal(_bits(got), _bits(ref))
    assert np.signbit(got[0, 0]) and not np.signbit(got[0, 1]) and np.signbit(got[0, 2])


def test_hard_roundings_match():
    """Decimals whose double lies near a rounding tie (0.1 + k ulp neighbourhoods,
    15-digit values): one division rounds them as float() does."""
    vals = ["0.1", "0.3", "2.675", "1.0000001", "9007199.25474099", "0.00000015"]
    vals += ["1234567.12345678", "4503599.62737049", "8.9999999"]
    rows = [" ".join(vals)]
    got = _plain_decimals(rows, len(vals))
    assert got is not None
    assert np.array_equal(_bits(got), _bits(_reference(rows)))


@pytest.mark.parametrize(
    "token",
    [
        "1e-05",
        "1.5E3",
        "nan",
        "inf",
        "-",
        ".",
        "-.",
        "1.2.3",
        "1-2",
        "--1",
        "+-1",
        "0x1",
        "123456789.5",
        "1.123456789",
        "1234567.123456789",
        "1_0",
        "١٢",
    ],
)
def test_other_forms_go_to_numpys_parser(token):
    rows = [f"1.0 {token} 2", "3 4 5"]
    assert _plain_decimals(rows, 3) is None


def test_rows_with_compensating_counts_go_to_numpys_parser():
    assert _plain_decimals(["1 2 3", "4", "5 6"], 2) is None  # 6 values, rows of 3, 1, 2
    assert _plain_decimals(["1 2\x0c3", "4 5 6"], 3) is None  # a form feed is not a space


def test_parse_bvh_reads_exponents_and_integers_alike():
    """A document mixing both paths' forms gives float()'s values either way."""
    head = (
        "HIERARCHY\nROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
        "\tEnd Site\n\t{\n\t\tOFFSET 0 5 0\n\t}\n}\nMOTION\nFrames: 2\nFrame Time: 0.1\n"
    )
    for rows in (["0 -17 3.25", "1.5 -0.000 2"], ["0 5.1072e-06 3", "1 2 -5.5e-7"]):
        doc = parse_bvh(head + "\n".join(rows) + "\n")
        assert np.array_equal(_bits(doc.motion), _bits(_reference(rows)))


HEAD = (
    "HIERARCHY\nROOT Hips\n{\n\tOFFSET 0 0 0\n\tCHANNELS 3 Zrotation Xrotation Yrotation\n"
    "\tEnd Site\n\t{\n\t\tOFFSET 0 5 0\n\t}\n}\nMOTION\nFrames: 3\nFrame Time: 0.1\n"
)


@pytest.mark.parametrize(
    "rows, clean",
    [
        ("0 1.5 -2\n3 4 5\n6 7 8\n", True),
        ("0 1.5 -2\r\n3 4 5\r\n6 7 8\r\n", True),  # CRLF
        ("\t0 1.5 -2 \n3\t4 5\n6 7 8\n\n  \n", True),  # tabs, blank lines after the rows
        ("0 1.5 -2\n\n3 4 5\n6 7 8\n", False),  # a blank line between rows
        ("0 1.5 -2\r3 4 5\r6 7 8\r", False),  # CR alone
        ("0 1.5 -2\n3 4 5\n6 7 8\n9 9 9\n", False),  # a row beyond the header's count
        ("0 1.5e0 -2\n3 4 5\n6 7 8\n", False),  # an exponent
    ],
)
def test_whole_block_route_agrees_with_the_line_route(rows, clean):
    """The block route (the header split into lines, the rows read as one string)
    reads the well-formed files and gives the line-by-line parse's document; the others
    it leaves to the line route, which warns and names lines."""
    import warnings

    from snapcore.motion import bvh

    text = HEAD + rows
    fast = bvh._parse_clean(text, None)
    assert (fast is not None) == clean
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        doc = parse_bvh(text)  # whichever route
    ref = np.array([[0.0, 1.5, -2.0], [3.0, 4.0, 5.0], [6.0, 7.0, 8.0]])
    assert np.array_equal(_bits(doc.motion), _bits(ref))
    if fast is not None:
        assert fast.names == doc.names and fast.channels == doc.channels
        assert fast.frame_time == doc.frame_time
        assert np.array_equal(fast.offsets, doc.offsets)
