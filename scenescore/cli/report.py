"""``scenescore report``: the results page, and the README's headline table, from a ``results.json``."""

from __future__ import annotations

import argparse
import os
from pathlib import Path

from . import UserError, add_common


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``scenescore report`` to the command line's subcommands."""
    p = sub.add_parser(
        "report",
        help="render the results page (and the README's headline table) from an experiment's results.json",
        description=(
            "Render the results page from a results.json that `scenescore experiment` wrote: each "
            "experiment's table as it printed it, then where the figures came from (command, commit, date, "
            "versions, device, cores, wall time, options). Printed, or written to --out; with --readme, the "
            "README's headline table between its '<!-- results:begin FILE -->' and '<!-- results:end -->' "
            "markers is rendered from the same file and the begin marker names it."
        ),
    )
    p.add_argument("results", type=Path, help="results.json written by `scenescore experiment ... --out DIR`")
    p.add_argument("--out", type=Path, default=None, help="write the page here (default: print it)")
    p.add_argument(
        "--readme", type=Path, default=None, help="rewrite this README's table between the results markers"
    )
    add_common(p)
    p.set_defaults(func=run)


def _relative(path: Path, start: Path) -> str:
    """``path`` as the README names it: relative to the README's folder, with forward slashes."""
    return Path(os.path.relpath(path.resolve(), start.resolve())).as_posix()


def run(args: argparse.Namespace) -> int:
    from ..experiments.results_page import (
        ResultsError,
        headline_table,
        load_results,
        render_page,
        replace_readme_table,
    )
    from ..scene.outputs import atomic_write_text
    from ..scene.textfiles import read_text

    try:
        doc = load_results(args.results)
    except ResultsError as e:
        raise UserError(str(e)) from None
    page = render_page(doc, args.results.as_posix())
    readme = None
    if (
        args.readme is not None
    ):  # rendered before anything is written: a README without markers writes nothing
        text = read_text(args.readme, UserError, "README")
        try:
            readme = replace_readme_table(
                text, headline_table(doc), _relative(args.results, args.readme.parent)
            )
        except ResultsError as e:
            raise UserError(f"--readme {args.readme}: {e}") from None
    if args.out is None:
        print(page, end="")
    else:
        atomic_write_text(args.out, page)
        print(f"wrote {args.out}")
    if readme is not None:
        atomic_write_text(args.readme, readme)
        print(f"wrote the headline table of {args.readme}")
    return 0
