"""The user study: stimuli, the Streamlit app, and the store of participants' answers.

Two layers, with :mod:`analysis` between them (``tests/test_architecture.py`` checks it):

- the study logic — :mod:`~study_app.protocol`, :mod:`~study_app.scenes`,
  :mod:`~study_app.stimuli`, :mod:`~study_app.store`, :mod:`~study_app.export`,
  :mod:`~study_app.session`, :mod:`~study_app.commands` — builds on snapcore and never
  imports :mod:`analysis`;
- :mod:`analysis` reads what the logic produces (the store, export files through
  :mod:`study_app.export`, the stimulus manifest, :class:`~study_app.scenes.StudyScene`);
- the Streamlit UI — :mod:`study_app.app`, :mod:`study_app.screens`,
  :mod:`study_app.picker` — sits on top: the researcher screen shows analysis results.

So data flows one way: study logic → analysis → UI.
"""

from .export import StoreError, read_export, write_export
from .store import Store

__all__ = ["Store", "StoreError", "read_export", "write_export"]
