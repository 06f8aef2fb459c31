"""Compare solvers on the YAML example: same seeds and initial particles for each; one table.

    python examples/compare_solvers.py [--seeds 3] [--out compare.md]

The same as ``scenescore compare examples/place_bowl.yaml --solvers 'langevin,langevin>osqp,langevin>casadi'``.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from scenescore.problem.files import load_problem
from scenescore.scene.outputs import atomic_write_text
from scenescore.solvers.compare import compare

HERE = Path(__file__).parent


def main(argv: list[str] | None = None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problem", default=str(HERE / "place_bowl.yaml"))
    ap.add_argument("--solvers", default="langevin,langevin>osqp,langevin>casadi")
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--out")
    args = ap.parse_args(argv)
    lp = load_problem(args.problem)
    cmp = compare(lp.problem, args.solvers.split(","), seeds=args.seeds, options=lp.options)
    print(cmp.table())
    if args.out:
        atomic_write_text(args.out, cmp.table() + "\n")
    return cmp


if __name__ == "__main__":
    main()
