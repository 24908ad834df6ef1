"""`snapshot bench --only`: which cases a name picks."""

from __future__ import annotations

from snapcore.bench.runner import select_cases


def test_only_picks_whole_words_not_a_longer_number():
    """``--only "two salsa dancers, 100"`` is the 100-frame video case, not also the
    1000-frame one (a plain substring match ran both); an exact name picks just it."""
    hundred = "render: video 1280x720 two salsa dancers, 100 frames"
    assert [c.name for c in select_cases("two salsa dancers, 100")] == [hundred]
    assert [c.name for c in select_cases(hundred)] == [hundred]
    assert len(select_cases("two salsa dancers")) >= 3  # a phrase still picks a family
    assert select_cases("salsa dancers, 10") == []


#: Issue 41's table: a case's name (what --only finds) and the target it must carry (ms).
ISSUE_41 = {
    "skin: two salsa human bodies, all 2242 frames": 1000.0,
    "render: video 1280x720 two salsa dancers, 1000 frames": 20000.0,
    "viewpoint entropy 162 views, two human bodies": 500.0,
    "render: still 1280x720, two salsa dancers (per frame)": 50.0,
    "parse+FK salsa pair (2x2242 frames, 2x57 joints)": 100.0,
    "pose selection (story, the default) salsa pair": 5.0,
    "view PMA salsa pair (2562 views + refinement)": 15.0,
    "`snapshot select FILE`": 1200.0,
    "`snapshot render FILE`": 1000.0,
    "library: CPU per scene": 150.0,
    "library: --jobs 2 wall per 1000 ms of --jobs 1": 1000.0 / 1.8,
}


def test_every_row_of_issue_41_has_a_case_with_its_target():
    for name, target in ISSUE_41.items():
        found = select_cases(name)
        assert len(found) == 1, (name, [c.name for c in found])
        assert found[0].target_ms == target, name


def test_a_case_may_report_its_own_figure(monkeypatch):
    """A case whose work returns ``Measured`` (CPU per scene, a ratio) is reported by
    that figure, not by the wall time of its work."""
    from snapcore.bench import registry, runner
    from snapcore.bench.registry import BenchCase, BenchContext, Measured

    cases = [BenchCase("figure", lambda ctx: lambda: Measured(123.0), 200.0, "", 3)]
    monkeypatch.setattr(registry, "CASES", cases)
    monkeypatch.setattr(runner, "CASES", cases)
    (r,) = runner.run_cases(BenchContext(data=None), repeats=3)
    assert (r.min_ms, r.median_ms, r.status) == (123.0, 123.0, "ok")


def test_library_cases_take_each_ratio_within_one_pair_of_runs(monkeypatch):
    """``-n 3`` with ``SNAPSHOT_BENCH_SCALE``: three ``--jobs 1`` / ``--jobs 2`` pairs run
    one after the other, the CPU row the median of the three ``--jobs 1`` runs and the
    ratio row the median of the three ratios, each of a ``--jobs 2`` run over the
    ``--jobs 1`` run just before it (the machine drifts over minutes: a ratio across
    pairs, or of one run each, said more about the drift than the batch)."""
    from snapcore.bench import cases_speed, runner
    from snapcore.bench.registry import BenchContext

    walls = iter([40.0, 20.0, 36.0, 21.0, 38.0, 19.5])  # pair 0, pair 1, pair 2
    order = []

    def fake_run(ctx, jobs, k):
        key = f"library-run-{jobs}-{k}"
        if key not in ctx.cache:
            order.append((jobs, k))
            ctx.cache[key] = {"scenes": 300, "wall_s": next(walls), "cpu_s": 3.0 * (1 + k)}
        return ctx.cache[key]

    monkeypatch.setenv("SNAPSHOT_BENCH_SCALE", "300")
    monkeypatch.setattr(cases_speed, "_library_run", fake_run)
    monkeypatch.setattr(runner, "CASES", runner.select_cases("library:"))
    results = {
        r.name.split(" (")[0]: r for r in runner.run_cases(BenchContext(data=None), repeats=3)
    }
    assert order == [(1, 0), (2, 0), (1, 1), (2, 1), (1, 2), (2, 2)]
    cpu = results["library: CPU per scene"]
    assert (cpu.min_ms, cpu.median_ms) == (10.0, 20.0)  # 3, 6 and 9 CPU-s over 300 scenes
    ratio = results["library: --jobs 2 wall per 1000 ms of --jobs 1"]
    assert ratio.median_ms == 1000.0 * 19.5 / 38.0  # of 500, 583.3 and 513.2
    assert ratio.min_ms == 500.0
