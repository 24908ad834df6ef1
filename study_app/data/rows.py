"""What the store writes: the checks of a response row and of an event, before any query.

A row that does not pass is refused with a :class:`~study_app.data.errors.StoreError` naming
the trial and the field, and nothing is written (:mod:`study_app.data.store`).
"""

from __future__ import annotations

import json
import math
from typing import Any, cast

from snapcore.errors import SchemaError
from snapcore.schema import load_schema, validate

from .answer import Answer
from .errors import StoreError

__all__ = ["TRIAL_FIELDS", "checked_response", "checked_event"]

#: Fields of a response row that the caller gives (the store fills the others): the keys
#: of the answer record.
TRIAL_FIELDS = tuple(Answer.__annotations__)


def checked_response(row: Answer) -> Answer:
    """The response ``row`` with every trial field (None where not given), checked: known
    fields only, finite numbers, the chosen method shown at the chosen position, and the
    response schema. Raises :class:`~study_app.data.errors.StoreError` naming the field."""
    if not isinstance(row, dict):
        raise StoreError(f"a response must be a dict, got {type(row).__name__}")
    extra = sorted(set(row) - set(TRIAL_FIELDS))
    if extra:
        raise StoreError(
            f"response has unknown field(s) {', '.join(extra)} "
            f"(the store fills participant, study, version, time itself)"
        )
    full = {k: row.get(k) for k in TRIAL_FIELDS}
    for key in ("fps", "response_time_s"):
        value = full[key]
        if isinstance(value, float) and not math.isfinite(value):
            raise StoreError(
                f"response to trial {row.get('trial_index')!r}: {key}: "
                f"{value} is not a finite number"
            )
    order, pos, method = full["shown_order"], full["chosen_position"], full["chosen_method"]
    if (
        isinstance(order, list)
        and isinstance(pos, int)
        and not isinstance(pos, bool)
        and method is not None
    ):
        # A forged label: the method claimed must be the one shown at that position.
        if not 0 <= pos < len(order) or order[pos] != method:
            raise StoreError(
                f"response to trial {row.get('trial_index')!r}: chosen_method "
                f"{method!r} was not shown at chosen_position {pos!r} "
                f"(shown_order {order!r})"
            )
    groups = full["shown_groups"]
    if groups is not None and (
        not isinstance(order, list)
        or not isinstance(groups, list)
        or len(groups) != len(order)
        or any(not isinstance(g, list) or not g or g[0] != m for g, m in zip(groups, order))
    ):
        # Each shown picture stands for its own method first (and maybe alike ones).
        raise StoreError(
            f"response to trial {row.get('trial_index')!r}: shown_groups {groups!r} "
            f"does not match shown_order {order!r}"
        )
    if full["skipped"] is not None and (method is not None or pos is not None):
        raise StoreError(
            f"response to trial {row.get('trial_index')!r}: a skipped trial "
            f"({full['skipped']}) has no chosen method or position"
        )
    # Validate as a complete export row (placeholders for the store's own fields).
    probe = {
        **full,
        "participant_id": "x" * 22,
        "study_id": "s",
        "created_at": "2000-01-01T00:00:00+00:00",
        "app_version": "v",
        "manifest_sha256": "0" * 64,
        "simulated": False,
    }
    probe = {
        k: v
        for k, v in probe.items()
        if v is not None or k not in load_schema("response")["required"]
    }
    try:
        validate(probe, "response", source=f"response to trial {row.get('trial_index')!r}")
    except SchemaError as err:
        raise StoreError(str(err)) from None
    return cast(Answer, full)  # every key of Answer, the values checked by the schema


def checked_event(trial_index: object, kind: object, payload: Any) -> dict:
    """An event row ``{"trial_index", "kind", "payload"}``, checked: a 1-32 character
    kind, a trial index >= 0 or None, a plain-JSON payload (no NaN/inf). Raises
    :class:`~study_app.data.errors.StoreError`."""
    if not isinstance(kind, str) or not 0 < len(kind) <= 32:
        raise StoreError(f"event kind must be 1-32 characters, got {kind!r}")
    if trial_index is not None and (
        isinstance(trial_index, bool) or not isinstance(trial_index, int) or trial_index < 0
    ):
        raise StoreError(f"event trial_index must be an integer >= 0 or None, got {trial_index!r}")
    try:
        payload = json.loads(json.dumps(payload if payload is not None else {}, allow_nan=False))
    except (TypeError, ValueError) as err:
        raise StoreError(f"event payload is not plain JSON: {err}") from None
    return {"trial_index": trial_index, "kind": kind, "payload": payload}
