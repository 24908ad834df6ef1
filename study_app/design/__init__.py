"""What a study shows: its protocol (config, trial plan, consent text), its scenes and the
stimuli built from them (videos, frame strips, candidate views, the manifest): the set
on disk (``stimuli``), its candidate views (``candidates``), its media (``media``) and
its build (``build``).

Builds on snapcore only; everything else in :mod:`study_app` reads from here.
"""
