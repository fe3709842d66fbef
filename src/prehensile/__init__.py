"""prehensile: robots that reach, grasp and place.

Layers (a lower one never imports a higher one): spatial -> model -> kinematics -> collision
-> scene -> ik / workspace -> planning -> grasping / placement -> execution.
"""

from prehensile import kernel_cache
from prehensile.errors import ModelError, PrehensileError, SceneError, UnknownFrameError

kernel_cache.refresh()

__version__ = "0.1.0"
__all__ = ["ModelError", "PrehensileError", "SceneError", "UnknownFrameError", "__version__"]
