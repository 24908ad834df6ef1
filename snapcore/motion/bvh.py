"""BVH motion-capture files: a strict, fast reader and an exact writer.

The reader parses the hierarchy token by token (it is small) and the motion block in one
vectorised pass (it is large), so a 2,000-frame, 43-joint file reads in a few
milliseconds. Malformed input raises :class:`~snapcore.errors.BVHError` naming the file,
the 1-based line and what was expected there.

What real files do that the reader handles (see ``../shared/motions/README.md``):

- channel orders that differ per joint (``ZYX`` at the root, ``ZXY`` elsewhere);
- 6-channel non-root joints whose position channels *replace* the offset;
- ``End Site`` blocks, kept as joints without channels (they carry limb lengths);
- CRLF or LF line ends, tabs or spaces, blank lines;
- more data rows than the header's ``Frames:`` count (the extra rows are ignored with a
  warning: the header is the file's own statement of its length).

End sites are named ``<parent>_End`` (``_End2``... for several), so a read-write-read
round-trip reproduces names, offsets, channels, frame time and every value exactly
(values are written with Python's shortest round-tripping ``repr``).
"""

from __future__ import annotations

import os
import re
import warnings
from dataclasses import dataclass
from pathlib import Path
from typing import NoReturn

import numpy as np

from snapcore.errors import BVHError

__all__ = [
    "BVHDocument",
    "read_bvh",
    "parse_bvh",
    "write_bvh",
    "format_bvh",
    "split_roots",
    "CHANNEL_NAMES",
]

#: Channel names the format defines; anything else is an error.
CHANNEL_NAMES = ("Xposition", "Yposition", "Zposition", "Xrotation", "Yrotation", "Zrotation")
#: Channel names in any case → as the format writes them.
_CHANNEL_CASE = {c.lower(): c for c in CHANNEL_NAMES}


@dataclass(frozen=True, eq=False)
class BVHDocument:
    """The content of one BVH file, in the file's own units.

    Attributes
    ----------
    names : tuple of str, length J
        Joint names in file order; end sites included (named ``<parent>_End``).
    parents : ndarray of int, shape (J,)
        Index of each joint's parent, ``-1`` for a root. Parents precede children.
    offsets : ndarray of float, shape (J, 3)
        Rest offsets from the parent, file units.
    channels : tuple of tuple of str, length J
        Channel names per joint in file order; ``()`` for end sites.
    end_site : ndarray of bool, shape (J,)
        True for ``End Site`` entries.
    frame_time : float
        Seconds per frame, as written in the file.
    motion : ndarray of float, shape (F, C)
        One row per frame, ``C`` = total number of channels, in channel order.
    path : str or None
        Where the document was read from, for messages.
    """

    names: tuple[str, ...]
    parents: np.ndarray
    offsets: np.ndarray
    channels: tuple[tuple[str, ...], ...]
    end_site: np.ndarray
    frame_time: float
    motion: np.ndarray
    path: str | None = None

    @property
    def n_frames(self) -> int:
        return int(self.motion.shape[0])

    @property
    def n_channels(self) -> int:
        return int(sum(len(c) for c in self.channels))

    @property
    def fps(self) -> float:
        return 1.0 / self.frame_time

    def channel_start(self) -> np.ndarray:
        """Column of each joint's first channel in :attr:`motion`, shape (J,)."""
        counts = np.array([len(c) for c in self.channels], dtype=int)
        return np.concatenate(([0], np.cumsum(counts)[:-1])).astype(int)


# --------------------------------------------------------------------------- reading


def read_bvh(path: str | os.PathLike) -> BVHDocument:
    """Read a BVH file.

    Parameters
    ----------
    path : str or path-like
        The file.

    Returns
    -------
    BVHDocument

    Raises
    ------
    BVHError
        If the file is missing, not text, or malformed; the message names the line.
    """
    p = str(path)
    try:
        raw = Path(p).read_bytes()
    except FileNotFoundError as err:
        raise BVHError("no such file", path=p) from err
    except IsADirectoryError as err:
        raise BVHError("is a directory, expected a .bvh file", path=p) from err
    except OSError as err:
        raise BVHError(f"cannot read file ({err.strerror})", path=p) from err
    try:
        text = raw.decode("utf-8")
    except UnicodeDecodeError:
        try:
            text = raw.decode("latin-1")
        except UnicodeDecodeError as err:  # pragma: no cover - latin-1 decodes any byte
            raise BVHError("not a text file", path=p) from err
    if "\x00" in text:
        raise BVHError("not a text file (contains NUL bytes)", path=p)
    return parse_bvh(text, path=p)


class _Tokens:
    """Header tokens with their 1-based line numbers."""

    def __init__(self, lines: list[str], path: str | None):
        self.items: list[tuple[str, int]] = []
        for n, line in enumerate(lines, start=1):
            for tok in line.split():
                # "{" glued to a name ("Hips{") is legal in some exporters.
                if len(tok) > 1 and tok.endswith("{"):
                    self.items.append((tok[:-1], n))
                    self.items.append(("{", n))
                else:
                    self.items.append((tok, n))
        self.i = 0
        self.path = path
        self.last_line = len(lines)

    def peek(self) -> str | None:
        return self.items[self.i][0] if self.i < len(self.items) else None

    def line(self) -> int:
        return self.items[self.i][1] if self.i < len(self.items) else self.last_line

    def next(self, expected: str) -> tuple[str, int]:
        if self.i >= len(self.items):
            raise BVHError(
                f"unexpected end of file in HIERARCHY: expected {expected}",
                path=self.path,
                line=self.last_line,
            )
        tok = self.items[self.i]
        self.i += 1
        return tok

    def expect(self, word: str) -> int:
        """Consume the keyword ``word`` (in any case: some exporters write ``joint``)."""
        tok, line = self.next(f"'{word}'")
        if tok.lower() != word.lower():
            raise BVHError(f"expected '{word}', found '{tok}'", path=self.path, line=line)
        return line

    def number(self, what: str) -> float:
        tok, line = self.next(what)
        try:
            value = float(tok)
        except ValueError:
            raise BVHError(f"expected {what}, found '{tok}'", path=self.path, line=line) from None
        if not np.isfinite(value):
            raise BVHError(f"{what} is not finite ('{tok}')", path=self.path, line=line)
        return value


def _xyz(tk: _Tokens, what: str) -> tuple[float, float, float]:
    """The three numbers of an OFFSET line; ``what`` names its joint in errors."""
    x, y, z = (tk.number(f"OFFSET {ax} {what}") for ax in "xyz")
    return x, y, z


def _parse_hierarchy(lines: list[str], path: str | None):
    tk = _Tokens(lines, path)
    first = tk.peek()
    if first is None:
        raise BVHError("file is empty; expected 'HIERARCHY'", path=path, line=1)
    tk.expect("HIERARCHY")
    names: list[str] = []
    parents: list[int] = []
    offsets: list[tuple[float, float, float]] = []
    channels: list[tuple[str, ...]] = []
    end_site: list[bool] = []
    name_line: dict[str, int] = {}

    def joint(parent: int) -> None:
        name, line = tk.next("a joint name")
        if name in ("{", "}") or name.upper() in ("OFFSET", "CHANNELS"):
            raise BVHError(f"expected a joint name, found '{name}'", path=path, line=line)
        while tk.peek() not in (None, "{") and tk.line() == line:
            name += " " + tk.next("")[0]  # 3ds Max: "JOINT Bip01 L Thigh"
        if name in name_line:
            raise BVHError(
                f"duplicate joint name '{name}' (first defined on line {name_line[name]})",
                path=path,
                line=line,
            )
        name_line[name] = line
        index = len(names)
        names.append(name)
        parents.append(parent)
        end_site.append(False)
        tk.expect("{")
        tk.expect("OFFSET")
        offsets.append(_xyz(tk, f"of joint '{name}'"))
        tk.expect("CHANNELS")
        n_tok, n_line = tk.next("the channel count")
        try:
            n = int(n_tok)
        except ValueError:
            raise BVHError(
                f"expected the channel count of joint '{name}', found '{n_tok}'",
                path=path,
                line=n_line,
            ) from None
        if not 0 <= n <= 6:
            raise BVHError(
                f"joint '{name}' declares {n} channels; expected 0 to 6", path=path, line=n_line
            )
        chans = []
        for _ in range(n):
            c, c_line = tk.next(f"{n} channel names for joint '{name}'")
            c = _CHANNEL_CASE.get(c.lower(), c)  # XROTATION, xrotation
            if c not in CHANNEL_NAMES:
                hint = (
                    " (the CHANNELS count may be too large)" if c in ("JOINT", "End", "}") else ""
                )
                raise BVHError(
                    f"unknown channel '{c}' for joint '{name}'; expected one of "
                    f"{', '.join(CHANNEL_NAMES)}{hint}",
                    path=path,
                    line=c_line,
                )
            if c in chans:
                raise BVHError(f"channel '{c}' repeated in joint '{name}'", path=path, line=c_line)
            chans.append(c)
        channels.append(tuple(chans))
        n_end = 0
        while True:
            tok, line = tk.next(f"'JOINT', 'End Site' or '}}' closing joint '{name}'")
            if tok == "}":
                return
            if tok.upper() == "JOINT":
                joint(index)
            elif tok.lower() == "end":
                tk.expect("Site")
                tk.expect("{")
                tk.expect("OFFSET")
                off = _xyz(tk, f"of the end site of '{name}'")
                tk.expect("}")
                n_end += 1
                end_name = f"{name}_End" if n_end == 1 else f"{name}_End{n_end}"
                names.append(end_name)
                parents.append(index)
                offsets.append(off)
                channels.append(())
                end_site.append(True)
            elif tok.lower() in _CHANNEL_CASE or tok.upper() == "CHANNELS":
                raise BVHError(
                    f"extra channel '{tok}' in joint '{name}': the CHANNELS count is too small",
                    path=path,
                    line=line,
                )
            else:
                raise BVHError(
                    f"expected 'JOINT', 'End Site' or '}}' in joint '{name}', found '{tok}'",
                    path=path,
                    line=line,
                )

    tok, line = tk.next("'ROOT'")
    if tok.upper() != "ROOT":
        raise BVHError(f"expected 'ROOT', found '{tok}'", path=path, line=line)
    joint(-1)
    while (tk.peek() or "").upper() == "ROOT":
        tk.next("'ROOT'")
        joint(-1)
    if tk.peek() is not None:
        tok, line = tk.next("end of hierarchy")
        raise BVHError(
            f"expected 'MOTION' after the hierarchy, found '{tok}'", path=path, line=line
        )
    return names, parents, offsets, channels, end_site


def _header_value(lines, i, key, path) -> tuple[str, int]:
    """Return the value after ``key`` on the first non-blank line at or after ``i``."""
    while i < len(lines) and not lines[i].strip():
        i += 1
    if i >= len(lines):
        raise BVHError(f"unexpected end of file: expected '{key}'", path=path, line=len(lines))
    line = lines[i].strip()
    if not line.lower().startswith(key.lower()):  # "Frame time:" too
        raise BVHError(f"expected '{key}', found '{line[:40]}'", path=path, line=i + 1)
    return line[len(key) :].strip(), i


def _header_number(lines, start: int, label: str, cast, what: str, path):
    """``(number, text, line index)`` of the header line ``label`` at or after ``start``."""
    value, i = _header_value(lines, start, label, path)
    try:
        return cast(value), value, i
    except ValueError:
        raise BVHError(
            f"expected {what} after '{label}', found '{value}'", path=path, line=i + 1
        ) from None


def parse_bvh(text: str, *, path: str | None = None) -> BVHDocument:
    """Parse BVH text. See :func:`read_bvh`; ``path`` is only used in messages."""
    text = text.removeprefix("\ufeff")  # a UTF-8 byte order mark (Windows tools)
    doc = _parse_clean(text, path)
    if doc is not None:
        return doc
    lines = text.splitlines()
    m = next((i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    if m is None:
        # Parse the hierarchy first so a truncated one is reported as such.
        _parse_hierarchy(lines, path)
        raise BVHError("no 'MOTION' section after the hierarchy", path=path, line=len(lines))
    names, parents, offsets, channels, end_site = _parse_hierarchy(lines[:m], path)

    n_frames, value, i = _header_number(
        lines, m + 1, "Frames:", int, "an integer frame count", path
    )
    if n_frames <= 0:
        raise BVHError(
            f"the motion has {n_frames} frames; expected at least 1", path=path, line=i + 1
        )
    frame_time, value, i = _header_number(lines, i + 1, "Frame Time:", float, "a number", path)
    if not np.isfinite(frame_time) or frame_time <= 0:
        raise BVHError(
            f"frame time must be a positive number of seconds, found {value}", path=path, line=i + 1
        )

    n_chan = sum(len(c) for c in channels)
    motion = _parse_motion_block(lines, i + 1, n_frames, n_chan, path)
    return _document((names, parents, offsets, channels, end_site), frame_time, motion, path)


def _document(hierarchy, frame_time: float, motion: np.ndarray, path) -> BVHDocument:
    """The document of a parsed ``hierarchy`` (what :func:`_parse_hierarchy` returns)
    and its motion."""
    names, parents, offsets, channels, end_site = hierarchy
    return BVHDocument(
        names=tuple(names),
        parents=np.asarray(parents, dtype=int),
        offsets=np.asarray(offsets, dtype=float).reshape(-1, 3),
        channels=tuple(channels),
        end_site=np.asarray(end_site, dtype=bool),
        frame_time=frame_time,
        motion=motion,
        path=path,
    )


#: The end of the header's last line, where the motion rows start.
_FRAME_TIME_LINE = re.compile(r"^[ \t]*frame time:[^\n]*\n", re.IGNORECASE | re.MULTILINE)


def _parse_clean(text: str, path: str | None) -> BVHDocument | None:
    """The document of a well-formed file, or None for the full parse to read.

    Well-formed: its header parses, and right after the ``Frame Time`` line come the
    header's number of rows of plain decimals (:func:`_decimal_block`), nothing else but
    trailing whitespace. Only the header is split into lines (the same lines, and the
    same header functions, as the full parse: the text is cut just after a line end);
    the rows go to the decimal reader as one string. A file that is not so (extra or
    blank rows, exponents, errors) is read again by the full parse, which warns and
    names the line: this route only saves the splitting, stripping and joining of the
    data lines (a tenth of the reading time).
    """
    hit = _FRAME_TIME_LINE.search(text)
    if hit is None:
        return None
    lines = text[: hit.end()].splitlines()
    m = next((i for i, line in enumerate(lines) if line.strip().upper() == "MOTION"), None)
    if m is None:
        return None
    try:
        hierarchy = _parse_hierarchy(lines[:m], path)
        n_frames, _, i = _header_number(lines, m + 1, "Frames:", int, "", path)
        frame_time, _, j = _header_number(lines, i + 1, "Frame Time:", float, "", path)
    except BVHError:
        return None
    n_chan = sum(len(c) for c in hierarchy[3])
    if j != len(lines) - 1 or n_frames <= 0 or n_chan == 0:
        return None
    if not (np.isfinite(frame_time) and frame_time > 0):
        return None
    motion = _decimal_block(text[hit.end() :], n_frames, n_chan)
    if motion is None:
        return None
    return _document(hierarchy, frame_time, motion, path)


def _parse_motion_block(lines, start, n_frames, n_chan, path) -> np.ndarray:
    """Parse data rows ``lines[start:]`` into an (n_frames, n_chan) array.

    The fast path reads rows of plain decimals (:func:`_plain_decimals`, what exporters
    write); other rows (exponents, ``nan``) go through ``np.loadtxt`` (NumPy's C parser).
    Only when that fails does a line-by-line pass find the first bad line for the message.
    """
    body = lines[start:]
    rows = [k for k, line in enumerate(body) if line.strip()]
    n_rows = len(rows)
    if n_rows < n_frames:
        last = start + (rows[-1] + 1 if rows else 0)
        raise BVHError(
            f"expected {n_frames} frames of motion data, found {n_rows} (file truncated?)",
            path=path,
            line=max(last, start),
        )
    if n_rows > n_frames:
        warnings.warn(
            f"{path or '<bvh>'}:{start + rows[n_frames] + 1}: {n_rows - n_frames} data "
            f"row(s) beyond the header's 'Frames: {n_frames}' ignored",
            stacklevel=3,
        )
    data = [body[k] for k in rows[:n_frames]]
    if n_chan == 0:
        return np.zeros((n_frames, 0))
    motion = _plain_decimals(data, n_chan)
    if motion is None:  # not all plain decimals: NumPy's parser, and its errors
        try:
            motion = np.loadtxt(data, dtype=float, ndmin=2, comments=None)
        except ValueError:
            motion = np.empty((0, 0))  # not the declared shape: the slow path finds the row
    if motion.shape != (n_frames, n_chan):
        _raise_bad_row(data, rows, start, n_chan, path)
    finite = np.isfinite(motion)
    if not finite.all():
        f, c = np.argwhere(~finite)[0]
        raise BVHError(
            f"frame {int(f)}, channel {int(c)} is not a finite number ({float(motion[f, c])})",
            path=path,
            line=start + rows[f] + 1,
        )
    return motion


#: 10**k as the exact float and the exact integer, k = 0..8 digits.
_POW10 = 10.0 ** np.arange(9)
_POW10_INT = 10 ** np.arange(9, dtype=np.uint64)
#: Masks keeping the top k bytes of a little-endian word (the last k characters), k = 0..8.
_KEEP = np.array([(2**64 - 1) << (8 * (8 - k)) & (2**64 - 1) for k in range(9)], np.uint64)
_U = np.uint64


def _eight_digits(w: np.ndarray) -> np.ndarray:
    """The integers whose 8 decimal digits are the bytes of ``w`` (uint64, digit values
    0-9, first character in the lowest byte): pairs, then quads, then the eight merged
    in place (the SWAR digit parse of simdjson), exact."""
    w = w * _U(10) + (w >> _U(8))
    w &= _U(0x00FF00FF00FF00FF)
    w = w * _U(100) + (w >> _U(16))
    w &= _U(0x0000FFFF0000FFFF)
    w = w * _U(10000) + (w >> _U(32))
    return w & _U(0xFFFFFFFF)


def _plain_decimals(data: list[str], n_chan: int) -> np.ndarray | None:
    """Rows of plain decimals (``-12.345678``) as an (F, n_chan) array, or None
    (see :func:`_decimal_block`)."""
    return _decimal_block("\n".join(data), len(data), n_chan)


def _decimal_block(block: str, n_rows: int, n_chan: int) -> np.ndarray | None:
    """``n_rows`` rows of plain decimals, one a line (LF or CRLF line ends; whitespace
    after the last row allowed), as an (n_rows, n_chan) array, or None.

    None when any value is not ``[+-]digits[.digits]`` (an integer, or one dot), with
    at least one digit and at most 8 on either side of the dot, or a row has other than ``n_chan`` values, or
    a row holds a byte other than these, spaces and tabs: the caller then uses
    ``np.loadtxt``, whose messages and exotic forms (exponents, ``nan``) it keeps.

    Each value is the integer M of its digits divided by 10**k for its k fraction
    digits. With at most 15 digits, M < 10**15 < 2**53: M and 10**k are exact doubles
    and one IEEE division rounds correctly (Clinger's fast path), which is the double a
    correctly rounding parser (Python's ``float``, NumPy's) gives for the text: bit for
    bit the same numbers, ``-0.0`` included.

    The work is on the bytes: token edges from one whitespace mask; each value's
    integer and fraction digits read as two 8-byte words ending at its dot and at its
    end, validated and converted by word arithmetic: about a third of ``np.loadtxt``'s
    time on the salsa files.
    """
    try:
        raw = block.encode("ascii")
    except UnicodeEncodeError:
        return None
    end = len(raw)  # whitespace after the last row is not read (no copy to strip it)
    while end and raw[end - 1] in b" \t\r\n":
        end -= 1
    n_cr = raw.count(b"\r", 0, end) if b"\r" in raw else 0  # `in` is memchr; count is not
    if n_cr and n_cr != raw.count(b"\r\n", 0, end):
        return None  # a lone CR ends a line too: the caller's line split decides
    # 8 spaces on either side: every word read below starts inside the buffer
    a = np.full(end + 16, 32, dtype=np.uint8)
    a[8 : 8 + end] = np.frombuffer(raw, dtype=np.uint8, count=end)
    # the only control bytes: the rows' line ends (a CR only before an LF) and tabs
    # (others are not whitespace to NumPy's parser)
    breaks = np.flatnonzero(a == 10)
    if breaks.size != n_rows - 1 or np.count_nonzero(
        a < 32
    ) != breaks.size + n_cr + np.count_nonzero(a == 9):
        return None
    word = a > 32
    edges = np.flatnonzero(word[1:] != word[:-1])
    edges += 1
    starts, ends = edges[0::2], edges[1::2]
    dots = np.flatnonzero(a == 46)
    n = n_rows * n_chan
    if starts.size != n:
        return None
    # n values and n dots, both in order: one dot in each value iff each k-th dot lies
    # inside the k-th value
    if dots.size != n or not ((dots >= starts).all() and (dots < ends).all()):
        # integers too ("0", "-17"): a value's dot is the first at or after its start,
        # else its end; values holding a dot as many as the dots: none holds two
        first_dot = np.append(dots, a.size)[np.searchsorted(dots, starts)]
        has_dot = first_dot < ends
        if np.count_nonzero(has_dot) != dots.size:
            return None
        dots = np.where(has_dot, first_dot, ends)
    # each row holds n_chan values: the k-th line end falls after value k * n_chan - 1
    if not (np.searchsorted(starts, breaks) == n_chan * np.arange(1, n_rows)).all():
        return None
    first = a[starts]
    neg = first == 45
    n_int = dots - starts - (neg | (first == 43))
    n_frac = np.maximum(ends - dots - 1, 0)
    n_digits = n_int + n_frac
    if n_int.max() > 8 or n_frac.max() > 8 or not 1 <= n_digits.min() <= n_digits.max() <= 15:
        return None
    # the 8 bytes before each dot and before each end, as little-endian words (the
    # last character highest); ASCII digits XOR 0x30 are their values 0-9
    words = np.ndarray((a.size - 7,), dtype=np.uint64, buffer=a, strides=(1,))
    w_int = words[dots - 8] ^ _U(0x3030303030303030)
    w_frac = words[ends - 8] ^ _U(0x3030303030303030)
    w_int &= _KEEP[n_int]
    w_frac &= _KEEP[n_frac]
    # every kept byte a digit: no byte above 9 (adding 6 sets a high nibble from 10 on)
    six = _U(0x0606060606060606)
    high = _U(0xF0F0F0F0F0F0F0F0)
    if ((w_int | (w_int + six) | w_frac | (w_frac + six)) & high).any():
        return None
    m = _eight_digits(w_int)
    m *= _POW10_INT[n_frac]
    m += _eight_digits(w_frac)
    values = m.astype(np.float64)
    values /= _POW10[n_frac]
    np.negative(values, out=values, where=neg)
    return values.reshape(n_rows, n_chan)


def _raise_bad_row(data, rows, start, n_chan, path) -> NoReturn:
    """Slow path, only on error: find the first row that is not n_chan numbers."""
    for r, text in enumerate(data):
        toks = text.split()
        line = start + rows[r] + 1
        if len(toks) != n_chan:
            what = "fewer" if len(toks) < n_chan else "more"
            raise BVHError(
                f"frame {r} has {len(toks)} values, {what} than the {n_chan} channels "
                "the hierarchy declares",
                path=path,
                line=line,
            )
        for c, tok in enumerate(toks):
            try:
                float(tok)
            except ValueError:
                raise BVHError(
                    f"frame {r}, channel {c}: expected a number, found '{tok[:20]}'",
                    path=path,
                    line=line,
                ) from None
    raise BVHError("motion data could not be parsed as numbers", path=path, line=start + 1)


def split_roots(doc: BVHDocument) -> list[BVHDocument]:
    """One document per ``ROOT`` of ``doc`` (a file may hold several people, or props).

    A root's joints, and their channels' columns, are contiguous: the hierarchy is
    written depth-first. A document with one root comes back as ``[doc]``.
    """
    roots = np.flatnonzero(doc.parents < 0)
    if roots.size <= 1:
        return [doc]
    starts = doc.channel_start()
    counts = np.array([len(c) for c in doc.channels])
    out = []
    for a, b in zip(roots, [*roots[1:], len(doc.names)]):
        cols = slice(int(starts[a]), int(starts[b - 1] + counts[b - 1]))
        out.append(
            BVHDocument(
                names=doc.names[a:b],
                parents=np.where(doc.parents[a:b] < 0, -1, doc.parents[a:b] - a),
                offsets=doc.offsets[a:b],
                channels=doc.channels[a:b],
                end_site=doc.end_site[a:b],
                frame_time=doc.frame_time,
                motion=doc.motion[:, cols],
                path=doc.path,
            )
        )
    return out


# --------------------------------------------------------------------------- writing


def format_bvh(doc: BVHDocument) -> str:
    """The BVH text of ``doc`` (LF line ends, tab indents, exact ``repr`` values)."""
    children: dict[int, list[int]] = {}
    for j, p in enumerate(doc.parents):
        children.setdefault(int(p), []).append(j)
    out = ["HIERARCHY"]

    def fmt(v) -> str:
        return " ".join(repr(float(x)) for x in v)

    def emit(j: int, depth: int) -> None:
        ind = "\t" * depth
        if doc.end_site[j]:
            out.append(f"{ind}End Site")
            out.append(f"{ind}{{")
            out.append(f"{ind}\tOFFSET {fmt(doc.offsets[j])}")
            out.append(f"{ind}}}")
            return
        kw = "ROOT" if doc.parents[j] < 0 else "JOINT"
        out.append(f"{ind}{kw} {doc.names[j]}")
        out.append(f"{ind}{{")
        out.append(f"{ind}\tOFFSET {fmt(doc.offsets[j])}")
        out.append(f"{ind}\tCHANNELS {len(doc.channels[j])} {' '.join(doc.channels[j])}".rstrip())
        for c in children.get(j, []):
            emit(c, depth + 1)
        out.append(f"{ind}}}")

    for root in children.get(-1, []):
        emit(root, 0)
    out.append("MOTION")
    out.append(f"Frames: {doc.n_frames}")
    out.append(f"Frame Time: {doc.frame_time!r}")
    rows = doc.motion.tolist()
    out.extend(" ".join(map(repr, row)) for row in rows)
    return "\n".join(out) + "\n"


def write_bvh(doc: BVHDocument, path: str | os.PathLike) -> None:
    """Write ``doc`` to ``path`` (see :func:`format_bvh`)."""
    Path(path).write_text(format_bvh(doc), encoding="utf-8")
