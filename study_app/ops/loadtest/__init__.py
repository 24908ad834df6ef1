"""Load tests of a running study: simulated participants at the protocol level.

- :mod:`.client` — a Streamlit websocket client (protobuf messages of the installed
  ``streamlit``), one per simulated browser tab;
- :mod:`.participant` — one participant's way from the study link to the completion
  code, with seeded random choices (and optional reload, Back, double click);
- :mod:`.run` — many participants at once, the latency and server report, and the
  database check afterwards.

This is study logic (no Streamlit UI imported): ``snapshot loadtest`` and the tests
drive it.
"""
