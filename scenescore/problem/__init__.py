"""Problems: a scene, a cost bound to it, and which objects move.

- ``problem.py``: :class:`Problem`, its feasibility check and the violations it names;
- ``files.py``: YAML problem files (a typed schema; errors name the file, the line and the key path).
  It sits above the solvers (a file names its solver), so it is not imported here.
"""

from .problem import FEASIBILITY_TOL, Problem, ProblemError

__all__ = ["FEASIBILITY_TOL", "Problem", "ProblemError"]
