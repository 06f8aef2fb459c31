"""Geometry: poses and footprints as batched torch tensors, and the exact checks they are held to.

- ``poses.py``: poses composed and related, poses drawn uniformly inside bounds;
- ``footprints.py``: footprints as padded tensors, signed distances between them (differentiable);
- ``exact.py``: the same footprints in shapely and python-fcl, the reference for feasibility.
"""

from .footprints import Footprints, footprint_core, signed_distance, support_extent
from .poses import compose_poses, relative_poses, uniform_init

__all__ = [
    "Footprints",
    "compose_poses",
    "footprint_core",
    "relative_poses",
    "signed_distance",
    "support_extent",
    "uniform_init",
]
