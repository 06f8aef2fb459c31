"""Baselines the paper compares against."""

from .nearest import NearestNeighbour
from .neatnet_r import NeatNetR

__all__ = ["NearestNeighbour", "NeatNetR"]
