"""reactive_anim: physics-driven hit reactions for motion-captured characters (Blender extension).

Importing this package needs no Blender; `register()` and `unregister()` load the Blender layer.
"""

from __future__ import annotations


def register() -> None:
    from .blender import registry

    registry.register()


def unregister() -> None:
    from .blender import registry

    registry.unregister()
