"""The data layer's one exception: what the store, the export codec, withdrawal, pseudonyms
and backups raise when they cannot do what was asked.

It lives apart from every module that raises it, so the database modules need not import
the export codec to name it.
"""

from __future__ import annotations

from snapcore.errors import SnapshotError

__all__ = ["StoreError"]


class StoreError(SnapshotError):
    """The store cannot do what was asked: bad database URL, unknown participant, bad row."""
