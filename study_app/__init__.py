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

from .data.errors import StoreError
from .data.export import read_export, write_export
from .data.store import Store

__all__ = ["Store", "StoreError", "read_export", "write_export"]
