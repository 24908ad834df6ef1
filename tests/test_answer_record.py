"""The answer record (study_app.data.answer) and the response schema say the same thing.

The schema (``data_schema/response.schema.json``) is the contract of every stored and
exported answer; the TypedDicts are what the code's type checker sees. If a field is
added to one and not the other, or a type or a choice drifts, these tests fail.
"""

from __future__ import annotations

import types
import typing

import pytest

from snapcore.schema import load_schema
from snapcore.select.view_methods import VIEW_METHODS
from study_app.data.answer import Answer, ClientFields, ResponseRow
from study_app.data.errors import StoreError
from study_app.data.rows import TRIAL_FIELDS, checked_response

SCHEMA = load_schema("response")
# JSON type -> the Python types that stand for it in a TypedDict
JSON_TYPES = {"integer": {int}, "number": {float}, "boolean": {bool}, "string": {str}}


def _python_types(hint) -> tuple[set, set, bool]:
    """(plain types, literal values, None allowed) of a field's annotation."""
    hint = typing.get_origin(hint) is typing.Required and typing.get_args(hint)[0] or hint
    union = typing.get_origin(hint) in (typing.Union, types.UnionType)
    members = typing.get_args(hint) if union else (hint,)
    plain, literals, nullable = set(), set(), False
    for m in members:
        if m is type(None):
            nullable = True
        elif typing.get_origin(m) is typing.Literal:
            literals |= set(typing.get_args(m))
        else:
            plain.add(typing.get_origin(m) or m)
    return plain, literals, nullable


def test_response_row_has_the_schema_fields_and_required_keys():
    assert set(ResponseRow.__annotations__) == set(SCHEMA["properties"])
    assert ResponseRow.__required_keys__ == set(SCHEMA["required"])


@pytest.mark.parametrize("field", sorted(SCHEMA["properties"]))
def test_field_types_and_choices_follow_the_schema(field):
    spec = SCHEMA["properties"][field]
    hints = typing.get_type_hints(ResponseRow, include_extras=True)
    plain, literals, nullable = _python_types(hints[field])
    kinds = spec.get("type", "string")
    kinds = kinds if isinstance(kinds, list) else [kinds]
    assert nullable == ("null" in kinds or None in spec.get("enum", ())), field
    if field == "chosen_method":
        # a str whose vocabulary is the view methods' own (the store checks the enum)
        assert plain == {str} and set(VIEW_METHODS) == set(spec["enum"]) - {None}
    elif "enum" in spec:
        assert literals == {v for v in spec["enum"] if v is not None}, field
    elif "array" in kinds:
        assert plain == {list}, field
    else:
        expected = set().union(*(JSON_TYPES[k] for k in kinds if k != "null"))
        assert plain == expected, field


def test_the_store_takes_exactly_the_answer_fields():
    """What the session may hand the store is the Answer's keys: one more is refused."""
    assert set(TRIAL_FIELDS) == set(Answer.__annotations__)
    row = {"trial_index": 0, "task": "view", "scene": "s", "stimulus_id": "s/view"}
    row["response_time_s"] = 3.0
    assert set(checked_response(row)) == set(Answer.__annotations__)
    with pytest.raises(StoreError, match="unknown field"):
        checked_response({**row, "participant_id": "x"})


def test_client_fields_are_answer_fields_of_the_same_types():
    answer = typing.get_type_hints(Answer)
    for name, hint in typing.get_type_hints(ClientFields).items():
        assert answer[name] == hint, name
