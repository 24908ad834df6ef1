"""The user study: stimuli, the Streamlit app, and the store of participants' answers.

Two layers, with :mod:`analysis` between them (``tests/test_architecture.py`` checks it):

- the study logic — :mod:`~study_app.design.protocol`, :mod:`~study_app.design.scenes`,
  :mod:`~study_app.design.stimuli`, :mod:`~study_app.data.store`, :mod:`~study_app.data.export`,
  :mod:`~study_app.session`, :mod:`~study_app.commands` — builds on snapcore and never
  imports :mod:`analysis`;
- :mod:`analysis` reads what the logic produces (the store, export files through
  :mod:`study_app.data.export`, the stimulus manifest, :class:`~study_app.design.scenes.StudyScene`);
- the Streamlit UI — :mod:`study_app.web.app`, :mod:`study_app.web.screens`,
  :mod:`study_app.web.picker` — sits on top: the researcher screen shows analysis results.

So data flows one way: study logic → analysis → UI.
"""

from study_app.data.errors import StoreError
from study_app.data.export import read_export, write_export
from study_app.data.store import Store

__all__ = ["Store", "StoreError", "read_export", "write_export"]
