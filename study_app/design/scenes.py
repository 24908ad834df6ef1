"""One scene of a study, as every part of the suite describes it.

:class:`StudyScene` holds what the app, the analysis and the simulation need to know
about a scene: its id, the motion's rate, length and first source frame, and the
algorithm's picks. The stimuli add their files (:class:`study_app.design.stimuli.SceneStimulus`
is a StudyScene with the video, frame images and view images); the frame analysis
(:mod:`analysis.frames`) adds the motion-derived baseline frames; a simulated study
(:mod:`analysis.simulate`) adds the salient moments its observers aim at and the
methods' strengths. It lives in the study layer, the lowest that the stimuli, the
analysis and the researcher screen may all import (``tests/test_architecture.py``).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

__all__ = ["StudyScene"]


@dataclass(frozen=True)
class StudyScene:
    """One scene of a study: its motion's timing and the algorithm's picks.

    Attributes
    ----------
    scene : str
        Scene id (the stimulus folder name and the ``scene`` column of responses).
    fps : float
        Motion frames per second.
    n_frames : int
        Motion length in frames.
    algorithm_frame : int
        The algorithm's pick, source numbering.
    frame_offset : int
        Source number of the scene's first frame.
    algorithm_frames : tuple of int
        All of the algorithm's picks (top-k, best first; may be empty).
    title : str or None
        Display name for researchers.
    baseline_frames : dict
        Motion-derived baselines for the frame analysis, name → source frame
        (``fastest``, ``stretch``: those selectors' top picks; empty when unknown).
    salient_frames : tuple of int
        Simulated studies: other salient moments observers may aim at (source numbering).
    strengths : dict or None
        Simulated studies: Luce strengths of the view methods in this scene (None: the
        observer model's).
    selector_frames : dict
        Every pose selector's top-k source frames, name → list (``story``, ``paper``,
        ``stretch``...; from the stimuli manifest's ``picks.by_method``), may be empty.
    """

    scene: str
    fps: float
    n_frames: int
    algorithm_frame: int
    frame_offset: int = 0
    algorithm_frames: tuple = ()
    title: str | None = None
    baseline_frames: dict = field(default_factory=dict)
    salient_frames: tuple = ()
    strengths: dict | None = None
    selector_frames: dict = field(default_factory=dict)

    @property
    def source_frames(self) -> np.ndarray:
        """Every source frame of the scene, shape ``(n_frames,)``."""
        return np.arange(self.frame_offset, self.frame_offset + self.n_frames)
