"""The study server process: Streamlit's own command line, with the app's imports warmed.

``snapshot study`` and the replicas run ``python -m study_app.web.server run study_app/web/app.py
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

It sends a browser that asks for a page two or more folders deep (``/pages/consent``, an
old or mistyped link) to the study with the same query (:class:`DeepPageRedirect`):
Streamlit would serve its page there, take ``/pages`` for the app's base path, fail to
connect and stay blank.

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
from pathlib import Path

__all__ = [
    "main",
    "warm_up",
    "index_config_sections",
    "DeepPageRedirect",
    "redirect_deep_page_paths",
    "streamlit_command",
    "APP",
]

log = logging.getLogger("study_app.web.server")

#: The app script Streamlit runs.
APP = Path(__file__).resolve().parent / "app.py"


def warm_up() -> float:
    """Import what the app's script runs need; return the seconds it took."""
    t0 = time.perf_counter()
    from streamlit import dataframe_util

    # The first call loads pandas and pyarrow (component data are scanned for frames).
    dataframe_util.is_dataframe_like([0])
    import sqlalchemy  # noqa: F401 - the store's engine

    import study_app.web.screens as screens

    for page in pkgutil.iter_modules(screens.__path__):  # every page the app can show
        importlib.import_module(f"{screens.__name__}.{page.name}")
    from study_app.data.store import Store  # noqa: F401
    from study_app.session import ParticipantSession  # noqa: F401

    return time.perf_counter() - t0


def streamlit_command(*, port: int, address: str) -> list[str]:
    """The ``streamlit run`` command line for the app (headless, no telemetry, no watcher),
    through :mod:`study_app.web.server`, which warms the app's imports while Streamlit starts.

    ``runner.postScriptGC`` is off: Streamlit otherwise runs a full ``gc.collect(2)``
    after every script run, which took two thirds of the server's CPU in the load test
    (tens of ms per interaction with this app's heap); Python's own generational
    collector still runs.

    ``runner.fastReruns`` is off: with it, a rerun request during a run (a double click's
    second send) starts a new script thread at once while the old one finishes, so the
    second run could resume the participant before the first one's answer was stored and
    draw the answered step again. Off, a session's runs follow one another: a rerun
    stops the current run at its next Streamlit call and starts after it.
    """
    return [
        sys.executable,
        "-m",
        "study_app.web.server",
        "run",
        str(APP),
        "--server.headless",
        "true",
        "--server.address",
        address,
        "--server.port",
        str(port),
        "--browser.gatherUsageStats",
        "false",
        "--server.fileWatcherType",
        "none",
        "--server.runOnSave",
        "false",
        "--runner.postScriptGC",
        "false",
        "--runner.fastReruns",
        "false",
        "--theme.base",
        "light",
        "--client.toolbarMode",
        "minimal",
    ]


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
    get_options_for_section.snapshot_indexed = True  # type: ignore[attr-defined]  # a marker
    config.get_options_for_section = get_options_for_section


class DeepPageRedirect:
    """ASGI middleware: a page request for a path of two or more segments, or of one that
    is not a page of the app (``/study``, ``/pose_task``, ``/done``: every step of the
    flow is at the root) → 307 to the app's root with the same query string (so
    ``/done?pid=…`` resumes the participant). Streamlit would show the root's page under
    a "Page not found" dialog.

    Only browser page loads (GET/HEAD accepting ``text/html``) outside Streamlit's own
    route prefixes are redirected; scripts, assets and the websocket pass through.
    """

    #: First path segments that are Streamlit's (or its components') routes, never pages.
    RESERVED = frozenset(
        {"_stcore", "static", "media", "component", "app", "auth", "oauth2callback"}
    )
    #: Pages with an address of their own (study_app.web.app.RESEARCHER_PATH).
    PAGES = frozenset({"researcher"})

    def __init__(self, app, base_path: str = ""):
        self.app = app
        self.root = "/" + "/".join(s for s in base_path.split("/") if s)
        self.root += "" if self.root == "/" else "/"

    async def __call__(self, scope, receive, send):
        if scope["type"] == "http" and scope["method"] in ("GET", "HEAD"):
            path = (
                scope["path"][len(self.root) - 1 :] if scope["path"].startswith(self.root) else ""
            )
            segments = [s for s in path.split("/") if s]
            accept = dict(scope.get("headers") or ()).get(b"accept", b"")
            elsewhere = len(segments) >= 2 or (len(segments) == 1 and segments[0] not in self.PAGES)
            if elsewhere and segments[0] not in self.RESERVED and b"text/html" in accept:
                query = scope.get("query_string", b"")
                location = self.root.encode() + (b"?" + query if query else b"")
                await send(
                    {
                        "type": "http.response.start",
                        "status": 307,
                        "headers": [(b"location", location), (b"content-length", b"0")],
                    }
                )
                await send({"type": "http.response.body", "body": b""})
                return
        await self.app(scope, receive, send)


def redirect_deep_page_paths() -> None:
    """Put :class:`DeepPageRedirect` in front of the app Streamlit's server creates."""
    from streamlit import config
    from streamlit.web.server.starlette import starlette_server

    create = starlette_server.create_starlette_app
    if getattr(create, "snapshot_redirects", False):
        return

    def create_starlette_app(runtime):
        app = create(runtime)
        app.add_middleware(
            DeepPageRedirect, base_path=config.get_option("server.baseUrlPath") or ""
        )
        return app

    create_starlette_app.snapshot_redirects = True  # type: ignore[attr-defined]  # a marker
    starlette_server.create_starlette_app = create_starlette_app


def main() -> None:
    """``streamlit`` with the warm-up thread started first (arguments as for streamlit)."""
    index_config_sections()
    redirect_deep_page_paths()
    threading.Thread(target=_warm_in_background, name="snapshot-warm-up", daemon=True).start()
    from streamlit.web.cli import main as streamlit_main

    streamlit_main(prog_name="streamlit")


if __name__ == "__main__":
    main()
