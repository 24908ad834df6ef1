"""The compiled schema check (fastjsonschema) that :func:`snapcore.schema.validate` tries
first: it may refuse a valid document (jsonschema then decides), but it must never
accept one that jsonschema refuses, and the error a user reads is still jsonschema's."""

from __future__ import annotations

import copy

import jsonschema
import pytest

from snapcore.errors import SchemaError
from snapcore.schema import _keywords, _validator, quick_check, validate


def _valid(doc, name: str) -> bool:
    return jsonschema.exceptions.best_match(_validator(name).iter_errors(doc)) is None


@pytest.fixture(scope="module")
def snapshot_doc():
    from snapcore.motion.synth import synth_scene
    from snapcore.pipeline import take_snapshot

    return take_snapshot(synth_scene("walk")).to_dict()


def _breaches(doc):
    """One breach of each kind the snapshot schema states: a wrong type, a minimum, a
    ``$ref``'d definition, ``minItems``/``maxItems``, ``oneOf``, ``minProperties``,
    ``additionalProperties``, ``required`` and ``enum``."""

    def edit(fn):
        d = copy.deepcopy(doc)
        fn(d)
        return d

    return [
        edit(lambda d: d.__setitem__("frame", -1)),  # $defs/frame: minimum 0
        edit(lambda d: d.__setitem__("frame", "12")),
        edit(lambda d: d.__setitem__("view", [0.0, 1.0])),  # unit_vector: minItems
        edit(lambda d: d.__setitem__("view", [0.0, 1.0, 0.0, 0.0])),
        edit(lambda d: d.__setitem__("view", [0.0, 2.0, 0.0])),  # unit_vector items: maximum
        edit(lambda d: d["window"].__setitem__("frame", 1.5)),  # oneOf [frame, null]
        edit(lambda d: d["window"].__setitem__("frame", -3)),
        edit(lambda d: d["pose_scores"].__setitem__("terms", {})),  # minProperties 1
        edit(lambda d: d["pose_scores"]["terms"].__setitem__("x", ["a"])),  # $ref series
        edit(lambda d: d["pose_scores"].__setitem__("method", "best")),  # enum
        edit(lambda d: d.__setitem__("surprise", 1)),  # additionalProperties false
        edit(lambda d: d.pop("frames")),  # required
        edit(lambda d: d["pose_scores"].__setitem__("first_frame", True)),
    ]


def test_snapshot_documents_get_the_compiled_check(snapshot_doc):
    quick = quick_check("snapshot")
    assert quick is not None  # $ref, $defs, oneOf and minProperties mean the same in both
    assert _valid(snapshot_doc, "snapshot") and quick(snapshot_doc)


def test_the_compiled_check_never_accepts_what_jsonschema_refuses(snapshot_doc):
    quick = quick_check("snapshot")
    breaches = _breaches(snapshot_doc)
    for doc in breaches:
        assert not _valid(doc, "snapshot"), "the breach must breach the schema"
        assert not quick(doc), doc


def test_validate_words_the_error_as_jsonschema_does(snapshot_doc, monkeypatch):
    """Before and after the schema is compiled (from the :data:`QUICK_AFTER`-th document
    on), a refused document gets jsonschema's line, and a valid one passes."""
    import snapcore.schema as schema

    compiled = []
    monkeypatch.setattr(schema, "_seen", {})
    monkeypatch.setattr(
        schema, "quick_check", lambda name: compiled.append(name) or quick_check(name)
    )
    doc = copy.deepcopy(snapshot_doc)
    doc["window"]["frame"] = -3
    for _ in range(schema.QUICK_AFTER + 1):
        with pytest.raises(SchemaError, match=r"^walk\.json: window\.frame: "):
            validate(doc, "snapshot", source="walk.json")
        validate(snapshot_doc, "snapshot")  # valid: no error
    assert compiled, "the compiled check was never tried"
    # 2 (Q + 1) documents, the first Q - 1 by jsonschema alone
    assert len(compiled) == 2 * (schema.QUICK_AFTER + 1) - (schema.QUICK_AFTER - 1)


def test_forms_that_changed_between_drafts_are_flagged():
    """A keyword beside ``$ref`` (ignored by Draft 7, applied by 2020-12), a list under
    ``items``, and keywords nested in ``$defs`` or ``oneOf`` all keep a schema from the
    compiled check; a ``description`` beside ``$ref`` does not."""
    assert "$ref-with-siblings" in _keywords({"$ref": "#/$defs/a", "minimum": 3})
    assert "$ref-with-siblings" not in _keywords({"$ref": "#/$defs/a", "description": "x"})
    assert "items-list" in _keywords({"items": [{"type": "string"}]})
    assert "prefixItems" in _keywords({"$defs": {"a": {"prefixItems": []}}})
    assert "if" in _keywords({"oneOf": [{"if": {}}, {"type": "null"}]})
    assert "dependentRequired" in _keywords({"not": {"dependentRequired": {}}})
