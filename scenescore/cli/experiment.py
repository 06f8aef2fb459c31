"""``scenescore experiment``: the paper's experiments, our tables beside the paper's figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from . import UserError, add_common

EXPERIMENTS = ["missing", "novel", "heatmap"]


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "experiment",
        help="run one of the paper's experiments",
        description=(
            "Run one of the paper's experiments and print its table with the paper's figures beside ours; "
            "writes table.md and results.json under --out."
        ),
    )
    p.add_argument("name", choices=EXPERIMENTS + ["all"], help="which experiment")
    p.add_argument("--seeds", type=int, default=3, help="seeds to average over (default 3)")
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/experiment-NAME)")
    p.add_argument("--methods", default=None, help="comma-separated subset of the methods")
    p.add_argument(
        "--quick", action="store_true", help="short training, for a smoke test (figures not comparable)"
    )
    p.add_argument(
        "--from-images",
        action="store_true",
        help="missing: build every graph from rendered images (detection, moments, crops)",
    )
    add_common(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    if args.seeds < 1:
        raise UserError(f"--seeds must be at least 1, got {args.seeds}")
    names = EXPERIMENTS if args.name == "all" else [args.name]
    for name in names:
        out = args.out or Path("runs") / f"experiment-{name}"
        if args.name == "all":
            out = (args.out or Path("runs") / "experiment-all") / name
        t0 = time.perf_counter()
        md = RUNNERS[name](args, out)
        print(md)
        print(f"\n{name}: {time.perf_counter() - t0:.0f} s; wrote {out}/table.md and {out}/results.json")
    return 0


def _missing(args: argparse.Namespace, out: Path) -> str:
    import torch

    from ..experiments import missing
    from ..experiments.report import write_results

    torch.manual_seed(args.seed)
    methods = args.methods.split(",") if args.methods else None
    scenes_fn, encoder = None, None
    if args.from_images:
        from ..encoders import make_encoder
        from ..vision import graphs_from_renders

        encoder = make_encoder("image")

        def scenes_fn(train, test):
            return graphs_from_renders(train, encoder=encoder), graphs_from_renders(test, encoder=encoder)

    res = missing.run(
        seeds=args.seeds,
        methods=methods,
        quick=args.quick,
        progress=not args.quiet,
        scenes_fn=scenes_fn,
        encoder=encoder,
    )
    md = (
        "## Table 1: missing objects"
        + (" (graphs from rendered images)" if args.from_images else "")
        + "\n\n"
    )
    md += (
        "Position error t in cm, orientation error R in degrees (none for the symmetric bowl); "
        f"mean ± std over {args.seeds} seed(s); the paper's figures in brackets.\n\n"
    )
    md += missing.format_missing(res)
    write_results(out, res.rows(), md)
    return md


def _novel(args: argparse.Namespace, out: Path) -> str:
    import torch

    from ..experiments import novel
    from ..experiments.report import write_results

    torch.manual_seed(args.seed)
    methods = args.methods.split(",") if args.methods else None
    res = novel.run(seeds=args.seeds, methods=methods, quick=args.quick, progress=not args.quiet)
    md = "## Table 2: novel objects (ordered rows of cutlery)\n\n"
    md += (
        "Mean position error in cm of a removed piece of cutlery, per ordering rule; test sizes never "
        f"seen in training; mean ± std over {args.seeds} seed(s); the paper's figures in brackets.\n\n"
    )
    md += novel.format_novel(res)
    write_results(out, res.rows(), md)
    return md


def _heatmap(args: argparse.Namespace, out: Path) -> str:
    import torch

    from ..experiments import heatmap
    from ..experiments.report import write_results

    torch.manual_seed(args.seed)
    res = heatmap.run(seeds=args.seeds, quick=args.quick, progress=not args.quiet, out=out)
    md = heatmap.format_heatmap(res)
    write_results(out, res.rows(), md)
    return md


RUNNERS = {"missing": _missing, "novel": _novel, "heatmap": _heatmap}
