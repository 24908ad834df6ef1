"""The view methods the suite compares: one vocabulary for the pipeline, study and analysis.

The study shows the selected pose from three views and asks which is best; the
analysis counts the votes; the figures label the panels. All three name the methods
with :class:`ViewMethod`, whose values are the identifiers stored in the database,
the stimulus manifest and the ``baselines`` keys of ``snapshot select --json``.
"""

from __future__ import annotations

from enum import StrEnum

__all__ = ["ViewMethod", "VIEW_METHODS", "view_label"]


class ViewMethod(StrEnum):
    """A view-selection method; the value is its stored identifier.

    ``OURS`` is the paper's Projected Motion Area (§3.2), ``VIEWPOINT_ENTROPY`` the
    baseline of Vázquez et al. (2001) on the posed body mesh, ``MOTION_AREA`` the
    baseline of Kwon & Lee (2008).
    """

    OURS = "ours"
    VIEWPOINT_ENTROPY = "viewpoint_entropy"
    MOTION_AREA = "motion_area"

    @property
    def label(self) -> str:
        """Short human label: ``"ours"``, ``"viewpoint entropy"``, ``"motion area"``."""
        return _LABELS[self]

    @property
    def figure(self) -> str:
        """The paper figure that shows this method's view (Figs. 8-10)."""
        return _FIGURES[self]

    @property
    def panel(self) -> str:
        """Panel title of the method's view in figures: ``"ours: PMA (Fig. 8)"``,
        ``"viewpoint entropy (Fig. 9)"``, ``"motion area (Fig. 10)"``."""
        name = f"{self.label}: PMA" if self is ViewMethod.OURS else self.label
        return f"{name} ({self.figure})"


_LABELS = {
    ViewMethod.OURS: "ours",
    ViewMethod.VIEWPOINT_ENTROPY: "viewpoint entropy",
    ViewMethod.MOTION_AREA: "motion area",
}
_FIGURES = {
    ViewMethod.OURS: "Fig. 8",
    ViewMethod.VIEWPOINT_ENTROPY: "Fig. 9",
    ViewMethod.MOTION_AREA: "Fig. 10",
}

#: The three methods in the paper's order (ours first, then the baselines).
VIEW_METHODS: tuple[ViewMethod, ...] = tuple(ViewMethod)


def view_label(key: str) -> str:
    """How a view key is shown on a picture: a :class:`ViewMethod` by its
    :attr:`~ViewMethod.label`, any other key (a free-form name) as given.

    Dicts of views are keyed by the enum, never by display labels; this turns a key into
    text at display time only.

    Parameters
    ----------
    key : ViewMethod or str

    Returns
    -------
    str

    Examples
    --------
    >>> from snapcore.select.view_methods import ViewMethod, view_label
    >>> view_label(ViewMethod.VIEWPOINT_ENTROPY), view_label("side")
    ('viewpoint entropy', 'side')
    """
    return key.label if isinstance(key, ViewMethod) else str(key)
