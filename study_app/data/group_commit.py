"""Group commit: the writes that queue while one SQLite transaction commits share the next.

SQLite has one writer at a time. In the study server every participant's answer is a
write from a Streamlit script thread, and all those threads share one interpreter lock
(GIL). Each statement of a transaction hands the GIL to another thread (the ``sqlite3``
module releases it around every call into SQLite) and waits for it to come back, so under
load a write transaction holds the database for many GIL turns, not for its few hundred
microseconds of work, and the writers queue behind it (measured at 100 participants:
~11 ms per commit, almost all of it waiting for the GIL; see docs/capacity.md).

:class:`GroupCommit` makes that queue useful. A writer enqueues its work, a function of
an open connection. If no transaction is running, it becomes the *leader*: it opens one
write transaction, runs every queued job in it, in arrival order, commits once and hands
each job its result; the writers that queued meanwhile wait and the next of them leads
the next batch. Under load one BEGIN and one COMMIT serve many answers; alone, a writer
runs its own job at once, as before.

Every job still returns only after the commit that made it durable. A job that fails
(its own :class:`~study_app.data.errors.StoreError`, a constraint) would roll back the whole
batch, so the batch is then run again one job per transaction: the failing job gets its
error, the others are stored. Jobs must therefore touch nothing but the connection (they
may run twice when a neighbour fails).
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from contextlib import AbstractContextManager
from typing import Any

__all__ = ["GroupCommit"]


class _Job:
    """One writer's work and, once its batch committed, its outcome."""

    __slots__ = ("work", "value", "error", "done")

    def __init__(self, work):
        self.work = work
        self.value = None
        self.error: BaseException | None = None
        self.done = False


class GroupCommit:
    """Run write jobs of many threads in shared transactions, one transaction at a time.

    Parameters
    ----------
    begin : callable
        ``begin()`` returns a context manager yielding a connection inside one write
        transaction, committed on a clean exit and rolled back on an exception
        (:meth:`study_app.data.store.Store.transaction` with ``write=True``).
    max_batch : int
        Most jobs in one transaction, so that one slow batch does not hold every
        waiting writer.

    Notes
    -----
    ``batches`` and ``jobs`` count what ran (for tests and measurements).
    """

    def __init__(self, begin: Callable[[], AbstractContextManager], *, max_batch: int = 64):
        self._begin = begin
        self._max_batch = max_batch
        self._cv = threading.Condition(threading.Lock())
        self._queue: list[_Job] = []
        self._leading = False
        # the thread running a batch (a job may not write again)
        self._leader: threading.Thread | None = None
        self.batches = 0
        self.jobs = 0

    def run(self, work: Callable[[Any], Any]) -> Any:
        """Run ``work(conn)`` in a committed write transaction; return its value.

        Raises whatever ``work`` or the commit raised for this job.
        """
        if self._leader is threading.current_thread():
            raise RuntimeError("a group-commit job cannot start another write")
        job = _Job(work)
        with self._cv:
            self._queue.append(job)
        while True:
            with self._cv:
                while not job.done and self._leading:
                    self._cv.wait()
                if job.done:
                    return self._outcome(job)
                self._leading = True
                batch = self._queue[: self._max_batch]
                del self._queue[: self._max_batch]
            # Our job is in this batch unless more than max_batch jobs queued before it:
            # then we lead the oldest ones and go round again.
            try:
                self._leader = threading.current_thread()
                self._run_batch(batch)
            finally:
                self._leader = None
                with self._cv:
                    for j in batch:
                        if not j.done:  # interrupted mid-batch: none of it is known stored
                            j.error = RuntimeError("the write was interrupted")
                            j.done = True
                    self._leading = False
                    self._cv.notify_all()

    def _run_batch(self, batch: list[_Job]) -> None:
        self.batches += 1
        self.jobs += len(batch)
        try:
            with self._begin() as conn:
                values = [j.work(conn) for j in batch]
        except Exception as err:  # noqa: BLE001 - handed to the job that raised it
            if len(batch) == 1:
                batch[0].error, batch[0].done = err, True
                return
            # Someone's job failed and took the batch with it: each alone, once more.
            for j in batch:
                try:
                    with self._begin() as conn:
                        j.value = j.work(conn)
                except Exception as err:  # noqa: BLE001
                    j.error = err
                j.done = True
            return
        for j, v in zip(batch, values, strict=True):
            j.value, j.done = v, True

    @staticmethod
    def _outcome(job: _Job):
        if job.error is not None:
            raise job.error
        return job.value
