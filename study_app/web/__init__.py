"""The Streamlit UI of the study: the app script (:mod:`.app`), its pages
(:mod:`.screens`), the frame picker and view chooser components (:mod:`.picker`), the
server process that runs it (:mod:`.server`) and the time of each script run
(:mod:`.timing`).

Sits above :mod:`analysis` (the researcher screen shows live vote tables).
"""
