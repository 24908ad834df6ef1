"""analysis: the user study's responses → the paper's tables and figures, with statistics.

Load responses (the store or an export file) into tidy frames (:mod:`analysis.load`),
test the view votes of Table 2 (:mod:`analysis.votes`), compare chosen frames with the
algorithm's pick and simple baselines (:mod:`analysis.frames`), simulate participants
(:mod:`analysis.simulate`), plan sample sizes (:mod:`analysis.power`), and write
everything as CSV/Markdown/LaTeX tables (:mod:`analysis.tables`), figures and an HTML
report (:mod:`analysis.report`, ``snapshot analyze``, with its sections in
:mod:`analysis.sections` and the page in :mod:`analysis.html_page`). Plotting (matplotlib) is imported only
when a figure is drawn.

Direction: analysis reads the study's data through the study logic — the store
(:mod:`study_app.data.store`), export files (:mod:`study_app.data.export`, the one codec of
export rows), the stimulus manifest and the scene record
(:class:`study_app.design.scenes.StudyScene`) — and never imports the study's UI; the
researcher screen (:mod:`study_app.web.screens.researcher`) imports analysis to show its
results. ``tests/test_architecture.py`` holds the layer table that enforces this.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING

# The names below are imported on first use (PEP 562), not here: importing one
# analysis module (say analysis.power) runs this file, and importing them all up front
# (pandas, scipy.stats, the study store) cost seconds, at test collection too.
_WHERE = {
    ".figures": ("FIGURES", "make_figures", "measure_table1", "paper_analogues", "paper_table1"),
    ".frames": (
        "baselines_from_stimuli",
        "closeness_tests",
        "frame_distances",
        "frame_histogram",
        "hit_rates",
        "motion_baselines",
        "scene_frames_from_rows",
    ),
    ".load": (
        "LoadError",
        "attention_summary",
        "load_responses",
        "ordered_scenes",
        "pose_choices",
        "tidy_responses",
        "view_choices",
    ),
    ".power": ("power_chisquare", "power_curve", "power_pairwise", "power_table", "sample_size"),
    ".report": ("analyze", "analyze_counts"),
    ".tables": ("write_table",),
    ".simulate": (
        "ObserverModel",
        "paper_design",
        "simulate_participants",
        "simulate_vote_counts",
        "simulated_rows",
        "store_simulation",
    ),
    ".votes": (
        "chisquare_no_preference",
        "choices_from_counts",
        "claim_summary",
        "fleiss_kappa",
        "holm_adjust",
        "luce_strengths",
        "ours_vs_baselines",
        "paper_counts",
        "paper_table2",
        "vote_counts",
        "vote_table",
        "wilson_interval",
    ),
}
_MODULE_OF = {name: module for module, names in _WHERE.items() for name in names}

# The type checker reads the same names from their modules (a PEP 562 `__getattr__`
# alone would make every public name `Any` to it); these lines never run.
if TYPE_CHECKING:
    from .figures import FIGURES, make_figures, measure_table1, paper_analogues, paper_table1
    from .frames import (
        baselines_from_stimuli,
        closeness_tests,
        frame_distances,
        frame_histogram,
        hit_rates,
        motion_baselines,
        scene_frames_from_rows,
    )
    from .load import (
        LoadError,
        attention_summary,
        load_responses,
        ordered_scenes,
        pose_choices,
        tidy_responses,
        view_choices,
    )
    from .power import power_chisquare, power_curve, power_pairwise, power_table, sample_size
    from .report import analyze, analyze_counts
    from .simulate import (
        ObserverModel,
        paper_design,
        simulate_participants,
        simulate_vote_counts,
        simulated_rows,
        store_simulation,
    )
    from .tables import write_table
    from .votes import (
        chisquare_no_preference,
        choices_from_counts,
        claim_summary,
        fleiss_kappa,
        holm_adjust,
        luce_strengths,
        ours_vs_baselines,
        paper_counts,
        paper_table2,
        vote_counts,
        vote_table,
        wilson_interval,
    )


def __getattr__(name: str) -> object:
    module = _MODULE_OF.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(import_module(module, __name__), name)
    globals()[name] = value  # later look-ups skip this function
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


__all__ = [
    "FIGURES",
    "LoadError",
    "ObserverModel",
    "analyze",
    "analyze_counts",
    "attention_summary",
    "baselines_from_stimuli",
    "chisquare_no_preference",
    "choices_from_counts",
    "claim_summary",
    "closeness_tests",
    "fleiss_kappa",
    "frame_distances",
    "frame_histogram",
    "hit_rates",
    "holm_adjust",
    "load_responses",
    "luce_strengths",
    "make_figures",
    "measure_table1",
    "motion_baselines",
    "ordered_scenes",
    "ours_vs_baselines",
    "paper_analogues",
    "paper_counts",
    "paper_design",
    "paper_table1",
    "paper_table2",
    "pose_choices",
    "power_chisquare",
    "power_curve",
    "power_pairwise",
    "power_table",
    "sample_size",
    "scene_frames_from_rows",
    "simulate_participants",
    "simulate_vote_counts",
    "simulated_rows",
    "store_simulation",
    "tidy_responses",
    "view_choices",
    "vote_counts",
    "vote_table",
    "wilson_interval",
    "write_table",
]
