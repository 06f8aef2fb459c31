"""The one workflow the command line and Python share: ``scenescore train`` is :func:`train`
(``ss.train``), which holds scenes out (or cross-validates little data, ``crossval.py``), trains,
evaluates, calibrates tidying and saves."""

from .crossval import cross_validate
from .training import NothingLearned, Outputs, Validation, holdout, train

__all__ = ["NothingLearned", "Outputs", "Validation", "cross_validate", "holdout", "train"]
