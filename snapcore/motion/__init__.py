"""Motion: files in, posed skeletons out (the lowest layer).

- :mod:`~snapcore.motion.bvh` reads and writes BVH (strict, with line numbers);
- :mod:`~snapcore.motion.gltf` reads skinned, animated glTF/GLB characters (with
  ``gltf_access`` for binary data and ``gltf_sample`` for STEP/LINEAR/CUBICSPLINE);
- :mod:`~snapcore.motion.skinning` is linear blend skinning, vectorised over frames;
- :mod:`~snapcore.motion.kinematics` is the vectorised forward kinematics;
- :mod:`~snapcore.motion.scene` holds ``Skeleton``/``Character``/``Scene`` and the unit
  inference;
- :mod:`~snapcore.motion.load` turns BVH/glTF paths or a scene manifest into a ``Scene``;
- :mod:`~snapcore.motion.anatomy` knows what each joint is (side, role, radius) and the
  reference stature;
- :mod:`~snapcore.motion.facing` says which way characters face;
- :mod:`~snapcore.motion.synth` (with ``synth_rig``) makes synthetic humanoid motion with
  known event times.
"""

from snapcore.motion.load import data_dir, load_scene
from snapcore.motion.scene import Character, Scene, Skeleton

__all__ = ["Character", "Scene", "Skeleton", "data_dir", "load_scene"]
