"""The index of a batch: one CSV row per scene (``OUT/index.csv``), and atomic writes.

The columns, their types and meaning are in ``data_schema/batch_index.schema.json``
(one row as a JSON object); :data:`COLUMNS` is their order in the file. Every row is
validated against the schema before it is written, and a file read back is parsed to
the schema's types (empty cell = null). List columns (:data:`LIST_COLUMNS`: frame
numbers, warnings) are lists in a row and in the Parquet file, and one cell joined by
their separator in the CSV.

Every file of a batch is written under a temporary name in the same folder and then
renamed over the real one (:func:`atomic_write`): a run killed at any moment leaves
either the old file or the new one, never half a file.
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

__all__ = [
    "COLUMNS",
    "LIST_COLUMNS",
    "TIMING_COLUMNS",
    "INDEX_NAME",
    "PARQUET_NAME",
    "atomic_write",
    "write_index",
    "read_index",
    "write_parquet",
    "read_parquet",
    "validate_row",
]

INDEX_NAME = "index.csv"
#: The same index as Parquet (same columns, order and types; null for an empty cell).
PARQUET_NAME = "index.parquet"
#: Column order in the CSV (the schema's properties, in a reading order).
COLUMNS = (
    "path",
    "folder",
    "name",
    "kind",
    "status",
    "error",
    "warnings",
    "content_hash",
    "options_hash",
    "characters",
    "rig",
    "n_frames",
    "fps",
    "duration_s",
    "frame",
    "time_s",
    "first_frame",
    "top_frames",
    "score",
    "thumb_frame",
    "thumb_choice",
    "view_x",
    "view_y",
    "view_z",
    "json",
    "thumb",
    "sheet",
    "preview",
    "preview_frames",
    "t_load_s",
    "t_select_s",
    "t_render_s",
    "t_total_s",
)
#: Columns that differ between two runs of the same batch (wall-clock seconds).
TIMING_COLUMNS = ("t_load_s", "t_select_s", "t_render_s", "t_total_s")
_INT = ("characters", "n_frames", "frame", "first_frame", "thumb_frame", "thumb_choice")
#: List columns and their separator in a CSV cell (a warning is one line, and never
#: holds " | " itself in practice; frame numbers are digits).
LIST_COLUMNS = {"top_frames": ";", "preview_frames": ";", "warnings": " | "}
_INT_LISTS = ("top_frames", "preview_frames")
_FLOAT = ("fps", "duration_s", "time_s", "score", "view_x", "view_y", "view_z", *TIMING_COLUMNS)
#: Text columns that are never null: an empty cell is the empty string (a top folder).
_TEXT = ("path", "folder", "name", "kind", "status", "content_hash", "options_hash")


def atomic_write(path, data: bytes | str) -> None:
    """Write ``data`` to ``path`` through a temporary file in the same folder, then
    rename it over ``path`` (atomic on POSIX: readers see the old or the new file).

    The temporary name starts with a dot, so a library walk never takes it for a scene.
    """
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        with open(tmp, "wb") as fh:
            fh.write(data.encode("utf-8") if isinstance(data, str) else data)
        os.replace(tmp, path)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise


def validate_row(row: dict) -> None:
    """Raise :class:`~snapcore.errors.SchemaError` unless ``row`` follows the schema."""
    from snapcore.schema import validate

    validate(row, "batch_index", source=f"index row {row.get('path')}")


def _cell(value, column: str = "") -> str:
    if value is None:
        return ""
    if isinstance(value, (list, tuple)):
        return LIST_COLUMNS[column].join(str(v) for v in value) if value else ""
    if isinstance(value, float):
        return repr(round(value, 6)) if value == value else ""
    return str(value)


def write_index(path, rows) -> None:
    """Write ``rows`` (dicts, every key in :data:`COLUMNS`; missing = null) as CSV,
    sorted by path, atomically."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(COLUMNS)
    for row in sorted(rows, key=lambda r: r["path"]):
        w.writerow([_cell(row.get(c), c) for c in COLUMNS])
    atomic_write(path, buf.getvalue())


def _parse(column: str, text: str):
    if text == "":
        return "" if column in _TEXT else None
    if column in LIST_COLUMNS:
        parts = text.split(LIST_COLUMNS[column])
        return [int(p) for p in parts] if column in _INT_LISTS else parts
    if column in _INT:
        return int(text)
    if column in _FLOAT:
        return float(text)
    return text


def read_index(path) -> list[dict]:
    """The rows of an index written by :func:`write_index`, typed as in the schema.

    Raises
    ------
    SchemaError
        The file is not such an index (other columns, a value of the wrong type).
    """
    from snapcore.errors import SchemaError

    with open(path, encoding="utf-8", newline="") as fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if header is None or tuple(header) != COLUMNS:
            raise SchemaError(
                f"{path}: not a batch index (its columns are not {', '.join(COLUMNS[:3])}, ...)"
            )
        rows = []
        for n, cells in enumerate(reader, start=2):
            if len(cells) != len(COLUMNS):
                raise SchemaError(f"{path}:{n}: {len(cells)} cells, expected {len(COLUMNS)}")
            try:
                rows.append({c: _parse(c, v) for c, v in zip(COLUMNS, cells)})
            except ValueError as err:
                raise SchemaError(f"{path}:{n}: {err}") from None
    return rows


def _arrow_schema():
    import pyarrow as pa

    def kind(c):
        if c in LIST_COLUMNS:
            return pa.list_(pa.int64() if c in _INT_LISTS else pa.string())
        return pa.int64() if c in _INT else pa.float64() if c in _FLOAT else pa.string()

    return pa.schema([pa.field(c, kind(c), nullable=c not in _TEXT) for c in COLUMNS])


def write_parquet(path, rows) -> None:
    """Write ``rows`` as :func:`write_index` does, as a Parquet file (for pandas, Polars,
    DuckDB: typed columns, no parsing), sorted by path, atomically.

    The columns, their order and their types are the schema's (integer columns int64,
    number columns float64, frame lists lists of int64, warnings lists of strings, the
    rest strings); a null is a null."""
    import pyarrow as pa
    import pyarrow.parquet as pq

    def value(row, c):  # the CSV's values: floats to 6 decimals, NaN as null
        v = row.get(c)
        if isinstance(v, float):
            return round(v, 6) if v == v else None
        return v

    rows = sorted(rows, key=lambda r: r["path"])
    table = pa.Table.from_pydict(
        {c: [value(r, c) for r in rows] for c in COLUMNS}, schema=_arrow_schema()
    )
    buf = pa.BufferOutputStream()
    pq.write_table(table, buf)
    atomic_write(path, buf.getvalue().to_pybytes())


def read_parquet(path) -> list[dict]:
    """The rows of an index written by :func:`write_parquet` (as :func:`read_index`
    gives them)."""
    import pyarrow.parquet as pq

    return pq.read_table(path).to_pylist()
