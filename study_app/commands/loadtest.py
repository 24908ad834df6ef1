"""``snapshot loadtest``: simulated participants through a running study, measured."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import click

from snapcore.cli.common import FiniteFloatRange
from snapcore.errors import SnapshotError

__all__ = ["loadtest", "LoadTestError", "format_report"]


class LoadTestError(SnapshotError):
    """The study cannot be load-tested as asked (unreachable, bad database URL...)."""


def _check_reachable(url: str) -> None:
    import urllib.error
    import urllib.request

    health = url.rstrip("/") + "/_stcore/health"
    try:
        with urllib.request.urlopen(health, timeout=10) as r:
            if r.read().strip() != b"ok":
                raise LoadTestError(
                    f"{url} answers, but not as a Streamlit study (health: {health})"
                )
    except (urllib.error.URLError, OSError, ValueError) as err:
        reason = getattr(err, "reason", err)
        raise LoadTestError(f"cannot reach the study at {url}: {reason}") from None


def format_report(report: dict) -> str:
    """The report as a short table (what ``--json`` writes in full)."""
    from tabulate import tabulate

    rows = []
    for action, s in report["latency"].items():
        if s["n"]:
            rows.append(
                [
                    action,
                    s["n"],
                    f"{s['p50'] * 1000:.0f}",
                    f"{s['p95'] * 1000:.0f}",
                    f"{s['max'] * 1000:.0f}",
                ]
            )
    runs = report.get("server_script_runs")
    if runs and runs["n"]:
        rows.append(
            [
                "(server script run)",
                runs["n"],
                f"{runs['p50'] * 1000:.0f}",
                f"{runs['p95'] * 1000:.0f}",
                f"{runs['max'] * 1000:.0f}",
            ]
        )
    out = [tabulate(rows, headers=["action", "n", "p50 ms", "p95 ms", "max ms"])]
    c = report["config"]
    out.append(
        f"participants {report['completed']}/{report['participants']} completed "
        f"in {report['elapsed_s']:.0f} s ({c['driver']} driver, think {c['think_s']} s, "
        f"ramp {c['ramp_s']} s); errors {report['errors']['count']}, reconnects "
        f"{report['reconnects']}"
    )
    s = report.get("server") or {}
    if s:
        out.append(
            f"server ({s['processes']} process(es)): CPU {s['cpu_share'] * 100:.0f}% of "
            f"one core, memory {s['rss_start_mb']:.0f} -> {s['rss_peak_mb']:.0f} MB "
            f"({s.get('rss_per_session_mb', 0):.2f} MB per session)"
        )
    db = report.get("database")
    if db:
        out.append(
            f"database: {db['participants_found']}/{db['participants_expected']} "
            f"participants, {db['answers_stored_once']}/{db['answers_sent']} answers "
            f"stored once as sent, {db['duplicates']} duplicated, {db['missing']} "
            f"missing, {db['unseen_trial_rows']} rows for unseen trials: "
            + ("OK" if db["ok"] else "FAILED")
        )
    for e in report["errors"]["first"][:5]:
        out.append(f"  error: {e}")
    return "\n".join(out)


@click.command()
@click.option(
    "--url",
    required=True,
    metavar="URL",
    help="The running study (snapshot study, or nginx before replicas).",
)
@click.option(
    "-n",
    "--participants",
    type=click.IntRange(1, 5000),
    default=20,
    show_default=True,
    help="Simulated participants.",
)
@click.option(
    "--ramp",
    type=FiniteFloatRange(0),
    default=30.0,
    show_default=True,
    help="Seconds over which they arrive (evenly).",
)
@click.option(
    "--think",
    type=FiniteFloatRange(0),
    default=2.0,
    show_default=True,
    help="Mean seconds before each answer (uniform 0.5-1.5 x this).",
)
@click.option(
    "--seed",
    type=int,
    default=0,
    show_default=True,
    help="Seeds every choice and who reloads / goes Back / double-clicks.",
)
@click.option(
    "--reload",
    "reload_share",
    type=FiniteFloatRange(0, 1),
    default=0.1,
    show_default=True,
    help="Share of participants who reload once mid-study.",
)
@click.option(
    "--back",
    "back_share",
    type=FiniteFloatRange(0, 1),
    default=0.1,
    show_default=True,
    help="Share who go Back to the study link once.",
)
@click.option(
    "--double-click",
    "double_share",
    type=FiniteFloatRange(0, 1),
    default=0.1,
    show_default=True,
    help="Share who double-click one answer.",
)
@click.option(
    "--driver",
    type=click.Choice(["protocol", "browser"]),
    default="protocol",
    show_default=True,
    help="protocol: websocket clients, hundreds per process (measures the "
    "server); browser: headless Chromium via Playwright (a few at a time).",
)
@click.option(
    "--db",
    "db_url",
    metavar="URL",
    default=None,
    help="The study's database: checked afterwards (participants, one answer "
    "per trial as sent, nothing for unseen trials).",
)
@click.option(
    "--server-pid",
    "server_pids",
    type=int,
    multiple=True,
    help="Server process to measure (CPU, memory); repeat for replicas. "
    "Default: whatever listens on the URL's port on this machine.",
)
@click.option(
    "--timings",
    "timings",
    type=click.Path(dir_okay=False),
    multiple=True,
    help="The servers' $SNAPSHOT_TIMINGS file(s): adds the server-side time per script run.",
)
@click.option(
    "--json",
    "json_path",
    type=click.Path(dir_okay=False),
    default=None,
    help="Write the full report (data_schema/loadtest.schema.json) here; '-' for stdout.",
)
@click.option(
    "--timeout",
    "timeout_s",
    type=FiniteFloatRange(1),
    default=120.0,
    show_default=True,
    help="Longest wait for one interaction (s).",
)
def loadtest(
    url,
    participants,
    ramp,
    think,
    seed,
    reload_share,
    back_share,
    double_share,
    driver,
    db_url,
    server_pids,
    timings,
    json_path,
    timeout_s,
):
    """Drive simulated participants through a running study, from consent to the
    completion code, and report what the server did.

    Each participant opens the study link (with Prolific parameters), agrees, answers
    the background questions, every pose task (a log batch saying the animation was
    watched, then a random frame), view task (a random position) and the attention
    check, and reads the completion code; all choices are valid, random and seeded.
    Reported: per-action latency (p50/p95/max, end to end), errors, the server's CPU
    and memory per session, the server's own time per script run (--timings), and the
    database check (--db). Exit code 1 when a participant did not finish or the
    database check fails.

    Example, 100 participants arriving over a minute, against a local study:

    \b
      SNAPSHOT_TIMINGS=var/timings.jsonl snapshot study --db sqlite:///var/load.db &
      snapshot loadtest --url http://127.0.0.1:8501 -n 100 --ramp 60 --think 2 \\
          --db sqlite:///var/load.db --timings var/timings.jsonl --json var/load.json
    """
    from urllib.parse import urlsplit

    _check_reachable(url)
    if db_url:
        from study_app.data.store import Store

        try:
            Store(db_url).close()
        except SnapshotError:
            raise
        except Exception as err:  # noqa: BLE001 - a driver's message, one line
            raise LoadTestError(f"cannot open the database {db_url}: {err}") from None
    pids = list(server_pids)
    if not pids:
        from study_app.ops.loadtest.run import server_pids_for_port

        parts = urlsplit(url)
        if parts.hostname in ("127.0.0.1", "localhost", "::1"):
            pids = server_pids_for_port(parts.port or 80)
    from study_app.ops.loadtest.run import run_load, warm_up

    # The server's one-off start work (verifying the stimuli) is not the launch.
    warm_up(url, timeout_s=timeout_s)
    if driver == "browser":
        from study_app.ops.loadtest.browser import run_browsers

        report, _ = run_browsers(
            url,
            participants,
            ramp_s=ramp,
            think_s=think,
            seed=seed,
            server_pids=pids,
            timings=timings,
            db_url=db_url,
        )
    else:
        report, _ = run_load(
            url,
            participants,
            ramp_s=ramp,
            think_s=think,
            seed=seed,
            reload=reload_share,
            back=back_share,
            double_click=double_share,
            server_pids=pids,
            timings=timings,
            db_url=db_url,
            timeout_s=timeout_s,
        )
    from snapcore.schema import validate

    validate(report, "loadtest", source="the load-test report")
    if json_path:
        text = json.dumps(report, indent=1)
        if json_path == "-":
            click.echo(text)
        else:
            Path(json_path).write_text(text + "\n", encoding="utf-8")
    click.echo(format_report(report), err=json_path == "-")
    failed = report["completed"] < report["participants"] or (
        report.get("database") and not report["database"]["ok"]
    )
    if failed:
        sys.exit(1)
