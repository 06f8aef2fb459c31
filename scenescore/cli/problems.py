"""``scenescore solve`` and ``scenescore compare``: YAML problems through one solver or several."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from . import SEEDS, UserError, add_common, add_device, device_of


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "solve", help="solve a YAML problem", description="Solve a YAML problem file and print the result."
    )
    p.add_argument("problem", help="problem.yaml")
    p.add_argument(
        "--solver",
        help="langevin, osqp, casadi, alm, or a chain of them joined by '>' (quote it: 'langevin>osqp'); "
        "default: the file's",
    )
    p.add_argument("--out", help="write the result as JSON here")
    p.add_argument("--scene-out", help="write the solved scene as JSON here")
    p.add_argument("--plot", help="draw the solved scene to this PNG")
    add_common(p, seed=None, seed_help="random seed (default: the problem file's own seed)")
    add_device(p)
    p.set_defaults(func=run_solve)

    c = sub.add_parser(
        "compare",
        help="compare solvers on a YAML problem",
        description="Run several solvers on the same seeds and initial particles; print one table.",
    )
    c.add_argument("problem", help="problem.yaml")
    c.add_argument(
        "--solvers",
        default="langevin,langevin>osqp,langevin>casadi",
        help="comma-separated solvers (langevin, osqp, casadi, alm) or chains joined by '>'; quote it, '>' is a "
        "shell redirect (default: 'langevin,langevin>osqp,langevin>casadi')",
    )
    c.add_argument(
        "--seeds",
        type=SEEDS,
        default=5,
        help="how many seeds: seeds --seed .. --seed+N-1, the same for every solver (default 5)",
    )
    c.add_argument(
        "--out",
        type=Path,
        default=None,
        help="output folder: table.md (the table) and comparison.json (every row, as JSON) in it",
    )
    add_common(c)
    add_device(c)
    c.set_defaults(func=run_compare)


def _load(path: str, args: argparse.Namespace):
    from ..problem.files import load_problem

    return load_problem(path, device=device_of(args))


def warn_unused_options(path: str, options: dict, chains: list[str]) -> None:
    """Say on stderr which of the file's solver options the chosen chain(s) will not use."""
    import sys

    used = {stage.strip() for c in chains for stage in c.split(">")}
    unused = sorted(set(options) - used)
    if unused:
        print(
            f"warning: {path}: options for {', '.join(unused)} are not used by {' / '.join(chains)}",
            file=sys.stderr,
        )


def run_solve(args: argparse.Namespace) -> int:
    from ..scene.outputs import atomic_write_text
    from ..solvers import solve

    lp = _load(args.problem, args)
    solver = args.solver or lp.solver
    seed = lp.seed if args.seed is None else args.seed
    warn_unused_options(args.problem, lp.options, [solver])
    if not args.quiet:
        print(f"solving {args.problem} with {solver} (seed {seed})")
    r = solve(lp.problem, solver, seed=seed, options=lp.options)
    print(r.summary())
    if args.out:
        atomic_write_text(args.out, r.to_json() + "\n")
    if args.scene_out:
        r.scene.to_json(args.scene_out)
    if args.plot:
        from ..viz.plot import plot_result

        plot_result(r, args.plot)
    return 0 if r.success else 1


def _solver_list(text: str) -> list[str]:
    """``--solvers`` as names, each checked against the registry; empty or repeated names refused."""
    from ..problem.problem import ProblemError
    from ..solvers import get

    names = [s.strip() for s in text.split(",")]
    example = "e.g. 'langevin,langevin>osqp'"
    if any(not n or any(not st.strip() for st in n.split(">")) for n in names):
        raise UserError(
            f"--solvers {text!r}: an empty solver name; expected a comma-separated list, {example}"
        )
    repeated = sorted({n for n in names if names.count(n) > 1})
    if repeated:
        raise UserError(f"--solvers {text!r}: {', '.join(repeated)} given more than once")
    for n in names:
        try:
            get(n)
        except ProblemError as e:
            raise UserError(f"--solvers: {e}") from None
    return names


def run_compare(args: argparse.Namespace) -> int:
    from ..scene.outputs import atomic_write_text
    from ..solvers.compare import compare

    if args.out is not None and args.out.suffix in (".md", ".json"):
        raise UserError(f"--out {args.out}: a folder to write table.md and comparison.json in, not a file")
    lp = _load(args.problem, args)
    solvers = _solver_list(args.solvers)
    warn_unused_options(args.problem, lp.options, list(solvers))
    cmp = compare(
        lp.problem,
        solvers,
        seeds=list(range(args.seed, args.seed + args.seeds)),
        options=lp.options,
        progress=not args.quiet,
    )
    print(cmp.table())
    if args.out is not None:
        atomic_write_text(
            args.out / "table.md", f"# {lp.problem.name}: {args.seeds} seeds\n\n" + cmp.table() + "\n"
        )
        atomic_write_text(args.out / "comparison.json", json.dumps(cmp.to_dict(), indent=1) + "\n")
        print(f"wrote {args.out}/table.md and {args.out}/comparison.json")
    return 0
