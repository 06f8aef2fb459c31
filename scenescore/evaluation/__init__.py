"""Evaluation: how well a model places objects, beside the baselines it is compared with.

- ``cases.py``: the missing-object protocol: cases with poses removed, errors against the truth, the
  oracle that knows the data-generating process;
- ``report.py``: :func:`evaluate`, the leave-one-object-out table of every category beside nearest
  neighbour (what ``scenescore train`` and ``scenescore evaluate`` print);
- ``baselines/``: nearest neighbour, NeatNet and NeatNet-R, the paper's baselines.
"""

from .cases import MissingCase, OraclePlacer, case_errors, leave_one_out, make_cases, score_cases
from .report import CategoryErrors, EvalReport, evaluate

__all__ = [
    "CategoryErrors",
    "EvalReport",
    "MissingCase",
    "OraclePlacer",
    "case_errors",
    "evaluate",
    "leave_one_out",
    "make_cases",
    "score_cases",
]
