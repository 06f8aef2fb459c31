"""The one workflow the command line and Python share: ``scenescore train`` is :func:`train`
(``ss.train``), which holds scenes out (or cross-validates little data, ``crossval.py``), trains,
evaluates, calibrates tidying and saves."""

from .crossval import cross_validate
from .train import NothingLearned, holdout, train_model

__all__ = ["NothingLearned", "cross_validate", "holdout", "train_model"]
