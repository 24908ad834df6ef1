"""Comparison sheets (``snapshot sheet --compare``): every figure stands on its panel's
floor, whatever the view's elevation and the character kind (issue 40)."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

#: The lowest figure pixel is on the floor band's top row within this many pixels.
ON_FLOOR_PX = 3
#: Panel size for the test, pixels.
SIZE = (200, 240)


def _panels(image: np.ndarray, n: int) -> list[np.ndarray]:
    """The ``n`` panels of a one-row sheet without title or captions."""
    from snapcore.render.composites import PANEL_GAP

    w, h = SIZE
    return [
        image[PANEL_GAP : PANEL_GAP + h, PANEL_GAP + i * (w + PANEL_GAP) :][:, :w] for i in range(n)
    ]


def _feet_and_band(panel: np.ndarray) -> tuple[int, int]:
    """(lowest figure row, top row of the floor band) of a "horizon" panel: figure
    pixels are coloured (blue, orange), sky and floor grey; the band is where the
    panel's edge column takes the floor colour."""
    from snapcore.render.renderer import FLOOR_COLOR

    p = panel.astype(int)
    figure = (p.max(axis=-1) - p.min(axis=-1)) > 40
    rows = np.flatnonzero(figure.any(axis=1))
    floor = np.round(np.array(FLOOR_COLOR) * 255)
    edge = np.abs(p[:, 2] - floor).max(axis=-1) <= 3
    return int(rows.max()), int(np.flatnonzero(edge).min())


@pytest.mark.parametrize(
    "files, frame, fps, body",
    [
        # source frame 546: index 543 of the pair, 3 T-pose frames cut
        (("two_person/60_12_scaled.bvh", "two_person/61_12_scaled.bvh"), 546, 60.0, "mannequin"),
        (("gltf/CesiumMan.glb",), 25, None, "human"),  # its own mesh (no frame cut)
    ],
)
@pytest.mark.slow
def test_every_figure_stands_on_its_panels_floor(motions_dir, files, frame, fps, body):
    """A salsa pair and a glTF character compared from above (39°), level, from the
    front and from below (-9°): in each panel the lowest figure pixel is on the floor
    band's top row within 3 px (before: the horizon passed under the middle of the
    motion, and in the view from above the salsa dancer's feet were 38 px below it,
    CesiumMan's 25 px, in 240 px panels)."""
    from snapcore.motion.load import load_scene
    from snapcore.render.composites import compare_views

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        scene = load_scene([motions_dir / f for f in files], fps=fps)
    views = {
        "above": (0.10, 0.63, 0.77),
        "side": (1.0, 0.0, 0.0),
        "front": (0.07, 0.02, 1.0),
        "below": (0.70, -0.16, 0.69),
    }
    image = compare_views(scene, frame, views, size=SIZE, labels=False, title=None, body=body)
    for name, panel in zip(views, _panels(image, len(views))):
        feet, band = _feet_and_band(panel)
        assert abs(feet - band) <= ON_FLOOR_PX, f"{files[0]} {name}: feet row {feet}, floor {band}"
