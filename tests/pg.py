"""A throw-away PostgreSQL server for tests: real server, temporary data directory.

``PostgresServer`` finds ``initdb``/``pg_ctl`` (``/usr/lib/postgresql/*/bin`` or PATH),
makes a data directory under the system temp folder, starts the server on a free
loopback port (its unix socket in the same temp folder, so it never touches
``/var/run/postgresql``), and deletes everything on ``stop()``. Tuned for speed, not
durability (``fsync=off``, small ``shared_buffers``): it holds test data only.

PostgreSQL refuses to run as root. When the tests run as root (containers, CI), the
server binaries run as the ``postgres`` system user (created by Debian's ``postgresql``
package) through ``runuser``, and the temp folder is handed to that user.

Fixtures (registered in ``conftest.py``, so each test worker starts one server):

- ``pg_server`` (session): the running :class:`PostgresServer`; skips locally and
  fails in CI (``tests/conftest.py``'s ``need``) when PostgreSQL is not installed.
- ``pg_url`` (function): an empty database on that server (emptied before each test),
  as a SQLAlchemy URL
  ``postgresql+psycopg://postgres:<password>@127.0.0.1:<port>/<db>``.
"""

from __future__ import annotations

import glob
import os
import shutil
import socket
import subprocess
import tempfile
import time
from pathlib import Path

import pytest

__all__ = ["PostgresServer", "find_pg_bin", "pg_server", "pg_url", "PG_PASSWORD"]

#: Password of the ``postgres`` role over TCP (the server only listens on 127.0.0.1).
PG_PASSWORD = "snapshot-test"
#: Seconds to wait for the server to accept connections.
START_TIMEOUT_S = 60
#: Server settings for a fast, disposable server (durability is irrelevant here).
FAST_SETTINGS = {
    "fsync": "off",
    "synchronous_commit": "off",
    "full_page_writes": "off",
    "shared_buffers": "16MB",
    "max_connections": "120",
    "listen_addresses": "127.0.0.1",
    "log_min_messages": "warning",
}


def find_pg_bin() -> Path | None:
    """Folder holding ``initdb`` and ``pg_ctl`` (newest Debian version first), or None."""
    candidates = sorted(
        glob.glob("/usr/lib/postgresql/*/bin"),
        key=lambda p: [int(t) for t in Path(p).parent.name.split(".") if t.isdigit()],
        reverse=True,
    )
    for folder in candidates:
        if os.access(Path(folder) / "initdb", os.X_OK) and os.access(
            Path(folder) / "pg_ctl", os.X_OK
        ):
            return Path(folder)
    initdb, pg_ctl = shutil.which("initdb"), shutil.which("pg_ctl")
    if initdb and pg_ctl and Path(initdb).parent == Path(pg_ctl).parent:
        return Path(initdb).parent
    return None


def _free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class PostgresServer:
    """A PostgreSQL server in a temporary folder; ``start()``, ``url(db)``, ``stop()``.

    Parameters
    ----------
    bin_dir : Path, optional
        Folder of the server binaries (default: :func:`find_pg_bin`).
    """

    def __init__(self, bin_dir: Path | None = None):
        self.bin_dir = bin_dir or find_pg_bin()
        if self.bin_dir is None:
            raise RuntimeError("PostgreSQL server binaries (initdb, pg_ctl) not found")
        self.as_root = os.geteuid() == 0
        self.root: Path | None = None
        self.port: int | None = None
        self.start_seconds: float | None = None
        self._n_databases = 0

    # -- processes ---------------------------------------------------------------------
    def _run(self, *args: str, check: bool = True) -> subprocess.CompletedProcess:
        cmd = [str(self.bin_dir / args[0]), *args[1:]]
        if self.as_root:
            cmd = ["runuser", "-u", "postgres", "--", *cmd]
        # cwd: the postgres user may not be allowed into the caller's working folder.
        proc = subprocess.run(
            cmd, cwd=self.root, capture_output=True, text=True, timeout=START_TIMEOUT_S
        )
        if check and proc.returncode != 0:
            log = ""
            if self.root is not None and (self.root / "server.log").exists():
                log = (self.root / "server.log").read_text(errors="replace")[-2000:]
            raise RuntimeError(
                f"{' '.join(cmd)} failed ({proc.returncode}):\n{proc.stdout}\n{proc.stderr}\n{log}"
            )
        return proc

    def start(self) -> PostgresServer:
        """Create the data directory, start the server, wait until it accepts connections."""
        t0 = time.perf_counter()
        self.root = Path(tempfile.mkdtemp(prefix="snapshot-pg-"))
        if self.as_root:
            shutil.chown(self.root, user="postgres", group="postgres")
        data = self.root / "data"
        pwfile = self.root / "pw"
        pwfile.write_text(PG_PASSWORD + "\n")
        if self.as_root:
            shutil.chown(pwfile, user="postgres", group="postgres")
        # Local socket: trust (the fixture creates databases); TCP: password, so that a
        # wrong password in a URL is a real authentication failure.
        self._run(
            "initdb",
            "-D",
            str(data),
            "-U",
            "postgres",
            "-E",
            "UTF8",
            "--locale=C",
            "--no-sync",
            "--auth-local=trust",
            "--auth-host=scram-sha-256",
            f"--pwfile={pwfile}",
        )
        pwfile.unlink()
        last_error = None
        for _ in range(3):  # the free port can be taken between choosing and binding
            self.port = _free_port()
            options = " ".join(f"-c {k}={v}" for k, v in FAST_SETTINGS.items())
            options += f" -p {self.port} -k {self.root}"
            proc = self._run(
                "pg_ctl",
                "-D",
                str(data),
                "-l",
                str(self.root / "server.log"),
                "-w",
                "-t",
                str(START_TIMEOUT_S),
                "-o",
                options,
                "start",
                check=False,
            )
            if proc.returncode == 0:
                break
            last_error = proc.stdout + proc.stderr
        else:
            self.stop()
            raise RuntimeError(f"PostgreSQL did not start: {last_error}")
        self.start_seconds = time.perf_counter() - t0
        return self

    def stop(self) -> None:
        """Stop the server (fast shutdown) and delete its folder."""
        if self.root is None:
            return
        data = self.root / "data"
        if (data / "postmaster.pid").exists():
            self._run("pg_ctl", "-D", str(data), "-m", "fast", "-w", "stop", check=False)
        shutil.rmtree(self.root, ignore_errors=True)
        self.root = None

    # -- databases ---------------------------------------------------------------------
    def url(self, database: str = "postgres", *, password: str | None = PG_PASSWORD) -> str:
        """SQLAlchemy URL of ``database`` over TCP on the loopback port."""
        auth = f"postgres:{password}" if password is not None else "postgres"
        return f"postgresql+psycopg://{auth}@127.0.0.1:{self.port}/{database}"

    def create_database(self, name: str | None = None) -> str:
        """Create an empty database and return its SQLAlchemy URL."""
        import psycopg

        self._n_databases += 1
        name = name or f"test_{os.getpid()}_{self._n_databases}"
        with psycopg.connect(
            host="127.0.0.1",
            port=self.port,
            user="postgres",
            password=PG_PASSWORD,
            dbname="postgres",
            autocommit=True,
        ) as conn:
            conn.execute(f'CREATE DATABASE "{name}"')
        return self.url(name)

    def reset_database(self, name: str = "store_test") -> str:
        """A database emptied for the next test (much faster than creating one); its URL.

        Created on first use; later calls end every other connection to it and replace
        its ``public`` schema by an empty one.
        """
        import psycopg

        params = dict(
            host="127.0.0.1", port=self.port, user="postgres", password=PG_PASSWORD, autocommit=True
        )
        with psycopg.connect(dbname="postgres", **params) as conn:
            exists = conn.execute(
                "SELECT 1 FROM pg_database WHERE datname = %s", (name,)
            ).fetchone()
            if not exists:
                conn.execute(f'CREATE DATABASE "{name}"')
                return self.url(name)
            conn.execute(
                "SELECT pg_terminate_backend(pid) FROM pg_stat_activity "
                "WHERE datname = %s AND pid <> pg_backend_pid()",
                (name,),
            )
        with psycopg.connect(dbname=name, **params) as conn:
            conn.execute("DROP SCHEMA public CASCADE")
            conn.execute("CREATE SCHEMA public")
        return self.url(name)

    def __enter__(self) -> PostgresServer:
        return self.start()

    def __exit__(self, *exc) -> None:
        self.stop()


@pytest.fixture(scope="session")
def pg_server():
    """A running PostgreSQL server for the whole test session (stopped and deleted after)."""
    from conftest import need

    bin_dir = find_pg_bin()
    need(
        bin_dir is not None,
        "PostgreSQL server binaries not found (apt-get install postgresql; `make test` does it)",
    )
    if os.geteuid() == 0:
        import pwd

        try:
            pwd.getpwnam("postgres")
            have_user = True
        except KeyError:
            have_user = False
        need(
            have_user,
            "running as root and there is no 'postgres' system user to run "
            "the server as (Debian's postgresql package creates it)",
        )
    server = PostgresServer(bin_dir)
    server.start()
    try:
        yield server
    finally:
        server.stop()


@pytest.fixture
def pg_url(pg_server) -> str:
    """URL of an empty database on the session's PostgreSQL server (emptied per test)."""
    return pg_server.reset_database()
