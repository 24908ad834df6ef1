"""The study server process: Streamlit's own command line, with the app's imports warmed.

``snapshot study`` and the replicas run ``python -m study_app.server run study_app/app.py
...``, which is ``python -m streamlit run ...`` plus one thing: while the server starts,
a background thread imports what the app's first script runs would otherwise import
inside a participant's interaction. Streamlit runs the app script only when a session
arrives, so those imports (pandas and pyarrow, which Streamlit's component data
serialisation loads on the first player shown, SQLAlchemy, the app's own modules)
landed on the first participants: measured on a cold server, the first pose page's run
took 2.7 s, and at a launch every session that arrived meanwhile queued behind the
import lock (script runs of 1.3–4.4 s at 30 participants). Imports are process-wide,
so warming them in another thread of the same process is enough.

Once warm, it moves every object the imports made out of the garbage collector's sight
(``gc.freeze()``): Python's full collections walk every live object while holding the
interpreter, and a server's objects are mostly its imported modules. Measured at a
100-participant launch on one process: full collections paused the server 150–240 ms
each (8 of them), after the freeze 20–75 ms.

It also indexes Streamlit's configuration options by section (:func:`index_config_sections`):
every script run sends the theme, and Streamlit found each of its six theme sections by
walking all ~370 options (about 5% of the server's time at a 30-participant launch).
"""

from __future__ import annotations

import gc
import importlib
import logging
import pkgutil
import sys
import threading
import time

__all__ = ["main", "warm_up", "index_config_sections"]

log = logging.getLogger("study_app.server")


def warm_up() -> float:
    """Import what the app's script runs need; return the seconds it took."""
    t0 = time.perf_counter()
    from streamlit import dataframe_util

    # The first call loads pandas and pyarrow (component data are scanned for frames).
    dataframe_util.is_dataframe_like([0])
    import sqlalchemy  # noqa: F401 - the store's engine

    import study_app.screens as screens

    for page in pkgutil.iter_modules(screens.__path__):  # every page the app can show
        importlib.import_module(f"{screens.__name__}.{page.name}")
    from study_app.session import ParticipantSession  # noqa: F401
    from study_app.store import Store  # noqa: F401

    return time.perf_counter() - t0


def _warm_in_background() -> None:
    try:
        log.info("imports warmed in %.1f s", warm_up())
        # What the imports made lives as long as the process: never scan it again.
        gc.freeze()
    except Exception as err:  # noqa: BLE001 - a warm-up failure must not stop the server;
        # the app's own run then meets (and reports) the same problem.
        log.warning("warm-up failed: %s: %s", type(err).__name__, err)


def index_config_sections() -> None:
    """Make ``streamlit.config.get_options_for_section`` look up a section's options in
    an index instead of walking every option.

    Only the grouping is kept: values are read from the options on every call, so a
    changed value shows at once, and a re-parsed configuration (a new options dict)
    gets a new index. Same results as Streamlit's function (tested).
    """
    from streamlit import config

    if getattr(config.get_options_for_section, "snapshot_indexed", False):
        return
    index: dict[tuple, dict[str, list]] = {}

    def get_options_for_section(section: str) -> dict:
        options = config.get_config_options()
        key = (id(options), len(options))
        by_section = index.get(key)
        if by_section is None:
            by_section = {}
            for option in options.values():
                by_section.setdefault(option.section, []).append(option)
            index.clear()
            index[key] = by_section
        return {option.name: option.value for option in by_section.get(section, ())}

    get_options_for_section.__doc__ = config.get_options_for_section.__doc__
    get_options_for_section.snapshot_indexed = True
    config.get_options_for_section = get_options_for_section


def main() -> None:
    """``streamlit`` with the warm-up thread started first (arguments as for streamlit)."""
    index_config_sections()
    threading.Thread(target=_warm_in_background, name="snapshot-warm-up", daemon=True).start()
    from streamlit.web.cli import main as streamlit_main

    streamlit_main(prog_name="streamlit")


if __name__ == "__main__":
    sys.exit(main())
