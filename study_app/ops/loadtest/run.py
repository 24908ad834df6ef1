"""Many simulated participants at once, and what the run measured.

:func:`run_load` starts ``n`` participants over a ramp (a Prolific launch: everyone
within a minute or two), samples the server processes' CPU and memory while they run,
and returns a report (a dict; ``data_schema/loadtest.schema.json``):

- per action (``consent_start``, ``pose_confirm``, ...) and over all actions: count,
  p50, p95 and max of the time from sending the interaction to the end of the last
  script run it caused (end to end, as a browser would wait);
- the server's own time per script run, when the app writes ``$SNAPSHOT_TIMINGS``;
- server CPU (share of one core, over the run) and resident memory (before, peak, and
  the growth per participant session);
- the database afterwards (:func:`check_database`): one participant per simulated
  person, every answer sent stored exactly once and as sent, the completion code,
  and no response or event for a trial the participant never reached.
"""

from __future__ import annotations

import asyncio
import random
import threading
import time
from typing import Any

from .participant import Behaviour, ParticipantResult, run_participant

__all__ = [
    "run_load",
    "build_report",
    "percentiles",
    "ServerSampler",
    "server_pids_for_port",
    "check_database",
    "behaviours",
]


def percentiles(values) -> dict:
    """``{"n", "p50", "p95", "max"}`` of ``values`` (seconds, rounded to ms; None when empty).

    Percentiles by linear interpolation (NumPy's default), e.g.
    ``numpy.percentile([1, 2, 3, 4], 95) == 3.85``.
    """
    import numpy as np

    v = np.asarray(list(values), dtype=float)
    if v.size == 0:
        return {"n": 0, "p50": None, "p95": None, "max": None}
    return {
        "n": int(v.size),
        "p50": round(float(np.percentile(v, 50)), 4),
        "p95": round(float(np.percentile(v, 95)), 4),
        "max": round(float(v.max()), 4),
    }


def server_pids_for_port(port: int) -> list[int]:
    """Processes listening on ``port`` on this machine (the local server)."""
    import psutil

    pids = set()
    for c in psutil.net_connections(kind="tcp"):
        if c.status == psutil.CONN_LISTEN and c.laddr and c.laddr.port == port and c.pid:
            pids.add(c.pid)
    return sorted(pids)


class ServerSampler:
    """Samples CPU time and resident memory of server processes in a thread.

    Parameters
    ----------
    pids : list of int
        The server processes (their children are included).
    interval_s : float
        Seconds between samples.
    """

    def __init__(self, pids, *, interval_s: float = 0.5):
        import psutil

        self.procs = []
        for pid in pids:
            try:
                self.procs.append(psutil.Process(pid))
            except psutil.Error:
                pass
        self.interval_s = interval_s
        self.samples: list[tuple[float, float, float]] = []  # (time, cpu s, rss bytes)
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._loop, daemon=True)

    def _read(self) -> tuple[float, float]:
        import psutil

        cpu = rss = 0.0
        for p in self.procs:
            try:
                family = [p, *p.children(recursive=True)]
            except psutil.Error:
                continue  # a replica killed mid-run: its last numbers stay in the samples
            for q in family:
                try:
                    t = q.cpu_times()
                    cpu += t.user + t.system
                    rss += q.memory_info().rss
                except psutil.Error:
                    pass
        return cpu, rss

    def _loop(self) -> None:
        while not self._stop.is_set():
            self.samples.append((time.monotonic(), *self._read()))
            self._stop.wait(self.interval_s)

    def start(self) -> ServerSampler:
        self.samples.append((time.monotonic(), *self._read()))
        self._thread.start()
        return self

    def stop(self) -> dict:
        """Stop sampling; ``{"cpu_share", "cpu_seconds", "rss_start_mb", "rss_peak_mb"}``."""
        self._stop.set()
        self._thread.join()
        self.samples.append((time.monotonic(), *self._read()))
        if not self.procs or len(self.samples) < 2:
            return {}
        t0, c0, r0 = self.samples[0]
        t1, _, _ = self.samples[-1]
        cpu_used = max(c for _, c, _ in self.samples) - c0
        return {
            "processes": len(self.procs),
            "cpu_seconds": round(cpu_used, 2),
            "cpu_share": round(cpu_used / max(t1 - t0, 1e-9), 3),
            "rss_start_mb": round(r0 / 2**20, 1),
            "rss_peak_mb": round(max(r for _, _, r in self.samples) / 2**20, 1),
        }


def behaviours(
    n: int, *, reload: float, back: float, double_click: float, seed: int
) -> list[Behaviour]:
    """Who reloads, goes Back or double-clicks: each share drawn independently, seeded."""
    rng = random.Random(f"behaviours:{seed}")
    return [
        Behaviour(
            reload=rng.random() < reload,
            back=rng.random() < back,
            double_click=rng.random() < double_click,
        )
        for _ in range(n)
    ]


async def _run_all(url, n, *, ramp_s, think_s, seed, kinds, prolific, timeout_s, on_start=None):
    loop = asyncio.get_running_loop()
    start = loop.time()

    async def one(i):
        # Arrivals spread evenly over the ramp (a launch: everyone within ramp_s).
        await asyncio.sleep(ramp_s * i / max(n, 1))
        return await run_participant(
            url,
            i,
            seed=seed,
            think_s=think_s,
            behaviour=kinds[i],
            prolific=prolific,
            timeout_s=timeout_s,
        )

    tasks = [asyncio.create_task(one(i)) for i in range(n)]
    if on_start is not None:
        await on_start(tasks)
    results = await asyncio.gather(*tasks)
    return results, loop.time() - start


def run_load(
    url: str,
    n: int,
    *,
    ramp_s: float = 30.0,
    think_s: float = 2.0,
    seed: int = 0,
    reload: float = 0.0,
    back: float = 0.0,
    double_click: float = 0.0,
    prolific: bool = True,
    server_pids=(),
    timings=(),
    timeout_s: float = 120.0,
    db_url: str | None = None,
    during=None,
) -> tuple[dict, list[ParticipantResult]]:
    """Run ``n`` participants against the study at ``url``; return (report, results).

    Parameters
    ----------
    url : str
        The study's address.
    n : int
        Participants.
    ramp_s : float
        Seconds over which they arrive.
    think_s : float
        Mean seconds a participant takes before answering a trial.
    seed : int
        Seeds every choice and who reloads / goes Back / double-clicks.
    reload, back, double_click : float
        Share of participants (0-1) who do each once.
    server_pids : sequence of int
        Server processes to sample (empty: no CPU and memory numbers).
    timings : sequence of path
        ``$SNAPSHOT_TIMINGS`` files of the servers (script-run times).
    db_url : str, optional
        The study's database: checked afterwards (:func:`check_database`).
    during : callable, optional
        ``during(elapsed_s)`` is called about every second while the run goes on in a
        helper thread (e.g. to kill a replica mid-run in a test).
    """
    kinds = behaviours(n, reload=reload, back=back, double_click=double_click, seed=seed)
    sampler = ServerSampler(server_pids).start() if server_pids else None
    wall0 = time.time()
    stop = threading.Event()
    watcher = None
    if during is not None:

        def watch():
            t0 = time.monotonic()
            while not stop.wait(1.0):
                during(time.monotonic() - t0)

        watcher = threading.Thread(target=watch, daemon=True)
        watcher.start()
    try:
        results, elapsed = asyncio.run(
            _run_all(
                url,
                n,
                ramp_s=ramp_s,
                think_s=think_s,
                seed=seed,
                kinds=kinds,
                prolific=prolific,
                timeout_s=timeout_s,
            )
        )
    finally:
        stop.set()
        if watcher is not None:
            watcher.join()
    wall1 = time.time()
    server = sampler.stop() if sampler else {}
    config = {
        "url": url,
        "participants": n,
        "ramp_s": ramp_s,
        "think_s": think_s,
        "seed": seed,
        "reload": reload,
        "back": back,
        "double_click": double_click,
        "prolific": prolific,
        "driver": "protocol",
    }
    return build_report(
        results,
        elapsed_s=elapsed,
        server=server,
        config=config,
        timings=timings,
        window=(wall0, wall1),
        db_url=db_url,
    ), results


def build_report(
    results,
    *,
    elapsed_s: float,
    server: dict,
    config: dict,
    timings=None,
    window=(0.0, 0.0),
    db_url: str | None = None,
) -> dict:
    """The load-test report of either driver: latencies, the run's settings, the
    server's memory per session and own script-run times, and the database check.

    Parameters
    ----------
    results : list of ParticipantResult
    elapsed_s : float
        Wall-clock seconds of the run.
    server : dict
        From :class:`ServerSampler` (empty when no server process was watched).
    config : dict
        The run's settings (``participants`` among them).
    timings : path-like, optional
        The server's script-run log (``SNAPSHOT_TIMINGS``), read over ``window``.
    window : (float, float)
        Start and end of the run, Unix seconds.
    db_url : str, optional
        Check the stored answers against what the participants sent.
    """
    n = config["participants"]
    if server and n:
        server["rss_per_session_mb"] = round(
            (server["rss_peak_mb"] - server["rss_start_mb"]) / n, 3
        )
    report = summarize(results, elapsed_s=elapsed_s, server=server)
    report["config"] = config
    if timings:
        from study_app.web.timing import read_timings

        runs = read_timings(timings, since=window[0], until=window[1])
        report["server_script_runs"] = percentiles(r["ms"] / 1000.0 for r in runs)
    if db_url:
        report["database"] = check_database(db_url, results)
    return report


def summarize(results, *, elapsed_s: float, server: dict) -> dict:
    """The latency, error and completion part of the report."""
    by_action: dict[str, list[float]] = {}
    for r in results:
        for action, values in r.latencies.items():
            by_action.setdefault(action, []).extend(values)
    every = [v for vs in by_action.values() for v in vs]
    errors = [f"participant {r.index}: {e}" for r in results for e in r.errors]
    return {
        "elapsed_s": round(elapsed_s, 2),
        "completed": sum(1 for r in results if r.completion_code),
        "participants": len(results),
        "reconnects": sum(r.reconnects for r in results),
        "latency": {
            "all": percentiles(every),
            **{a: percentiles(v) for a, v in sorted(by_action.items())},
        },
        "errors": {"count": len(errors), "first": errors[:20]},
        "server": server,
    }


def check_database(db_url: str, results) -> dict:
    """Check the store against what the simulated participants did.

    Returns
    -------
    dict
        ``participants_expected``, ``participants_found`` (one record per simulated
        Prolific id), ``answers_sent``, ``answers_stored_once`` (stored exactly once,
        as sent), ``duplicates``, ``missing``, ``mismatched``, ``unseen_trial_rows``
        (responses or events for a trial after the participant's last answer + 1),
        ``codes_ok`` (the completion code shown is the stored one) and ``ok``.
    """
    from study_app.data.store import Store

    store = Store(db_url)
    try:
        found: dict[str, list[dict]] = {}
        for p in store.participants(include_simulated=True):
            if p.get("prolific_pid"):
                found.setdefault(p["prolific_pid"], []).append(p)
        # counts, the ok flag and the problems: one JSON object of the report
        out: dict[str, Any] = {
            "participants_expected": len(results),
            "participants_found": 0,
            "answers_sent": 0,
            "answers_stored_once": 0,
            "duplicates": 0,
            "missing": 0,
            "mismatched": 0,
            "unseen_trial_rows": 0,
            "codes_ok": 0,
            "problems": [],
        }
        for r in results:
            records = found.get(r.prolific_pid, [])
            if len(records) != 1:
                out["problems"].append(f"participant {r.index}: {len(records)} records")
                continue
            out["participants_found"] += 1
            part = records[0]
            pid = part["participant_id"]
            if r.completion_code and r.completion_code == part.get("completion_code"):
                out["codes_ok"] += 1
            rows = store.responses(pid)
            per_trial: dict[int, list] = {}
            for row in rows:
                per_trial.setdefault(row["trial_index"], []).append(row)
            out["answers_sent"] += len(r.answers)
            for trial, sent in r.answers.items():
                got = per_trial.get(trial, [])
                if not got:
                    out["missing"] += 1
                    out["problems"].append(f"participant {r.index}: trial {trial} not stored")
                elif len(got) > 1:
                    out["duplicates"] += 1
                elif not _matches(sent, got[0]):
                    out["mismatched"] += 1
                    out["problems"].append(
                        f"participant {r.index}: trial {trial} stored "
                        f"{_stored_value(got[0])}, sent {sent}"
                    )
                else:
                    out["answers_stored_once"] += 1
            reached = max(r.answers, default=-1) + 1  # the next trial may have been shown
            extra = [t for t in per_trial if t not in r.answers]
            extra += [
                e["trial_index"]
                for e in store.events(pid)
                if e["trial_index"] is not None and e["trial_index"] > reached
            ]
            out["unseen_trial_rows"] += len(extra)
            if extra:
                out["problems"].append(f"participant {r.index}: rows for unseen trials {extra}")
        out["ok"] = (
            out["participants_found"] == len(results)
            and out["answers_stored_once"] == out["answers_sent"]
            and not (
                out["duplicates"] or out["missing"] or out["mismatched"] or out["unseen_trial_rows"]
            )
        )
        out["problems"] = out["problems"][:20]
        return out
    finally:
        store.close()


def _stored_value(row: dict):
    return {
        k: row.get(k) for k in ("task", "chosen_video_frame", "chosen_position", "chosen_value")
    }


def _matches(sent: dict, row: dict) -> bool:
    if sent["task"] != row["task"]:
        return False
    if sent["task"] == "pose":
        return row.get("chosen_video_frame") == sent["video_frame"]
    if sent["task"] == "view":
        return row.get("chosen_position") == sent["position"]
    return row.get("chosen_value") == sent["value"]


def warm_up(url: str, *, timeout_s: float = 120.0) -> None:
    """Open the study once and leave (no participant is created), so the server's
    one-off start work (verifying the stimuli) is not measured as the launch."""
    from .client import StreamlitClient

    async def go():
        c = StreamlitClient(url, timeout_s=timeout_s)
        await c.connect()
        try:
            await c.rerun()
        finally:
            await c.close()

    asyncio.run(go())
