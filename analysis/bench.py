"""Benchmark cases of the analysis for ``snapshot bench`` (issue 35): ``snapshot analyze``
on 300 simulated participants over the demo stimuli, as a researcher runs it.

Registered through the ``action_snapshot.bench`` entry point (the bench runner sits in a
lower layer and cannot import the analysis). Each case times the command itself, in its
own process: start-up and imports are part of what a researcher waits for. The store is
simulated once (not timed); the demo stimuli must be built (``snapshot stimuli build
study_app/configs/demo.toml -o var/stimuli/demo``, or ``make study``), else the cases are
skipped.

Targets (issue 35, this 2-core machine): ``--no-figures`` <= 5 s; with the figures at
most 5 s more (<= 10 s).
"""

from __future__ import annotations

import atexit
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

from snapcore.bench.registry import BenchContext, case

#: Simulated participants of the benchmark's store.
N_PARTICIPANTS = 300
#: The demo stimuli the cases analyse.
DEMO_STIMULI = Path(__file__).resolve().parents[1] / "var" / "stimuli" / "demo"


def _store(ctx: BenchContext) -> tuple[str, Path] | None:
    """A SQLite store with the simulated participants (made once per bench run): its URL
    and the folder it is in."""
    if "analysis_store" not in ctx.cache:
        if not (DEMO_STIMULI / "manifest.json").is_file():
            ctx.cache["analysis_store"] = None
            return None
        from study_app.data.store import Store

        from . import simulate as sim
        from .stimuli import read_stimuli

        folder = Path(tempfile.mkdtemp(prefix="bench-analysis-"))
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        url = f"sqlite:///{folder / 'study.db'}"
        doc, _ = read_stimuli(DEMO_STIMULI)
        att = (doc.get("study") or {}).get("attention")
        people = sim.simulate_participants(
            sim.design_from_stimuli(doc),
            N_PARTICIPANTS,
            seed=1,
            attention=att if isinstance(att, dict) else None,
        )
        with Store(url) as store:
            sim.store_simulation(store, people, study_id="demo", manifest_sha256="0" * 64)
        ctx.cache["analysis_store"] = (url, folder)
    return ctx.cache["analysis_store"]


def _analyze(ctx: BenchContext, *extra: str):
    made = _store(ctx)
    if made is None:
        return None
    url, folder = made
    command = [sys.executable, "-m", "snapcore.cli.main", "analyze", "--db", url]
    command += ["--stimuli", str(DEMO_STIMULI), "--include-simulated", "-q"]
    command += ["-o", str(folder / "out"), *extra]

    def work():
        subprocess.run(command, check=True, stdout=subprocess.DEVNULL)

    return work


@case(
    f"analyze: {N_PARTICIPANTS} simulated participants, demo stimuli, --no-figures",
    target_ms=5000.0,
    note="the whole command (start-up, load, every table, test and interval, report); "
    "needs var/stimuli/demo",
    max_repeats=3,
)
def _analyze_tables(ctx: BenchContext):
    return _analyze(ctx, "--no-figures")


@case(
    f"analyze: {N_PARTICIPANTS} simulated participants, demo stimuli, with figures",
    target_ms=10000.0,
    note="as above plus the five figures (PNG and PDF): at most 5 s more",
    max_repeats=3,
)
def _analyze_figures(ctx: BenchContext):
    return _analyze(ctx, "--figures")
