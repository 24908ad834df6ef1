"""Replicas behind nginx on one PostgreSQL: a replica dying mid-launch loses nothing.

``snapshot serve --replicas 2`` (its own PostgreSQL under the run folder, two Streamlit
processes, nginx with the generated config) serves the tiny study; ten simulated
participants (the protocol-level load-test driver) go through it, and one replica is
killed (SIGKILL, as a crash) while they are mid-study. Its participants' connections
drop; they reconnect through nginx, land on the other replica and resume from the pid
in their URL. The database must then hold every participant once, every answer they
sent exactly once and as sent, and their completion codes.
"""

from __future__ import annotations

import json
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import pytest
import test_e2e
from conftest import need
from test_e2e import free_port

from study_app.data.store import Store
from study_app.ops.loadtest.run import run_load
from study_app.ops.replicas import NGINX, find_pg_bin

#: The tiny demo stimuli, built once per session (the browser tests' fixture).
stimuli_dir = test_e2e.stimuli_dir

pytestmark = [pytest.mark.slow]

SNAPSHOT = str(Path(sys.executable).with_name("snapshot"))
#: Seconds for the set (initdb, two servers, nginx) to come up.
START_S = 90
N_PARTICIPANTS = 10
#: Seconds into the run when replica 0 is killed (everyone has arrived, nobody is done).
KILL_AT_S = 10.0


@pytest.fixture
def replica_set(stimuli_dir, tmp_path):
    """`snapshot serve --replicas 2` running; yields its state (url, pids, db url)."""
    need(os.access(NGINX, os.X_OK), f"no nginx at {NGINX} (make sysdeps installs it)")
    need(find_pg_bin() is not None, "PostgreSQL server binaries not found")
    # As root, PostgreSQL runs as the postgres user, who cannot enter pytest's private
    # (0700) temp folders: the set's folder is a world-traversable one of its own.
    run_dir = Path(tempfile.mkdtemp(prefix="snapshot-replicas-"))
    run_dir.chmod(0o755)
    log = tmp_path / "serve.log"
    with open(log, "w") as f:
        proc = subprocess.Popen(
            [
                SNAPSHOT,
                "serve",
                "--replicas",
                "2",
                "--stimuli",
                str(stimuli_dir),
                "--port",
                str(free_port()),
                "--run-dir",
                str(run_dir),
            ],
            stdout=f,
            stderr=subprocess.STDOUT,
        )
    state_file = run_dir / "state.json"
    deadline = time.monotonic() + START_S
    while not state_file.exists():
        if proc.poll() is not None or time.monotonic() > deadline:
            proc.kill()
            pytest.fail(f"the replica set did not start:\n{log.read_text()}")
        time.sleep(0.2)
    state = json.loads(state_file.read_text())
    yield state
    proc.send_signal(signal.SIGINT)
    try:
        proc.wait(timeout=30)
    except subprocess.TimeoutExpired:
        proc.kill()
        proc.wait()
    shutil.rmtree(run_dir, ignore_errors=True)


def test_a_replica_killed_mid_run_loses_and_duplicates_no_answer(replica_set):
    """Every participant finishes and every answer is stored once, though a replica died."""
    victim = replica_set["replicas"][0]["pid"]
    killed_at = []

    def kill_one(elapsed_s):
        if not killed_at and elapsed_s >= KILL_AT_S:
            os.kill(victim, signal.SIGKILL)
            killed_at.append(elapsed_s)

    report, results = run_load(
        replica_set["url"],
        N_PARTICIPANTS,
        ramp_s=2.0,
        think_s=2.0,
        seed=16,
        timeout_s=30.0,
        db_url=replica_set["db_url"],
        timings=[replica_set["timings"]],
        during=kill_one,
    )
    assert killed_at, "the run ended before the replica was killed"
    # Someone was on the killed replica mid-study, reconnected and went on elsewhere.
    moved = [r for r in results if r.reconnects]
    assert moved, "no participant was on the killed replica (routing not spread?)"
    assert all(r.completion_code for r in results), [r.errors for r in results]
    db = report["database"]
    assert db["ok"], db["problems"]
    # Straight from the database too: 10 participants, 5 trials each, no duplicate row.
    store = Store(replica_set["db_url"])
    try:
        ours = {r.prolific_pid for r in results}
        parts = [p for p in store.participants() if p["prolific_pid"] in ours]
        assert len(parts) == N_PARTICIPANTS
        assert all(p["completion_code"] for p in parts)
        for p in parts:
            rows = store.responses(p["participant_id"])
            trials = [row["trial_index"] for row in rows]
            assert sorted(trials) == list(range(5)), (p["participant_id"], trials)
    finally:
        store.close()
    # Both replicas served script runs (the routing spreads participants).
    pids = {
        json.loads(line)["pid"]
        for line in Path(replica_set["timings"]).read_text().splitlines()
        if line.strip()
    }
    assert len(pids) == 2


def test_serve_with_a_broken_database_url_is_one_line_exit_2(stimuli_dir):
    """`snapshot serve --db` with a database that cannot be opened: one line, exit 2,
    before any process starts."""
    from click.testing import CliRunner

    from snapcore.cli.main import cli

    r = CliRunner().invoke(
        cli,
        [
            "serve",
            "--stimuli",
            str(stimuli_dir),
            "--db",
            "postgresql+psycopg://nobody@127.0.0.1:9/none",
        ],
    )
    assert r.exit_code == 2, r.output
    assert "cannot open database" in r.output and "Traceback" not in r.output
    assert len(r.output.strip().splitlines()) == 1


def test_nginx_config_routes_by_cookie_upgrades_websockets_and_is_valid(tmp_path):
    """The generated config passes `nginx -t`, routes by the participant's cookie (not
    the client IP), upgrades the websocket, and caches the stimuli."""
    from study_app.ops.replicas import ROUTE_COOKIE, nginx_config

    need(os.access(NGINX, os.X_OK), f"no nginx at {NGINX} (make sysdeps installs it)")
    (tmp_path / "nginx-tmp").mkdir()
    conf = tmp_path / "nginx.conf"
    text = nginx_config(
        tmp_path,
        port=free_port(),
        replica_ports=[18001, 18002, 18003],
        worker_user="nobody nogroup" if os.geteuid() == 0 else None,
    )
    conf.write_text(text)
    r = subprocess.run(
        [NGINX, "-t", "-p", str(tmp_path), "-c", str(conf), "-e", str(tmp_path / "error.log")],
        capture_output=True,
        text=True,
    )
    assert r.returncode == 0, r.stderr
    assert f"map $cookie_{ROUTE_COOKIE} $route_key" in text
    assert "hash $route_key consistent;" in text and "ip_hash" not in text
    assert text.count("server 127.0.0.1:1800") == 3
    assert "proxy_set_header Upgrade $http_upgrade;" in text
    assert "proxy_set_header Connection $connection_upgrade;" in text
    assert "proxy_cache media;" in text
    # Everything nginx writes stays in the folder.
    for line in text.splitlines():
        if line.strip().startswith(("pid ", "error_log ", "access_log ", "proxy_temp_path ")):
            assert str(tmp_path.resolve()) in line, line
