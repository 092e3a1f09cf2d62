"""External pushes applied to a body for a time window. `Push` and `parse_push` are plain data of the scene
(`wbcbench.scene`, where scenarios parse them); the simulator applies them. Imported here under their old path."""

from __future__ import annotations

from ..scene import Push, parse_push

__all__ = ["Push", "parse_push"]
