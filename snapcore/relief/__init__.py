"""Bas-relief: a pose carved into a printable height field.

- :mod:`~snapcore.relief.scene` renders the depth of a posed scene from a view;
- :mod:`~snapcore.relief.height_field` compresses it in the gradient domain;
- :mod:`~snapcore.relief.poisson` reconstructs heights (DCT Poisson solves);
- :mod:`~snapcore.relief.mesh` writes the watertight STL and the raking-light preview.
"""

from snapcore.relief.height_field import Relief, ReliefParams
from snapcore.relief.scene import relief_from_scene

__all__ = ["Relief", "ReliefParams", "relief_from_scene"]
