"""Scenes: the data every other part reads.

- ``scene.py``: :class:`Scene` and :class:`SceneObject`, their JSON and JSONL reading and writing;
- ``fields.py``: each JSON field read and checked, :class:`SceneError`;
- ``units.py``: the length unit a dataset names, and lengths said in it;
- ``textfiles.py``: the bounded, decoded reading of the text files users give (scenes, problems);
- ``outputs.py``: files written atomically, :class:`~scenescore.scene.outputs.WriteError`.
"""

from .fields import Bounds, SceneError
from .outputs import WriteError
from .scene import Scene, SceneObject, read_jsonl, wrap_angle, write_jsonl
from .units import declared_unit, length_unit

__all__ = [
    "Bounds",
    "Scene",
    "SceneError",
    "SceneObject",
    "WriteError",
    "declared_unit",
    "length_unit",
    "read_jsonl",
    "wrap_angle",
    "write_jsonl",
]
