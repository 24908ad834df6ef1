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
