"""Benchmark cases for ``snapshot bench``, one section per pipeline stage.

Targets come from the issues (one core): parse + FK of a 2,000-frame two-person scene
under 150 ms; pose selection under 20 ms; PMA + refinement under 30 ms; viewpoint
entropy (162 views, 75k faces) under 5 s; relief 1024² to STL under 2 s.
"""

from __future__ import annotations

from .bench import BenchContext, case

# ----------------------------------------------------------------- motion core


@case("parse+FK salsa pair (2x2242 frames, 2x57 joints)", target_ms=150.0,
      note="two BVH files read, scaled, forward kinematics, lead-in trimmed")
def _parse_fk_pair(ctx: BenchContext):
    a, b = ctx.path("two_person/60_01_scaled.bvh"), ctx.path("two_person/61_01_scaled.bvh")
    if a is None or b is None:
        return None
    import warnings

    from .load import load_scene

    def work():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")  # the salsa unit is fitted, which warns
            return load_scene([a, b], fps=60)

    return work


@case("parse+FK Boxing_Toes (3069 frames, 26 joints)")
def _parse_fk_boxing(ctx: BenchContext):
    p = ctx.path("boxing_jump/Boxing_Toes.bvh")
    if p is None:
        return None
    import warnings

    from .load import load_scene

    def work():
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            return load_scene(p)

    return work
