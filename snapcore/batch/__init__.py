"""A whole motion library: one snapshot, thumbnail and index row per scene.

- :mod:`~snapcore.batch.discover` finds the scenes under folders, globs and list files;
- :mod:`~snapcore.batch.task` is the one task every executor runs on a scene;
- :mod:`~snapcore.batch.run` plans (skips what is done), runs in this process, in
  worker processes or on a Dask cluster, and writes the outputs as they come back;
- :mod:`~snapcore.batch.index` is the CSV index and the atomic writes;
- :mod:`~snapcore.batch.gallery` is the static HTML gallery.
"""

from snapcore.batch.discover import BatchError, Discovery, SceneSource, discover
from snapcore.batch.run import BatchInterrupted, BatchReport, run_batch
from snapcore.batch.task import BatchOptions, run_scene

__all__ = [
    "BatchError",
    "BatchInterrupted",
    "BatchOptions",
    "BatchReport",
    "Discovery",
    "SceneSource",
    "discover",
    "run_batch",
    "run_scene",
]
