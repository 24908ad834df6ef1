"""``snapshot bench``: time every hot path and print a table."""

from __future__ import annotations

import os

import click

__all__ = ["bench"]


@click.command()
@click.option(
    "--repeats",
    "-n",
    type=click.IntRange(1, 1000),
    default=7,
    show_default=True,
    help="Timed runs per case (after one warm-up).",
)
@click.option("--only", default=None, help="Run only cases whose name contains this text.")
@click.option(
    "--json", "as_json", is_flag=True, help="Print results as JSON (data_schema/bench.schema.json)."
)
@click.option(
    "--threads",
    type=click.IntRange(1, 64),
    default=1,
    show_default=True,
    help="BLAS threads (1 = the 'one core' the targets are set for).",
)
def bench(repeats, only, as_json, threads):
    """Benchmark parsing, FK, pose and view selection, rendering and reliefs.

    Prints min and median wall time per case over REPEATS runs, with the target where
    one is set. Cases whose data is missing (SNAPSHOT_DATA) are listed as skipped.
    """
    for var in ("OMP_NUM_THREADS", "OPENBLAS_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ[var] = str(threads)
    from threadpoolctl import threadpool_limits

    threadpool_limits(threads)  # NumPy may already be loaded: limit its BLAS pool now too
    from snapcore.bench.registry import BenchContext
    from snapcore.bench.runner import run_cases
    from snapcore.motion.load import data_dir

    ctx = BenchContext(data=data_dir())
    results = run_cases(
        ctx,
        repeats=repeats,
        only=only,
        progress=None if as_json else lambda n: click.echo(f"  running {n}...", err=True),
    )
    if not results:
        from snapcore.errors import SnapshotError

        raise SnapshotError(f"--only {only!r}: no benchmark case has that in its name")
    if as_json:
        from snapcore.cli.common import echo_json
        from snapcore.schema import validate

        doc = [r.__dict__ | {"status": r.status} for r in results]
        validate(doc, "bench", source="snapshot bench output")
        echo_json(doc)
        return
    w = max(len(r.name) for r in results) if results else 10
    click.echo(f"{'case':<{w}}  {'min ms':>9}  {'median ms':>9}  {'target':>8}  status")
    click.echo("-" * (w + 42))
    for r in results:
        mn = f"{r.min_ms:9.1f}" if r.min_ms is not None else f"{'-':>9}"
        md = f"{r.median_ms:9.1f}" if r.median_ms is not None else f"{'-':>9}"
        tg = f"{r.target_ms:8.0f}" if r.target_ms is not None else f"{'':>8}"
        click.echo(f"{r.name:<{w}}  {mn}  {md}  {tg}  {r.status}")
    click.echo(f"\n{repeats} timed runs per case after one warm-up; {threads} BLAS thread(s).")
