"""The worker set-up of a batch on a Dask cluster (imported only with ``--scheduler``)."""

from __future__ import annotations

from distributed import WorkerPlugin

__all__ = ["DaskWorkerSetup"]


class DaskWorkerSetup(WorkerPlugin):
    """What :func:`snapcore.batch.task.init_worker` does for a local worker process,
    on each Dask worker (those running and those that join later): one BLAS and one
    Mesa rasteriser thread. Without it a worker's llvmpipe started a thread per core,
    and two workers on two cores fought over them. The GL renderer itself is made by
    the first task, on the worker's task thread (an EGL context belongs to a thread).

    Parameters
    ----------
    size : (int, int)
        Thumbnail size (kept for symmetry with the local set-up).
    threads : int
        BLAS and rasteriser threads per worker.
    """

    def __init__(self, size=(320, 360), threads: int = 1):
        self.size = tuple(size)
        self.threads = threads

    def setup(self, worker):
        from snapcore.batch.task import init_worker

        init_worker(self.size, ignore_sigint=False, threads=self.threads, renderer=False)
