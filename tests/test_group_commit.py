"""Group commit: concurrent SQLite writes share transactions, and each still gets its
own outcome (study_app.data.group_commit, used by the store for every study write)."""

from __future__ import annotations

import threading
import time
from concurrent.futures import ThreadPoolExecutor

import pytest
import sqlalchemy as sa

from study_app.data.errors import StoreError
from study_app.data.group_commit import GroupCommit
from study_app.data.store import Store


class _Recorder:
    """A stand-in transaction: records which jobs committed together (no database),
    and can be slowed so that writers queue behind it."""

    def __init__(self, commit_s: float = 0.0):
        self.committed: list[list] = []
        self.commit_s = commit_s

    def begin(self):
        rec = self

        class _Tx:
            def __enter__(self):
                self.rows = []
                return self.rows

            def __exit__(self, exc_type, *_):
                if exc_type is None:
                    time.sleep(rec.commit_s)
                    rec.committed.append(list(self.rows))
                return False

        return _Tx()


def test_a_lone_write_commits_alone_and_returns_its_value():
    rec = _Recorder()
    group = GroupCommit(rec.begin)
    assert group.run(lambda rows: rows.append("a") or 7) == 7
    assert rec.committed == [["a"]]


def test_writes_queued_during_a_commit_share_the_next_one():
    """20 threads write while each commit takes 50 ms: every write commits exactly once
    and far fewer transactions than writes are used."""
    rec = _Recorder(commit_s=0.05)
    group = GroupCommit(rec.begin)
    start = threading.Barrier(20)

    def write(i):
        start.wait()
        return group.run(lambda rows: rows.append(i) or i * 10)

    with ThreadPoolExecutor(20) as pool:
        values = list(pool.map(write, range(20)))
    assert values == [i * 10 for i in range(20)]
    flat = [i for batch in rec.committed for i in batch]
    assert sorted(flat) == list(range(20))
    # The first writer commits alone; the 19 that queued meanwhile need a few commits.
    assert len(rec.committed) <= 5, rec.committed
    assert group.jobs == 20 and group.batches == len(rec.committed)


def test_a_failing_write_gets_its_error_and_its_neighbours_are_stored():
    """One job of a batch raises: the batch is retried job by job, the bad job's caller
    gets its own exception, everyone else's write commits once."""
    rec = _Recorder(commit_s=0.05)
    group = GroupCommit(rec.begin)
    start = threading.Barrier(10)

    def write(i):
        start.wait()

        def work(rows):
            if i == 5:
                raise StoreError("bad row 5")
            rows.append(i)
            return i

        try:
            return group.run(work)
        except StoreError as err:
            return str(err)

    with ThreadPoolExecutor(10) as pool:
        values = list(pool.map(write, range(10)))
    assert values == [*range(5), "bad row 5", *range(6, 10)]
    flat = [i for batch in rec.committed for i in batch]
    assert sorted(flat) == [0, 1, 2, 3, 4, 6, 7, 8, 9]


def test_a_job_cannot_write_again_from_inside_its_batch():
    group = GroupCommit(_Recorder().begin)
    with pytest.raises(RuntimeError, match="cannot start another write"):
        group.run(lambda rows: group.run(lambda r: None))


def test_store_writes_from_many_threads_share_sqlite_transactions(tmp_path):
    """Through the real store on SQLite: 40 threads each record an event at once; all
    40 rows are there and fewer than 40 transactions were committed."""
    store = Store(f"sqlite:///{tmp_path / 'g.db'}")
    pid = store.create_participant("s", "0" * 64, app_version="v", seed=1)
    start = threading.Barrier(40)

    def write(i):
        start.wait()
        store.record_event(pid, i, "play", {"i": i})

    before = store._group.batches
    with ThreadPoolExecutor(40) as pool:
        list(pool.map(write, range(40)))
    got = sorted(e["payload"]["i"] for e in store.events(pid))
    assert got == list(range(40))
    batches = store._group.batches - before
    print(f"\n40 concurrent writes in {batches} transactions")
    assert batches < 40
    with store.engine.connect() as conn:
        assert conn.execute(sa.text("SELECT count(*) FROM events")).scalar() == 40
    store.close()
