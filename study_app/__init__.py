"""The user study: stimuli, the Streamlit app, and the store of participants' answers.

Layers, lowest first, with :mod:`analysis` between the logic and the UI
(``tests/test_architecture.py`` checks it; ARCHITECTURE.md has the table):

- :mod:`~study_app.design` — what a study shows: protocol, scenes, stimuli;
- :mod:`~study_app.data` — what it stores, and every SQL statement: tables, store,
  export codec, withdrawal, pseudonyms, backups, Psych-DS;
- :mod:`~study_app.session` — one participant's walk through the protocol;
- :mod:`analysis` reads what the logic produces (the store, export files, the stimulus
  manifest, :class:`~study_app.design.scenes.StudyScene`), never the session or the UI;
- :mod:`~study_app.web` — the Streamlit UI (app, screens, picker, server, timing): the
  researcher screen shows analysis results;
- :mod:`~study_app.ops` — replicas and the load test, which run the web servers;
- :mod:`~study_app.commands` — the study's ``snapshot`` commands.

So data flows one way: design → data → session → analysis → UI → operations → commands.
"""

from importlib import import_module
from typing import TYPE_CHECKING

# The names below are imported on first use (PEP 562), not here: importing any
# study module runs this file, and the store (SQLAlchemy) cost every test module that
# only needs a protocol or a scene a second or more, at test collection too.
_WHERE = {
    ".data.errors": ("StoreError",),
    ".data.export": ("read_export", "write_export"),
    ".data.store": ("Store",),
}
_MODULE_OF = {name: module for module, names in _WHERE.items() for name in names}

# The type checker reads the same names from their modules (a PEP 562 `__getattr__`
# alone would make every public name `Any` to it); these lines never run.
if TYPE_CHECKING:
    from .data.errors import StoreError
    from .data.export import read_export, write_export
    from .data.store import Store


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = ["Store", "StoreError", "read_export", "write_export"]
