"""Baselines the paper compares against."""

from .nearest import NearestNeighbour
from .neatnet import NeatNet, NeatNetConfig
from .neatnet_r import NeatNetR

__all__ = ["NearestNeighbour", "NeatNet", "NeatNetConfig", "NeatNetR"]
