"""Pages of the study app, one module per step; each exposes ``render()``.

``app.py`` builds ``st.navigation`` from them. Pages only read state, call
:mod:`study_app.session` and show the result; the logic lives there. What the pages
share is in four modules that are not pages: :mod:`.keys` (every session-state, URL and
environment key), :mod:`.context` (the stimuli and store of the server, this run's
session), :mod:`.widgets` (small UI helpers) and :mod:`.answers` (storing an answer once
per tab); :mod:`.token_guard` (the researcher page's wrong-token limit) is not a page
either.
"""
