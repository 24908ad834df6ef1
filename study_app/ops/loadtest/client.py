"""A Streamlit client at the protocol level: one websocket, protobuf messages, no browser.

It speaks what the Streamlit frontend speaks on ``ws://HOST/_stcore/stream``: a
``BackMsg.rerun_script`` carrying the page's query string and the state of every widget
the page shows, answered by ``ForwardMsg`` deltas until ``script_finished``. The messages
are the classes of the installed ``streamlit`` package, so the client follows the
server's own version of the protocol. Widgets are found in the deltas by the ``key`` the
app gives them (Streamlit ends each element id with ``-<key>``), and set the way the
browser sets them: a checkbox as ``bool_value``, a radio or selectbox as the chosen
option's text (``string_value``), a button as ``trigger_value``, and a components-v2
widget (the frame picker, the view chooser) as a JSON list of ``{"event", "value"}``
on its trigger aggregator ``$$STREAMLIT_INTERNAL_KEY_<id>__events``.

Many clients share one asyncio loop, so one process drives hundreds of participants
and the server is what gets measured.
"""

from __future__ import annotations

import asyncio
import json
from dataclasses import dataclass, field
from typing import TYPE_CHECKING
from urllib.parse import parse_qsl, urlsplit

if TYPE_CHECKING:
    from websockets.asyncio.client import ClientConnection

__all__ = ["Element", "Page", "StreamlitClient", "ProtocolError", "trigger_id"]

#: Element types that are widgets, by the oneof name of ``Element.type``.
WIDGET_TYPES = (
    "button",
    "checkbox",
    "radio",
    "selectbox",
    "text_input",
    "slider",
    "bidi_component",
)
#: Element types whose text the client keeps (what the participant reads).
TEXT_TYPES = ("heading", "markdown", "alert", "code", "exception")


class ProtocolError(RuntimeError):
    """The server closed the connection or answered something the client cannot follow."""


def trigger_id(element_id: str) -> str:
    """The trigger aggregator widget id of a components-v2 element (where its events go)."""
    return f"$$STREAMLIT_INTERNAL_KEY_{element_id}__events"


@dataclass
class Element:
    """One element of the page as the server sent it.

    Attributes
    ----------
    kind : str
        The element type (``"button"``, ``"radio"``, ``"bidi_component"``, ``"markdown"``...).
    id : str
        The widget id ('' for non-widgets).
    key : str
        The app's ``key=`` of the widget (the id's suffix), '' without one.
    options : list of str
        Options of a radio or selectbox.
    data : dict or None
        The JSON data of a components-v2 element.
    text : str
        Text of a heading, markdown, alert or code block.
    disabled : bool
    """

    kind: str
    id: str = ""
    key: str = ""
    options: list = field(default_factory=list)
    data: dict | None = None
    text: str = ""
    disabled: bool = False
    #: The ``st.fragment`` that drew it ("" outside one): a change of this widget
    #: reruns only that fragment, as in the browser.
    fragment_id: str = ""


@dataclass
class Page:
    """What one interaction left on screen: its elements, in the order they came."""

    elements: list = field(default_factory=list)

    def widget(self, key_prefix: str) -> Element | None:
        """The first widget whose key is ``key_prefix`` or starts with ``key_prefix.``."""
        for e in self.elements:
            if e.key == key_prefix or e.key.startswith(key_prefix + "."):
                return e
        return None

    def texts(self, kind: str | None = None) -> list[str]:
        return [e.text for e in self.elements if e.text and (kind is None or e.kind == kind)]

    def has_text(self, needle: str) -> bool:
        return any(needle in t for t in self.texts())


def _element(el) -> Element:
    kind = el.WhichOneof("type") or ""
    out = Element(kind=kind)
    if kind in WIDGET_TYPES:
        proto = getattr(el, kind)
        out.id = proto.id
        # Streamlit's ids are "$$ID-<hash>-<user key>" (the key may itself hold '-').
        parts = proto.id.split("-", 2)
        out.key = parts[2] if len(parts) == 3 and proto.id.startswith("$$ID") else ""
        out.disabled = bool(getattr(proto, "disabled", False))
        if kind in ("radio", "selectbox"):
            out.options = list(proto.options)
        if kind == "bidi_component" and proto.WhichOneof("data") == "json":
            out.data = json.loads(proto.json)
        elif kind == "bidi_component" and proto.WhichOneof("data") == "mixed":
            out.data = json.loads(proto.mixed.json)
        if isinstance(out.data, list) and len(out.data) == 1:
            out.data = out.data[0]  # the study's components send [data] (study_app/web/picker)
        if kind == "button":
            out.text = proto.label
    elif kind == "heading":
        out.text = el.heading.body
    elif kind == "markdown":
        out.text = el.markdown.body
    elif kind == "alert":
        out.text = el.alert.body
    elif kind == "code":
        out.text = el.code.code_text
    elif kind == "exception":
        out.text = f"{el.exception.type}: {el.exception.message}"
    return out


class StreamlitClient:
    """One browser tab's conversation with a Streamlit server.

    Parameters
    ----------
    url : str
        The app's address, ``http://host:port/`` (the websocket is ``/_stcore/stream``).
    query : str
        The query string the tab was opened with (e.g. the Prolific parameters).
    cookies : dict, optional
        Cookies sent with the websocket upgrade (e.g. the replica-routing cookie that
        nginx set on the page load).
    timeout_s : float
        Longest wait for one interaction's script runs to finish.
    load_page : bool
        Fetch the page's HTML before opening the websocket, as a browser does, keeping
        the cookies it sets (nginx's replica-routing cookie comes this way).
    """

    def __init__(
        self,
        url: str,
        *,
        query: str = "",
        cookies: dict | None = None,
        timeout_s: float = 60.0,
        load_page: bool = True,
    ):
        parts = urlsplit(url)
        scheme = "wss" if parts.scheme == "https" else "ws"
        path = parts.path.rstrip("/")
        self.http_url = f"{parts.scheme}://{parts.netloc}{path}/"
        self.ws_url = f"{scheme}://{parts.netloc}{path}/_stcore/stream"
        self.origin = f"{parts.scheme}://{parts.netloc}"
        self.query = query
        self.cookies = dict(cookies or {})
        self.timeout_s = timeout_s
        self.load_page = load_page
        self.ws: ClientConnection | None = None
        #: Current value of every stateful widget, by widget id (sent with every rerun,
        #: as the browser does).
        self.values: dict[str, tuple[str, object]] = {}
        self.page = Page()
        self.script_runs = 0
        #: The page the app is showing (its script hash, sent back with every rerun as
        #: the browser does; empty on a fresh page load).
        self.page_script_hash = ""
        #: What is on screen, by delta path (a fragment run replaces part of it).
        self._elements: dict[tuple, Element] = {}
        #: The fragment of the widget the participant last used ("" for the app).
        self._fragment_id = ""

    # -- connection ------------------------------------------------------------------
    def _get_page(self) -> None:
        import urllib.request
        from http.cookies import SimpleCookie

        req = urllib.request.Request(self.http_url + ("?" + self.query if self.query else ""))
        if self.cookies:
            req.add_header("Cookie", "; ".join(f"{k}={v}" for k, v in self.cookies.items()))
        with urllib.request.urlopen(req, timeout=self.timeout_s) as r:
            r.read()
            for header in r.headers.get_all("Set-Cookie") or []:
                for name, morsel in SimpleCookie(header).items():
                    self.cookies[name] = morsel.value

    async def connect(self) -> None:
        """Open the page (HTML, when ``load_page``) and its websocket."""
        import websockets
        from websockets.typing import Subprotocol

        if self.load_page:
            await asyncio.to_thread(self._get_page)
        headers = {"Origin": self.origin}
        if self.cookies:
            headers["Cookie"] = "; ".join(f"{k}={v}" for k, v in self.cookies.items())
        self.ws = await websockets.connect(
            self.ws_url,
            subprotocols=[Subprotocol("streamlit")],
            additional_headers=headers,
            max_size=None,
            open_timeout=self.timeout_s,
            ping_interval=None,
        )

    async def close(self) -> None:
        if self.ws is not None:
            await self.ws.close()
            self.ws = None

    async def reload(self, query: str | None = None) -> Page:
        """Close the tab's connection and open the page again (a browser reload).

        A new connection is a new Streamlit session: widget values are gone, and the
        app finds the participant from the ``pid`` in the URL.
        """
        await self.close()
        if query is not None:
            self.query = query
        self.values = {}
        self.page_script_hash = ""
        self._elements = {}
        self._fragment_id = ""
        await self.connect()
        return await self.rerun()

    # -- interactions ----------------------------------------------------------------
    async def rerun(
        self, *, triggers: list | None = None, history: bool = False, wait: bool = True
    ) -> Page:
        """Send one rerun (the stateful widget values plus ``triggers``) and read the
        page until the last script run finishes.

        Parameters
        ----------
        triggers : list of WidgetState, optional
            One-shot values (a button click, a component event).
        history : bool
            The rerun is a Back/Forward navigation of the browser.
        wait : bool
            Read the answer (False: send only, as the first click of a double click).
        """
        from streamlit.proto.BackMsg_pb2 import BackMsg
        from streamlit.proto.WidgetStates_pb2 import WidgetState

        msg = BackMsg()
        cs = msg.rerun_script
        cs.query_string = self.query
        cs.is_history_navigation = history
        # What the browser tells the server about the tab on every rerun: the page it
        # shows, and its address, time zone and locale (st.context).
        cs.page_script_hash = self.page_script_hash
        cs.context_info.url = self.http_url
        cs.context_info.timezone = "UTC"
        cs.context_info.locale = "en-US"
        cs.context_info.color_scheme = "light"
        # A change of a widget inside an st.fragment reruns only that fragment (both
        # sends of a double click); Back/Forward reruns the app.
        cs.fragment_id = "" if history else self._fragment_id
        for wid, (kind, value) in self.values.items():
            w = WidgetState(id=wid)
            setattr(w, kind, value)
            cs.widget_states.widgets.append(w)
        for w in triggers or ():
            cs.widget_states.widgets.append(w)
        if self.ws is None:
            raise ProtocolError("not connected")
        import websockets

        try:
            await self.ws.send(msg.SerializeToString())
        except websockets.ConnectionClosed as err:
            raise ProtocolError(f"connection closed ({_close_code(err)})") from err
        if not wait:
            return self.page
        return await asyncio.wait_for(self._read_until_finished(), self.timeout_s)

    async def _read_until_finished(self) -> Page:
        import websockets
        from streamlit.proto.ForwardMsg_pb2 import ForwardMsg

        if self.ws is None:
            raise ProtocolError("not connected")
        elements = self._elements
        fragments: set[str] = set()  # the fragments this run redraws (empty: the app)
        drawn: set[tuple] = set()
        while True:
            try:
                raw = await self.ws.recv()
            except websockets.ConnectionClosed as err:
                raise ProtocolError(f"connection closed ({_close_code(err)})") from err
            fm = ForwardMsg()
            fm.ParseFromString(raw)
            kind = fm.WhichOneof("type")
            if kind == "new_session":
                fragments = set(fm.metadata.run.fragment_ids)
                drawn = set()
                if not fragments:
                    elements.clear()  # a full run draws the whole page again
                self.page_script_hash = fm.new_session.page_script_hash or self.page_script_hash
            elif kind == "navigation":
                self.page_script_hash = fm.navigation.page_script_hash or self.page_script_hash
            elif kind == "delta" and fm.delta.WhichOneof("type") == "new_element":
                path = tuple(fm.metadata.delta_path)
                elements[path] = _element(fm.delta.new_element)
                elements[path].fragment_id = fm.delta.fragment_id
                drawn.add(path)
            elif kind == "page_info_changed":
                # The app changed its URL (st.query_params): the tab's address now.
                self.query = fm.page_info_changed.query_string
            elif kind == "script_finished":
                self.script_runs += 1
                status = fm.script_finished
                if status == ForwardMsg.FINISHED_FRAGMENT_RUN_SUCCESSFULLY:
                    # What the fragment drew before and not this time is gone.
                    for p in [
                        p
                        for p, e in elements.items()
                        if e.fragment_id in fragments and p not in drawn
                    ]:
                        del elements[p]
                if status in (
                    ForwardMsg.FINISHED_SUCCESSFULLY,
                    ForwardMsg.FINISHED_FRAGMENT_RUN_SUCCESSFULLY,
                ):
                    self.page = Page([elements[p] for p in sorted(elements)])
                    self._forget_gone_widgets()
                    return self.page
                if status == ForwardMsg.FINISHED_WITH_COMPILE_ERROR:
                    raise ProtocolError("the app script failed to compile")
                # FINISHED_EARLY_FOR_RERUN: st.rerun() or a newer request; keep reading.

    def _forget_gone_widgets(self) -> None:
        # The browser drops the state of widgets that are no longer on the page.
        ids = {e.id for e in self.page.elements if e.id}
        self.values = {k: v for k, v in self.values.items() if k in ids}

    # -- widget helpers (one user action each) ---------------------------------------
    def set_value(self, element: Element, value) -> None:
        """Set a stateful widget's value as the browser would (sent with the next rerun)."""
        self._fragment_id = element.fragment_id
        if element.kind == "checkbox":
            self.values[element.id] = ("bool_value", bool(value))
        elif element.kind in ("radio", "selectbox", "text_input"):
            self.values[element.id] = ("string_value", str(value))
        else:
            raise ProtocolError(f"cannot set a {element.kind} widget")

    def click(self, element: Element):
        """A button click (a one-shot trigger)."""
        from streamlit.proto.WidgetStates_pb2 import WidgetState

        self._fragment_id = element.fragment_id
        return WidgetState(id=element.id, trigger_value=True)

    def component_event(self, element: Element, event: str, value) -> object:
        """A components-v2 event (``setTriggerValue(event, value)`` in the browser)."""
        from streamlit.proto.WidgetStates_pb2 import WidgetState

        self._fragment_id = element.fragment_id
        return WidgetState(
            id=trigger_id(element.id),
            json_trigger_value=json.dumps([{"event": event, "value": value}]),
        )

    def query_params(self) -> dict:
        return dict(parse_qsl(self.query))


def _close_code(err) -> str:
    frame = err.rcvd or err.sent
    return "no close frame" if frame is None else str(frame.code)
