"""Figures a publisher accepts and a reader is not misled by (issue 27, item 7).

PDFs with TrueType (Type 42) fonts, not Type 3 (rejected by ACM/IEEE checks); titles
and legends that do not cite the original paper's figure numbers; the selector
timeline's title describing what it draws; Fig. 13's seconds axis labelled. The texts
are read from every Text artist of the figure as it is saved.
"""

from __future__ import annotations

import re

import numpy as np
import pandas as pd
import pytest

from analysis import plots
from study_app.design.scenes import StudyScene

PAPER_NUMBER = re.compile(r"\b(Fig\.?|Figure|Table)\s*\d", re.IGNORECASE)


@pytest.fixture
def saved_texts(monkeypatch):
    """Every text of every figure saved through analysis.plots.save_figure."""
    import matplotlib.text

    texts: dict[str, list[str]] = {}
    real = plots.save_figure

    def spy(fig, stem, **kw):
        name = str(stem).rsplit("/", 1)[-1]
        texts[name] = [t.get_text() for t in fig.findobj(matplotlib.text.Text) if t.get_text()]
        # The labels of secondary axes (Fig. 13's seconds on top), panel by panel.
        texts[name + ":secondary"] = [c.get_xlabel() for ax in fig.axes for c in ax.child_axes]
        return real(fig, stem, **kw)

    monkeypatch.setattr(plots, "save_figure", spy)
    return texts


def test_fig13_pdf_has_truetype_fonts_a_seconds_label_and_no_paper_numbers(tmp_path, saved_texts):
    from analysis import frames as fr

    rng = np.random.default_rng(0)
    pose = pd.DataFrame(
        {
            "scene": np.repeat(["kick", "jump"], 30),
            "participant_id": [f"p{i}" for i in range(30)] * 2,
            "chosen_frame": np.clip(rng.normal(45, 8, 60), 0, 89).astype(int),
            "algorithm_frame": 44,
            "fps": 30.0,
            "n_frames": 90,
        }
    )
    fig = plots.plot_frame_histograms(pose, fr.scene_frames_from_rows(pose))
    paths = plots.save_figure(fig, tmp_path / "fig13_frame_histograms")
    pdf = next(p for p in paths if p.suffix == ".pdf").read_bytes()
    assert b"/Type3" not in pdf and b"/FontFile2" in pdf  # embedded TrueType
    texts = saved_texts["fig13_frame_histograms"]
    assert not [t for t in texts if PAPER_NUMBER.search(t)], texts
    secondary = saved_texts["fig13_frame_histograms:secondary"]
    assert len(secondary) == 2 and all("second" in t for t in secondary), secondary


def test_selector_timeline_title_says_what_is_drawn(tmp_path, saved_texts):
    from analysis import sections

    pose = pd.DataFrame(
        {
            "scene": "kick",
            "participant_id": [f"p{i}" for i in range(6)],
            "chosen_frame": np.array([40, 42, 44, 50, 52, 61]),
        }
    )
    info = StudyScene(
        scene="kick",
        fps=30.0,
        n_frames=90,
        algorithm_frame=44,
        selector_frames={"ours": [44, 60], "fastest": [61]},
    )
    (tmp_path / "tables").mkdir()
    sections._selector_section(pose, tmp_path, scenes={"kick": info})
    texts = saved_texts["selector_timeline"]
    assert not [t for t in texts if "green" in t.lower()], texts
    assert any("chosen frames" in t for t in texts)
    pdf = (tmp_path / "figures" / "selector_timeline.pdf").read_bytes()
    assert b"/Type3" not in pdf
