"""Validation of documents against the JSON Schemas in ``data_schema/``.

``jsonschema`` does the checking (Draft 2020-12); this module only loads schemas once
and turns the first, most relevant error into one line that names the file and the
field, e.g. ``scene.toml: characters[0].offset: [1, 2] is too short``.
"""

from __future__ import annotations

import json
import tomllib
from functools import cache
from pathlib import Path

import jsonschema

from data_schema import schema_path
from snapcore.errors import SchemaError

__all__ = ["load_schema", "validate", "quick_check", "read_document", "field_path"]


@cache
def load_schema(name: str) -> dict:
    """The schema called ``name`` (``"scene"``, ``"snapshot"``, ...) as a dict."""
    path = schema_path(name)
    if not path.exists():
        raise SchemaError(f"no schema named '{name}' ({path})")
    # Not checked against the 2020-12 meta-schema here: that took longer than
    # validating a document (~0.1 s, a tenth of `snapshot select`'s start-up), and the
    # schemas are this package's files, each checked by
    # tests/test_output_schemas.py::test_every_schema_is_valid_draft_2020_12.
    return json.loads(path.read_text(encoding="utf-8"))


@cache
def _validator(name: str) -> jsonschema.Draft202012Validator:
    # One per schema and process: the study server validates every stored answer.
    return jsonschema.Draft202012Validator(load_schema(name))


#: Keywords whose meaning is the same in Draft 7 (what fastjsonschema compiles) and Draft
#: 2020-12 (what jsonschema checks): a schema using only these gets the compiled check.
_SAME_IN_DRAFT7 = frozenset(
    {"$schema", "$id", "title", "description", "type", "properties", "required"}
    | {"additionalProperties", "enum", "const", "minimum", "maximum", "exclusiveMinimum"}
    | {"exclusiveMaximum", "minLength", "maxLength", "pattern", "format", "uniqueItems"}
    | {"minItems", "maxItems", "items", "$ref", "$defs", "oneOf", "anyOf", "allOf", "not"}
    | {"minProperties", "maxProperties", "default", "examples", "$comment"}
)
#: Keywords that only annotate: beside a ``$ref`` they change nothing in either draft
#: (any other keyword beside ``$ref`` is ignored by Draft 7 and applied by 2020-12).
_ANNOTATIONS = frozenset({"description", "title", "$comment", "default", "examples"})


def _keywords(schema) -> set:
    """Every keyword a schema uses, its subschemas descended (``properties``, ``$defs``,
    ``items``, ``additionalProperties``, ``not`` and the ``oneOf``/``anyOf``/``allOf``
    lists), plus ``items-list`` and ``$ref-with-siblings`` for the two forms whose
    meaning changed between Draft 7 and 2020-12."""
    if isinstance(schema, list):
        return set().union(*(_keywords(s) for s in schema)) if schema else set()
    if not isinstance(schema, dict):
        return set()
    out = set(schema)
    if "$ref" in schema and set(schema) - {"$ref"} - _ANNOTATIONS:
        out.add("$ref-with-siblings")
    for key, value in schema.items():
        if key in ("properties", "$defs") and isinstance(value, dict):
            out |= set().union(*(_keywords(s) for s in value.values())) if value else set()
        elif key in ("items", "additionalProperties", "not") and isinstance(value, dict):
            out |= _keywords(value)
        elif key in ("oneOf", "anyOf", "allOf"):
            out |= _keywords(value)
        elif key == "items":  # a list of schemas means something else in 2020-12
            out.add("items-list")
    return out


@cache
def quick_check(name: str):
    """A fast yes/no check of schema ``name`` (fastjsonschema), or None when the schema
    uses a keyword that could mean something else there: ``check(doc)`` is True when
    ``doc`` is valid. Use it before :func:`validate`, which words the error.

    ``format`` is not checked, as :func:`validate` does not check it (jsonschema leaves
    formats to an opt-in checker).
    """
    import fastjsonschema

    schema = load_schema(name)
    if not _keywords(schema) <= _SAME_IN_DRAFT7:
        return None
    compiled = fastjsonschema.compile(
        {k: v for k, v in schema.items() if k != "$schema"},
        formats={f: (lambda _value: True) for f in ("date-time", "date", "uri", "email")},
    )

    def check(doc) -> bool:
        try:
            compiled(doc)
        except fastjsonschema.JsonSchemaException:
            return False
        return True

    return check


def field_path(parts) -> str:
    """``['characters', 0, 'offset']`` → ``characters[0].offset``."""
    out = ""
    for p in parts:
        out += f"[{p}]" if isinstance(p, int) else (f".{p}" if out else str(p))
    return out or "(document)"


#: Documents of one schema :func:`validate` checks with jsonschema alone before it
#: compiles the schema (:func:`quick_check`).
QUICK_AFTER = 3
_seen: dict[str, int] = {}


def validate(instance, name: str, *, source: str = "document") -> None:
    """Raise :class:`SchemaError` if ``instance`` does not follow schema ``name``.

    Parameters
    ----------
    instance : object
        The parsed document.
    name : str
        Schema name, e.g. ``"scene"``.
    source : str
        Where the document came from (a file name), for the message.
    """
    # From the third document of a schema on, the compiled check first: it never accepts
    # what jsonschema refuses (tests/test_schema_quick.py) and takes 0.3 ms where
    # jsonschema takes 10 (a batch's snapshot document), but compiling costs ~50 ms, more
    # than a command that checks one document saves.
    _seen[name] = seen = _seen.get(name, 0) + 1
    quick = quick_check(name) if seen >= QUICK_AFTER else None
    if quick is not None and quick(instance):
        return
    error = jsonschema.exceptions.best_match(_validator(name).iter_errors(instance))
    if error is not None:
        raise SchemaError(f"{source}: {field_path(error.absolute_path)}: {error.message}")


def read_document(path: str | Path, name: str | None = None) -> dict:
    """Read a TOML or JSON file, validating it against schema ``name`` if given."""
    p = Path(path)
    try:
        text = p.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise SchemaError(f"{p}: no such file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise SchemaError(f"{p}: cannot read ({err})") from err
    try:
        if p.suffix.lower() == ".toml":
            doc = tomllib.loads(text)
        else:
            doc = json.loads(text)
    except tomllib.TOMLDecodeError as err:
        raise SchemaError(f"{p}: not valid TOML ({err})") from err
    except json.JSONDecodeError as err:
        raise SchemaError(f"{p}:{err.lineno}: not valid JSON ({err.msg})") from err
    if name is not None:
        validate(doc, name, source=str(p))
    return doc
