"""The researcher's part of :class:`~study_app.data.store.Store`: responses as export
rows (every participant's, or one participant's), and the counts of the researcher page.

The rows have exactly the fields of ``data_schema/response.schema.json``; the codec,
:mod:`study_app.data.export`, writes and reads them. The monitor, exclusions and the
recruitment cap are in :mod:`study_app.data.monitor`.
"""

from __future__ import annotations

from typing import cast

import sqlalchemy as sa

from .answer import ResponseRow
from .database import participants, responses
from .engine import StoreEngine, _iso
from .export import BACKGROUND_FIELDS, _background_value, export_columns, validate_rows

__all__ = ["ResearcherQueries"]


class ResearcherQueries(StoreEngine):
    """Export rows and progress counts (one read transaction per call)."""

    def responses(self, pid: str) -> list[ResponseRow]:
        """This participant's stored responses (export rows), by trial index."""
        self._check_pid(pid)
        with self.transaction(write=False) as conn:
            self._participant_row(conn, pid)
            rows = (
                conn.execute(self._export_query().where(responses.c.participant_id == pid))
                .mappings()
                .all()
            )
        return [_export_row(r) for r in rows]

    @staticmethod
    def _export_query() -> sa.Select:
        return (
            sa.select(
                responses,
                participants.c.study_id,
                participants.c.simulated,
                participants.c.background,
                participants.c.prolific_pid,
            )
            .join(participants, responses.c.participant_id == participants.c.participant_id)
            .order_by(
                participants.c.created_at, responses.c.participant_id, responses.c.trial_index
            )
        )

    def export_rows(
        self, *, include_simulated: bool = False, validate: bool = False
    ) -> list[ResponseRow]:
        """Every response as a ``response.schema.json`` row (background joined in).

        Ordered by participant (oldest first) then trial index. Every schema field is a
        key (``None`` where absent). ``validate=True`` checks each row against the
        schema (:func:`validate_rows`).
        """
        query = self._export_query()
        if not include_simulated:
            query = query.where(participants.c.simulated.is_(False))
        with self.transaction(write=False) as conn:
            rows = [_export_row(r) for r in conn.execute(query).mappings()]
        if validate:
            validate_rows(rows)
        return rows

    def progress(self, *, include_simulated: bool = False) -> dict:
        """Counts for the researcher page.

        ``{"participants", "completed", "responses", "by_task": {task: n}, "simulated"}``;
        the first four count real participants only unless ``include_simulated``;
        ``simulated`` is always the number of simulated participants.
        """
        p, r = participants, responses
        real = sa.true() if include_simulated else p.c.simulated.is_(False)
        with self.transaction(write=False) as conn:
            n_part = conn.execute(
                sa.select(sa.func.count()).select_from(p).where(real)
            ).scalar_one()
            n_done = conn.execute(
                sa.select(sa.func.count()).select_from(p).where(real, p.c.completed_at.is_not(None))
            ).scalar_one()
            n_sim = conn.execute(
                sa.select(sa.func.count()).select_from(p).where(p.c.simulated.is_(True))
            ).scalar_one()
            by_task: dict[str, int] = dict(
                conn.execute(
                    sa.select(r.c.task, sa.func.count())
                    .select_from(r.join(p, r.c.participant_id == p.c.participant_id))
                    .where(real)
                    .group_by(r.c.task)
                ).all()
            )
        return {
            "participants": int(n_part),
            "completed": int(n_done),
            "responses": int(sum(by_task.values())),
            "by_task": {k: int(v) for k, v in sorted(by_task.items())},
            "simulated": int(n_sim),
        }


def _export_row(r: sa.RowMapping) -> ResponseRow:
    out: dict[str, object] = {}
    for name in export_columns():
        if name in BACKGROUND_FIELDS:
            out[name] = _background_value((r["background"] or {}).get(name))
        elif name == "created_at":
            out[name] = _iso(r[name])
        elif name in ("simulated",):
            out[name] = bool(r[name])
        elif name == "correct":
            out[name] = None if r[name] is None else bool(r[name])
        else:
            out[name] = r[name]
    return cast(ResponseRow, out)  # the schema's columns, as stored (checked on the way in)
