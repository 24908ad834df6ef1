"""JSON Schemas for every file the suite reads or writes.

Each ``<name>.schema.json`` here describes one document type: what the suite reads
(scene manifest, study config, stimuli manifest), what its commands print or write
(``snapshot select``/``info``/``bench``/``relief --json``, the video frame map, the
analysis ``summary.json``) and the three export files (response rows, participants,
interaction events). Every writer validates its document before it goes out.
Validation lives in ``snapcore.schema``; this package only locates the files so they
ship with the wheel.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["schema_path", "SCHEMA_DIR"]

SCHEMA_DIR = Path(__file__).resolve().parent


def schema_path(name: str) -> Path:
    """Path of ``<name>.schema.json`` (``name`` like ``"scene"``)."""
    return SCHEMA_DIR / f"{name}.schema.json"
