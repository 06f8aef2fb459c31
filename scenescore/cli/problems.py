"""``scenescore solve`` and ``scenescore compare``: YAML problems through one solver or several."""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from . import UserError, add_common


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "solve", help="solve a YAML problem", description="Solve a YAML problem file and print the result."
    )
    p.add_argument("problem", help="problem.yaml")
    p.add_argument(
        "--solver",
        help="langevin, osqp, casadi, or a chain of them joined by '>' (quote it: 'langevin>osqp'); "
        "default: the file's",
    )
    p.add_argument("--out", help="write the result as JSON here")
    p.add_argument("--scene-out", help="write the solved scene as JSON here")
    p.add_argument("--plot", help="draw the solved scene to this PNG")
    add_common(p, seed=-1)
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
        help="comma-separated solvers (langevin, osqp, casadi) or chains joined by '>'; quote it, '>' is a "
        "shell redirect (default: 'langevin,langevin>osqp,langevin>casadi')",
    )
    c.add_argument("--seeds", type=int, default=5, help="number of seeds (default 5)")
    c.add_argument("--out", help="write the table here: FILE.md (markdown) and FILE.json (JSON) beside it")
    add_common(c)
    c.set_defaults(func=run_compare)


def _load(path: str):
    from ..problem_file import load_problem

    return load_problem(path)


def run_solve(args: argparse.Namespace) -> int:
    from ..scene import atomic_write_text
    from ..solvers import solve

    lp = _load(args.problem)
    solver = args.solver or lp.solver
    seed = lp.seed if args.seed < 0 else args.seed
    if not args.quiet:
        print(f"solving {args.problem} with {solver} (seed {seed})")
    r = solve(lp.problem, solver, seed=seed, options=lp.options)
    print(r.summary())
    if args.out:
        atomic_write_text(args.out, r.to_json() + "\n")
    if args.scene_out:
        r.scene.to_json(args.scene_out)
    if args.plot:
        _plot(r, args.plot)
    return 0 if r.success else 1


def _plot(result, path: str) -> None:
    import io

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    from matplotlib.patches import Circle, Polygon

    from ..geometry import footprint_core
    from ..scene import atomic_write_bytes

    scene = result.scene
    fig, ax = plt.subplots(figsize=(5, 5))
    (x0, y0), (x1, y1) = scene.bounds
    ax.add_patch(Polygon([[x0, y0], [x1, y0], [x1, y1], [x0, y1]], fill=False, ls="--", color="0.5"))
    for o in scene.objects:
        col = [c / 255 for c in o.color]
        core, r = footprint_core(o)
        if len(core) == 1:
            ax.add_patch(Circle(o.pose[:2], r, color=col, ec="k", alpha=0.8 if not o.fixed else 0.4))
        else:
            ax.add_patch(
                Polygon(
                    o.world_polygon() if o.shape_kind != "polygon" else o.world_polygon(),
                    color=col,
                    ec="k",
                    alpha=0.8 if not o.fixed else 0.4,
                )
            )
        ax.annotate(o.name, o.pose[:2], fontsize=7, ha="center")
    ax.set_xlim(x0 - 0.05, x1 + 0.05)
    ax.set_ylim(y0 - 0.05, y1 + 0.05)
    ax.set_aspect("equal")
    ax.set_title(f"{result.solver}: {result.status}, objective {result.objective:.4g}")
    buf = io.BytesIO()
    fig.savefig(buf, format="png", dpi=100)
    plt.close(fig)
    atomic_write_bytes(path, buf.getvalue())


def _solver_list(text: str) -> list[str]:
    """``--solvers`` as names, each checked against the registry; empty or repeated names refused."""
    from ..problem import ProblemError
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
    from ..scene import atomic_write_text
    from ..solvers.compare import compare

    lp = _load(args.problem)
    solvers = _solver_list(args.solvers)
    if args.seeds < 1:
        raise UserError(f"--seeds: expected a number >= 1, got {args.seeds}")
    cmp = compare(
        lp.problem,
        solvers,
        seeds=list(range(args.seed, args.seed + args.seeds)),
        options=lp.options,
        progress=not args.quiet,
    )
    print(cmp.table())
    if args.out:
        out = Path(args.out)
        md = out if out.suffix == ".md" else out.with_suffix(".md")
        atomic_write_text(md, f"# {lp.problem.name}: {args.seeds} seeds\n\n" + cmp.table() + "\n")
        atomic_write_text(md.with_suffix(".json"), json.dumps(cmp.to_dict(), indent=1) + "\n")
    return 0
