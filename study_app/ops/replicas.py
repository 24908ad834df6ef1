"""Several study servers behind nginx on one PostgreSQL: the processes and their configs.

``snapshot serve --replicas N`` (``make serve-replicas N=2``) runs, all under one folder
(default ``var/replicas/``), as the user who starts it:

- one PostgreSQL (``initdb`` once into ``pg/``, its own port, its unix socket in the
  folder; as root the server runs as the ``postgres`` system user, which refuses root);
- N Streamlit processes of the study app on loopback ports, all on that database, each
  writing its script-run times to ``timings.jsonl`` (:mod:`study_app.web.timing`);
- nginx with a generated ``nginx.conf`` (pid, temp paths, logs and a media cache under
  the folder, a high port), which

  * upgrades ``/_stcore/stream`` to a websocket (``Upgrade``/``Connection`` headers,
    long read timeout);
  * routes each browser to one replica by a cookie (``snapshot_replica``) it sets on
    the first response, hashed consistently over the replicas — not by client IP, as
    Prolific participants can share one; a participant's page, websocket and media
    requests all reach the same replica;
  * checks health passively (a replica that refuses connections is taken out for
    ``fail_timeout`` and its requests go to the next one; the supervisor waits on
    ``/_stcore/health`` of every replica before nginx starts);
  * serves the stimuli once: ``/media/`` (Streamlit's media URLs are content hashes,
    the same on every replica) through an nginx cache, so each file leaves a replica
    once rather than once per participant.

A participant whose replica dies reconnects (the browser does so by itself) through
nginx to another replica, which resumes them from the ``pid`` in the URL: every
answer is in PostgreSQL the moment it is accepted, and session state holds nothing
that is not.
"""

from __future__ import annotations

import json
import os
import secrets
import shutil
import signal
import subprocess
import sys
import time
import urllib.request
from dataclasses import dataclass, field
from pathlib import Path

from snapcore.errors import SnapshotError
from study_app.data.database import ensure_postgres_database
from study_app.ops.loadtest.run import warm_up
from study_app.web.server import streamlit_command
from study_app.web.timing import ENV_TIMINGS

__all__ = [
    "ReplicaError",
    "Postgres",
    "nginx_config",
    "ReplicaSet",
    "find_pg_bin",
    "NGINX",
    "ROUTE_COOKIE",
    "STATE_FILE",
]

#: The nginx binary of Debian's package (installed by `make sysdeps`).
NGINX = "/usr/sbin/nginx"
#: The cookie that pins a browser to a replica.
ROUTE_COOKIE = "snapshot_replica"
#: What the running set writes for tools and tests: ports, pids, database URL.
STATE_FILE = "state.json"
#: Seconds to wait for a process to come up.
START_TIMEOUT_S = 90


class ReplicaError(SnapshotError):
    """A part of the replica set could not be started (its log names why)."""


def find_pg_bin() -> Path | None:
    """Folder holding ``initdb`` and ``pg_ctl`` (newest Debian version first), or None."""
    import glob

    found = sorted(
        glob.glob("/usr/lib/postgresql/*/bin/pg_ctl"),
        key=lambda p: [int(t) for t in Path(p).parents[1].name.split(".") if t.isdigit()],
        reverse=True,
    )
    if found:
        return Path(found[0]).parent
    pg_ctl = shutil.which("pg_ctl")
    return Path(pg_ctl).parent if pg_ctl else None


class Postgres:
    """A PostgreSQL server in ``root`` (initialised on first start, kept across starts).

    Parameters
    ----------
    root : Path
        Its folder: ``data/`` (the cluster), ``password``, ``server.log``, the socket.
    port : int
        TCP port on 127.0.0.1.
    """

    #: Settings for a study server: durable (fsync stays on), room for the replicas'
    #: connection pools.
    SETTINGS = {"max_connections": "200", "listen_addresses": "127.0.0.1", "shared_buffers": "64MB"}

    def __init__(self, root: Path, port: int):
        self.root = Path(root)
        self.port = port
        found = find_pg_bin()
        if found is None:
            raise ReplicaError(
                "PostgreSQL server binaries (initdb, pg_ctl) not found: "
                "apt-get install postgresql (make sysdeps)"
            )
        self.bin: Path = found
        self.as_root = os.geteuid() == 0

    def _run(self, *args: str) -> subprocess.CompletedProcess:
        cmd = [str(self.bin / args[0]), *args[1:]]
        if self.as_root:
            cmd = ["runuser", "-u", "postgres", "--", *cmd]
        r = subprocess.run(
            cmd, cwd=self.root, capture_output=True, text=True, timeout=START_TIMEOUT_S
        )
        if r.returncode != 0:
            out = " | ".join(x.strip() for x in (r.stderr or r.stdout).splitlines() if x.strip())
            raise ReplicaError(f"{args[0]} failed: {out} {_tail(self.root / 'server.log')}")
        return r

    @property
    def password(self) -> str:
        return (self.root / "password").read_text().strip()

    def start(self) -> str:
        """Start the server (``initdb`` first if needed); return the study database URL."""
        self.root.mkdir(parents=True, exist_ok=True)
        if self.as_root:
            shutil.chown(self.root, user="postgres", group="postgres")
            blocked = [p for p in self.root.parents if not os.stat(p).st_mode & 0o001]
            if blocked:
                raise ReplicaError(
                    f"PostgreSQL runs as the postgres user, who cannot enter "
                    f"{blocked[0]} (mode {oct(os.stat(blocked[0]).st_mode)[-3:]})"
                    ": choose a --run-dir it can reach"
                )
        data = self.root / "data"
        if not (data / "PG_VERSION").exists():
            pw = self.root / "password"
            pw.write_text(secrets.token_urlsafe(18) + "\n")
            pw.chmod(0o600)
            if self.as_root:
                shutil.chown(pw, user="postgres", group="postgres")
            self._run(
                "initdb",
                "-D",
                str(data),
                "-U",
                "postgres",
                "-E",
                "UTF8",
                "--locale=C",
                "--auth-local=trust",
                "--auth-host=scram-sha-256",
                f"--pwfile={pw}",
            )
        options = " ".join(f"-c {k}={v}" for k, v in self.SETTINGS.items())
        self._run(
            "pg_ctl",
            "-D",
            str(data),
            "-l",
            str(self.root / "server.log"),
            "-w",
            "-t",
            str(START_TIMEOUT_S),
            "-o",
            f"{options} -p {self.port} -k {self.root}",
            "start",
        )
        self._ensure_database("study")
        return self.url("study")

    def url(self, database: str) -> str:
        return f"postgresql+psycopg://postgres:{self.password}@127.0.0.1:{self.port}/{database}"

    def _ensure_database(self, name: str) -> None:
        ensure_postgres_database(
            host="127.0.0.1", port=self.port, user="postgres", password=self.password, name=name
        )

    def stop(self) -> None:
        if (self.root / "data" / "postmaster.pid").exists():
            try:
                self._run("pg_ctl", "-D", str(self.root / "data"), "-m", "fast", "-w", "stop")
            except ReplicaError:
                pass


def nginx_config(
    root: Path,
    *,
    port: int,
    replica_ports: list[int],
    address: str = "127.0.0.1",
    fail_timeout_s: int = 10,
    worker_user: str | None = None,
) -> str:
    """The nginx configuration of a replica set (see the module docstring).

    Parameters
    ----------
    root : Path
        Folder for the pid file, logs, temp paths and the media cache.
    port : int
        Port nginx listens on (the participants' address).
    replica_ports : list of int
        Loopback ports of the Streamlit replicas.
    worker_user : str, optional
        ``user`` directive (only meaningful when started as root: the workers then run
        as this unprivileged user, e.g. ``"nobody nogroup"``).
    """
    root = Path(root).resolve()
    servers = "\n".join(
        f"        server 127.0.0.1:{p} max_fails=1 fail_timeout={fail_timeout_s}s;"
        for p in replica_ports
    )
    proxy = """proxy_pass http://study;
            proxy_http_version 1.1;
            proxy_set_header Host $host;
            proxy_set_header X-Forwarded-For $proxy_add_x_forwarded_for;
            proxy_set_header X-Forwarded-Proto $scheme;
            # A replica that is down or restarting: try the next one (idempotent
            # requests only; an answer in flight is re-sent by the participant's browser).
            proxy_next_upstream error timeout http_502 http_503;
            proxy_connect_timeout 2s;"""
    return f"""# Generated by `snapshot serve --replicas {len(replica_ports)}` (study_app/ops/replicas.py).
{f"user {worker_user};" if worker_user else "# user: the one who started nginx"}
worker_processes 1;
pid {root}/nginx.pid;
error_log {root}/nginx-error.log warn;
daemon off;

events {{
    worker_connections 4096;
}}

http {{
    access_log {root}/nginx-access.log combined buffer=64k flush=5s;
    client_body_temp_path {root}/nginx-tmp/body;
    proxy_temp_path {root}/nginx-tmp/proxy;
    fastcgi_temp_path {root}/nginx-tmp/fastcgi;
    uwsgi_temp_path {root}/nginx-tmp/uwsgi;
    scgi_temp_path {root}/nginx-tmp/scgi;
    # Stimuli: Streamlit's media URLs are content hashes, identical on every replica.
    proxy_cache_path {root}/nginx-cache levels=1:2 keys_zone=media:10m max_size=2g
                     inactive=12h use_temp_path=off;

    map $http_upgrade $connection_upgrade {{
        default upgrade;
        ''      close;
    }}
    # The routing key: the browser's cookie, else a new random one (set below).
    map $cookie_{ROUTE_COOKIE} $route_key {{
        ''      $request_id;
        default $cookie_{ROUTE_COOKIE};
    }}
    map $cookie_{ROUTE_COOKIE} $route_set_cookie {{
        ''      "{ROUTE_COOKIE}=$request_id; Path=/; HttpOnly; SameSite=Lax";
        default "";
    }}

    upstream study {{
        hash $route_key consistent;
{servers}
        keepalive 32;
    }}

    server {{
        listen {address}:{port};
        # An empty value adds no header: only a browser without the cookie gets one.
        add_header Set-Cookie $route_set_cookie always;

        location /_stcore/stream {{
            {proxy}
            proxy_set_header Upgrade $http_upgrade;
            proxy_set_header Connection $connection_upgrade;
            proxy_read_timeout 1h;
            proxy_send_timeout 1h;
            proxy_buffering off;
        }}

        location /media/ {{
            {proxy}
            proxy_set_header Connection "";
            proxy_cache media;
            proxy_cache_key $uri;
            proxy_cache_valid 200 206 12h;
            proxy_cache_lock on;
            # Range requests (video seeking) are answered from the cached whole file.
            proxy_force_ranges on;
        }}

        location / {{
            {proxy}
            proxy_set_header Connection "";
        }}
    }}
}}
"""


def _free_port() -> int:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def _tail(path: Path | None, n: int = 600) -> str:
    """The end of a log file on one line (errors are shown in one line)."""
    if path is None or not Path(path).exists():
        return ""
    text = Path(path).read_text(errors="replace")[-n:]
    return " | ".join(line.strip() for line in text.splitlines() if line.strip())


def wait_healthy(
    url: str,
    *,
    proc: subprocess.Popen | None = None,
    timeout_s: float = START_TIMEOUT_S,
    log: Path | None = None,
) -> None:
    """Wait until ``url``/_stcore/health answers ok (raise ReplicaError on timeout)."""
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        try:
            with urllib.request.urlopen(url.rstrip("/") + "/_stcore/health", timeout=2) as r:
                if r.read() == b"ok":
                    return
        except OSError:
            pass
        if proc is not None and proc.poll() is not None:
            break
        time.sleep(0.2)
    raise ReplicaError(f"{url} did not become healthy: {_tail(log)}")


@dataclass
class ReplicaSet:
    """N study servers, nginx in front, one database; :meth:`start`, :meth:`stop`.

    Parameters
    ----------
    root : Path
        Folder of everything the set runs (``var/replicas``).
    n : int
        Streamlit replicas.
    port : int
        nginx's port (the participants' address).
    stimuli : Path
        The verified stimuli folder every replica serves.
    db_url : str, optional
        An existing database; default: a PostgreSQL of the set's own under ``root/pg``.
    pg_port : int, optional
        Port of that PostgreSQL (default: a free one).
    """

    root: Path
    n: int
    port: int
    stimuli: Path
    db_url: str | None = None
    pg_port: int | None = None
    replica_ports: list = field(default_factory=list)
    replicas: list = field(default_factory=list)  # Popen
    nginx: subprocess.Popen | None = None
    postgres: Postgres | None = None

    def start(self, *, env: dict | None = None) -> ReplicaSet:
        self.root = Path(self.root).resolve()
        self.root.mkdir(parents=True, exist_ok=True)
        if not os.access(NGINX, os.X_OK):
            raise ReplicaError(f"nginx not found at {NGINX}: apt-get install nginx (make sysdeps)")
        try:
            if self.db_url is None:
                self.postgres = Postgres(self.root / "pg", self.pg_port or _free_port())
                self.db_url = self.postgres.start()
            base_env = {
                **os.environ,
                **(env or {}),
                "SNAPSHOT_STIMULI": str(self.stimuli),
                "SNAPSHOT_DB": self.db_url,
                ENV_TIMINGS: str(self.root / "timings.jsonl"),
            }
            base_env.setdefault("PYOPENGL_PLATFORM", "egl")
            self.replica_ports = [_free_port() for _ in range(self.n)]
            for i, p in enumerate(self.replica_ports):
                self.replicas.append(self._start_replica(i, p, base_env))
            for i, (p, proc) in enumerate(zip(self.replica_ports, self.replicas, strict=True)):
                wait_healthy(f"http://127.0.0.1:{p}", proc=proc, log=self.root / f"replica-{i}.log")
                # Open the app once: each process verifies the stimuli on its first
                # script run (seconds), which must not be a participant's first page.
                warm_up(f"http://127.0.0.1:{p}")
            # nginx creates its temp and cache folders itself, owned by its workers.
            (self.root / "nginx-tmp").mkdir(exist_ok=True)
            conf = self.root / "nginx.conf"
            # As root, the workers (which talk to participants) drop to nobody.
            conf.write_text(
                nginx_config(
                    self.root,
                    port=self.port,
                    replica_ports=self.replica_ports,
                    worker_user="nobody nogroup" if os.geteuid() == 0 else None,
                )
            )
            # -p: nginx's prefix is the folder, so nothing is written under /var/lib/nginx.
            cmd = [
                NGINX,
                "-p",
                str(self.root),
                "-c",
                str(conf),
                "-e",
                str(self.root / "nginx-error.log"),
            ]
            check = subprocess.run([*cmd, "-t"], capture_output=True, text=True)
            if check.returncode != 0:
                raise ReplicaError(
                    f"nginx rejected {conf}: " + " | ".join(check.stderr.strip().splitlines())
                )
            self.nginx = subprocess.Popen(cmd, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
            wait_healthy(self.url, proc=self.nginx, log=self.root / "nginx-error.log")
            self.write_state()
        except BaseException:
            self.stop()
            raise
        return self

    def _start_replica(self, i: int, port: int, env: dict) -> subprocess.Popen:
        log = open(self.root / f"replica-{i}.log", "w")  # noqa: SIM115 - the child keeps it
        try:
            return subprocess.Popen(
                streamlit_command(port=port, address="127.0.0.1"),
                env=env,
                stdout=log,
                stderr=subprocess.STDOUT,
            )
        finally:
            log.close()

    @property
    def url(self) -> str:
        return f"http://127.0.0.1:{self.port}/"

    def state(self) -> dict:
        return {
            "url": self.url,
            "db_url": self.db_url,
            "nginx_pid": self.nginx.pid if self.nginx else None,
            "replicas": [
                {"port": p, "pid": proc.pid}
                for p, proc in zip(self.replica_ports, self.replicas, strict=False)
            ],
            "timings": str(self.root / "timings.jsonl"),
            "postgres_port": self.postgres.port if self.postgres else None,
        }

    def write_state(self) -> None:
        (self.root / STATE_FILE).write_text(json.dumps(self.state(), indent=1) + "\n")

    def stop(self) -> None:
        """Stop nginx, the replicas and the set's PostgreSQL (data kept under root/pg)."""
        procs = [p for p in [self.nginx, *self.replicas] if p is not None]
        for p in procs:
            if p.poll() is None:
                p.send_signal(signal.SIGTERM)
        for p in procs:
            try:
                p.wait(timeout=15)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
        if self.postgres is not None:
            self.postgres.stop()
        state = self.root / STATE_FILE
        if state.exists():
            state.unlink()


def main_loop(rs: ReplicaSet) -> None:
    """Run until SIGINT/SIGTERM, then stop everything (the supervisor of the set)."""
    stopping = []

    def handler(signum, frame):
        stopping.append(signum)

    signal.signal(signal.SIGTERM, handler)
    signal.signal(signal.SIGINT, handler)
    try:
        while not stopping:
            if rs.nginx is not None and rs.nginx.poll() is not None:
                print("nginx stopped; stopping the replicas", file=sys.stderr)
                break
            time.sleep(0.5)
    finally:
        rs.stop()
