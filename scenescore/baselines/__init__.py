"""Baselines the paper compares against."""

from .nearest import NearestNeighbour

__all__ = ["NearestNeighbour"]
