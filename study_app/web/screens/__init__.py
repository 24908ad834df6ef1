"""Pages of the study app, one module per step; each exposes ``render()``.

``app.py`` builds ``st.navigation`` from them. Pages only read state, call
:mod:`study_app.session` and show the result; the logic lives there.
"""
