"""Export files of the study: CSV and JSON lines, written atomically and read back typed.

No SQL here (that is :mod:`study_app.data.store`): these functions turn the store's export
rows into files and files back into rows. Rows follow ``data_schema/response.schema.json``;
in CSV, ``shown_order`` is a JSON array string (``["ours", "motion_area",
"viewpoint_entropy"]``), booleans are ``true``/``false`` and ``None`` is an empty cell.
:func:`read_export` reads either format back into typed rows.

This is the one codec of export rows: the study writes with it and the analysis
(:mod:`analysis.load`) reads with it; both take each column's type from the schema
(:func:`export_types`), never from a hand-written list.
"""

from __future__ import annotations

import csv
import io
import json
import os
import secrets
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any, Literal, overload

from snapcore.errors import SchemaError
from snapcore.schema import load_schema, quick_check, validate

from .answer import ResponseRow
from .errors import StoreError

__all__ = [
    "export_columns",
    "export_types",
    "validate_rows",
    "write_export",
    "read_export",
    "export_format",
    "participants_columns",
    "write_participants",
    "events_columns",
    "write_events",
    "EXPORT_FORMATS",
    "BACKGROUND_FIELDS",
]

EXPORT_FORMATS = {".csv": "csv", ".jsonl": "jsonl", ".ndjson": "jsonl", ".json": "jsonl"}
BACKGROUND_FIELDS = ("age_band", "gender", "experience")


def _background_value(value: object) -> str | None:
    if value is None or isinstance(value, str):
        return value
    if isinstance(value, list):
        return "; ".join(value)
    return json.dumps(value)


# ----------------------------------------------------------------------------- files
def export_columns() -> list[str]:
    """Export columns, in ``response.schema.json`` order."""
    return list(load_schema("response")["properties"])


def export_types() -> dict[str, str]:
    """Export column → its JSON type in ``response.schema.json`` (``"integer"``,
    ``"number"``, ``"boolean"``, ``"array"`` or ``"string"``; ``"null"`` left out)."""
    out = {}
    for name, spec in load_schema("response")["properties"].items():
        types = spec.get("type", "string")
        types = [t for t in (types if isinstance(types, list) else [types]) if t != "null"]
        out[name] = types[0] if types else "string"
    return out


def participants_columns() -> list[str]:
    """Columns of the participants export (:func:`write_participants`), in
    ``participant.schema.json`` order."""
    return list(load_schema("participant")["properties"])


def validate_rows(rows: Iterable[Mapping[str, Any]], *, source: str = "export") -> None:
    """Check every row against ``response.schema.json``.

    Raises
    ------
    SchemaError
        Naming the row (1-based), its participant and trial, and the field.
    """
    quick = quick_check("response")  # thousands of rows: the compiled check first
    for i, row in enumerate(rows, start=1):
        if quick is not None and quick(row):
            continue
        where = (
            f"{source}: row {i} (participant {row.get('participant_id')!r}, "
            f"trial {row.get('trial_index')!r})"
        )
        validate(row, "response", source=where)


def export_format(path: str | os.PathLike[str], fmt: str | None = None) -> str:
    """``"csv"`` or ``"jsonl"``: ``fmt`` if given, else from the file suffix."""
    if fmt is not None:
        if fmt not in ("csv", "jsonl"):
            raise StoreError(f"unknown export format {fmt!r} (expected csv or jsonl)")
        return fmt
    suffix = Path(str(path)).suffix.lower()
    if suffix not in EXPORT_FORMATS:
        raise StoreError(
            f"{path}: cannot tell the format from the suffix "
            f"(use {', '.join(EXPORT_FORMATS)} or --format)"
        )
    return EXPORT_FORMATS[suffix]


def _csv_cell(value: object) -> str:
    if value is None:
        return ""
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, (list, dict)):
        return json.dumps(value)
    return str(value)


def _render(rows: Iterable[Mapping[str, Any]], columns: Sequence[str], fmt: str) -> str:
    buf = io.StringIO()
    if fmt == "csv":
        writer = csv.writer(buf, lineterminator="\n")
        writer.writerow(columns)
        for row in rows:
            writer.writerow([_csv_cell(row.get(c)) for c in columns])
    else:
        for row in rows:
            buf.write(json.dumps({c: row.get(c) for c in columns}, allow_nan=False) + "\n")
    return buf.getvalue()


def _write_atomic(path: Path, text: str) -> None:
    """Write via a temp file + rename, so a failed export never leaves half a file."""
    path = Path(path)
    tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}.tmp")
    try:
        tmp.write_text(text, encoding="utf-8", newline="")
        os.replace(tmp, path)
    except OSError as err:
        try:
            tmp.unlink(missing_ok=True)
        except OSError:
            pass  # the folder itself is unusable: there is no temp file to remove
        raise StoreError(f"cannot write {path}: {err.strerror or err}") from None


def write_export(
    rows: Sequence[ResponseRow], path: str | os.PathLike[str], *, fmt: str | None = None
) -> int:
    """Validate ``rows`` and write them to ``path`` (CSV or JSON lines); return the count.

    ``path`` ``"-"`` writes to stdout. Nothing is written if any row is invalid.
    """
    fmt = export_format(path, fmt) if str(path) != "-" else (fmt or "csv")
    validate_rows(rows, source=str(path))
    text = _render(rows, export_columns(), fmt)
    if str(path) == "-":
        import sys

        sys.stdout.write(text)
    else:
        _write_atomic(Path(path), text)
    return len(rows)


def _validate_each(rows: Iterable[Mapping[str, Any]], name: str, source: object) -> None:
    """Check every row against ``<name>.schema.json``, naming the row and participant."""
    for i, row in enumerate(rows, start=1):
        validate(row, name, source=f"{source}: row {i} (participant {row.get('participant_id')!r})")


def write_participants(
    records: Sequence[Mapping[str, Any]],
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    drop: Iterable[str] = (),
) -> int:
    """Validate and write :meth:`Store.participants` records (background flattened) to
    CSV/JSON lines (``data_schema/participant.schema.json``); return the count.

    ``drop``: columns left out of the file (an open export drops ``seed``,
    :data:`study_app.data.pseudonym.OPEN_DROPPED`)."""
    fmt = export_format(path, fmt)
    rows = []
    for rec in records:
        bg = rec.get("background") or {}
        rows.append({**rec, **{k: _background_value(bg.get(k)) for k in BACKGROUND_FIELDS}})
    columns = [c for c in participants_columns() if c not in drop]
    _validate_each([{c: r.get(c) for c in columns} for r in rows], "participant", path)
    _write_atomic(Path(path), _render(rows, columns, fmt))
    return len(rows)


def events_columns() -> list[str]:
    """Columns of the events export (:func:`write_events`), in ``event.schema.json`` order."""
    return list(load_schema("event")["properties"])


def write_events(
    records: Sequence[Mapping[str, Any]], path: str | os.PathLike[str], *, fmt: str = "jsonl"
) -> int:
    """Validate and write :meth:`Store.events` records (``data_schema/event.schema.json``)
    as JSON lines, or as CSV (``fmt="csv"``: the payload cell is its JSON object as a
    string); return the count."""
    records = list(records)
    _validate_each(records, "event", path)
    if fmt == "csv":
        _write_atomic(Path(path), _render(records, events_columns(), "csv"))
    else:
        _write_atomic(Path(path), "".join(json.dumps(e, allow_nan=False) + "\n" for e in records))
    return len(records)


def _typed(name: str, text: str, spec: dict) -> Any:
    """:func:`_typed_cell`, naming the column in the error."""
    try:
        return _typed_cell(name, text, spec)
    except SchemaError:
        raise
    except ValueError as err:  # float("x"), json.loads("[") ...
        raise SchemaError(f"{name}: {err}") from None


def _typed_cell(name: str, text: str, spec: dict) -> Any:
    """One CSV cell back to the type the schema gives ``name``.

    Integers are also read from integer-valued decimals (``"20.0"``, as pandas writes a
    column with gaps) and booleans case-insensitively (``True``, as pandas writes them);
    anything else that is not of the column's type raises :class:`SchemaError`.
    """
    types = spec.get("type", "string")
    types = types if isinstance(types, list) else [types]
    if text == "":
        return None if "null" in types else text
    if "array" in types:
        value = json.loads(text)
        if not isinstance(value, list):
            raise SchemaError(f"{name}: expected a JSON list, got {text!r}")
        return value
    if "object" in types:  # the participants file's background: a JSON object as a string
        value = json.loads(text)
        if not isinstance(value, dict):
            raise SchemaError(f"{name}: expected a JSON object, got {text!r}")
        return value
    if "boolean" in types:
        if text.lower() not in ("true", "false"):
            raise SchemaError(f"{name}: expected true/false, got {text!r}")
        return text.lower() == "true"
    if "integer" in types:
        value = float(text)
        if not value.is_integer():
            raise SchemaError(f"{name}: not an integer: {text!r}")
        return int(value)
    if "number" in types:
        return float(text)
    return text


@overload
def read_export(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    validate: bool = True,
    schema: Literal["response"] = "response",
) -> list[ResponseRow]: ...
@overload
def read_export(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    validate: bool = True,
    schema: Literal["participant"],
) -> list[dict[str, Any]]: ...
def read_export(
    path: str | os.PathLike[str],
    *,
    fmt: str | None = None,
    validate: bool = True,
    schema: str = "response",
) -> list[ResponseRow] | list[dict[str, Any]]:
    """Read a file written by :func:`write_export` back into typed rows (or, with
    ``schema="participant"``, one written by :func:`write_participants`).

    Parameters
    ----------
    path : str or Path
        ``.csv``; ``.jsonl``/``.ndjson``/``.json`` JSON lines (a ``.json`` file holding
        one JSON list of rows is read too).
    fmt : {"csv", "jsonl"}, optional
        The format, if the suffix does not tell it.
    validate : bool
        Check every row against ``response.schema.json`` (:func:`validate_rows`), or
        the ``schema`` named.
    schema : {"response", "participant"}
        The schema giving the columns' types.

    Returns
    -------
    list of ResponseRow, or of dict (``schema="participant"``)
        One dict per row with JSON types (the answer record of
        :mod:`study_app.data.answer`, checked when ``validate``): CSV cells are turned back into the schema's
        types (``shown_order`` parsed from its JSON string, ``true``/``false`` to bool,
        empty cell to None, numbers to int/float).

    Raises
    ------
    StoreError
        The file cannot be read or its format is unknown.
    SchemaError
        A line or cell that cannot be parsed, or (``validate``) a row off the schema;
        the message names the file and the line or row.
    """
    path = Path(path)
    fmt = export_format(path, fmt)
    try:
        text = path.read_text(encoding="utf-8")
    except OSError as err:
        raise StoreError(f"cannot read {path}: {err.strerror or err}") from None
    props = load_schema(schema)["properties"]
    rows = []
    if fmt == "jsonl" and path.suffix.lower() == ".json" and text.lstrip().startswith("["):
        try:
            rows = list(json.loads(text))
        except json.JSONDecodeError as err:
            raise SchemaError(f"{path}:{err.lineno}: not valid JSON ({err.msg})") from None
    elif fmt == "jsonl":
        for lineno, line in enumerate(text.splitlines(), start=1):
            if line.strip():
                try:
                    rows.append(json.loads(line))
                except json.JSONDecodeError as err:
                    raise SchemaError(f"{path}:{lineno}: not valid JSON ({err.msg})") from None
    else:
        for lineno, rec in enumerate(csv.DictReader(io.StringIO(text, newline="")), start=2):
            try:
                rows.append({k: _typed(k, v, props.get(k, {})) for k, v in rec.items()})
            except (ValueError, SchemaError) as err:
                raise SchemaError(f"{path}:{lineno}: {err}") from None
    if validate and schema == "response":
        validate_rows(rows, source=str(path))
    elif validate:
        _validate_each(rows, schema, path)
    return rows
