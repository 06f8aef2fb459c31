"""``scenescore generate``: scenes from a bundled scenario, as JSONL and, with ``--images``, rendered."""

from __future__ import annotations

import argparse
import shutil
from collections.abc import Iterator
from dataclasses import replace
from itertools import chain, islice
from pathlib import Path
from typing import Any

from ..runtime.memory import check, format_gb
from ..scene.outputs import check_output_path
from ..scene.scene import Scene, write_jsonl
from . import PPM, SCENES, UserError, add_common

GENERATE_SAMPLE = 16  # scenes generated first to estimate the memory of a large --n
# memory per byte of a scene's JSON line: the Scene objects, the text and its UTF-8 bytes while the file
# is written, rounded up over the bundled scenarios
GENERATE_BYTES_PER_TEXT_BYTE = 6


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "generate",
        help="generate scenes from a scenario",
        description=(
            "Generate scenes from a data-generating process and write them as JSONL (one scene per line)."
        ),
    )
    p.add_argument("scenario", help="scenario name (see `scenescore generate --list`)", nargs="?")
    p.add_argument("--n", type=SCENES, default=48, help="number of scenes (default 48)")
    p.add_argument("--out", type=Path, help="output .jsonl file")
    p.add_argument(
        "--images", type=Path, default=None, help="also render top-down images (and a JSON per image) here"
    )
    p.add_argument("--ppm", type=PPM, default=None, help="image resolution in pixels per metre (default 500)")
    p.add_argument("--list", action="store_true", help="list the scenarios and exit")
    add_common(p)
    p.set_defaults(func=run_generate)


def run_generate(args: argparse.Namespace) -> int:
    from ..scenarios import available, describe, get

    if args.list or not args.scenario:
        names = available()
        width = max(len(n) for n in names)
        print("\n".join(f"{n:{width}s}  {describe(n)}" for n in names))
        return 0
    if args.out is None and args.images is None:
        raise UserError("give --out FILE.jsonl and/or --images DIR")
    scenario = get(args.scenario)
    if args.out is not None:
        check_output_path(args.out, "--out")  # before any scene is drawn
    # the images are rendered from a list (held whole, within the memory budget); the JSONL alone streams
    scenes = (
        None if args.images is None else _generate_within_budget(scenario, args.scenario, args.n, args.seed)
    )
    if args.out is not None:
        count = _write_generated(scenario, args.scenario, args.n, args.seed, args.out, not args.quiet, scenes)
        print(f"wrote {count} {args.scenario} scenes to {args.out}")
    if scenes is not None:
        from ..vision import write_rendered_dataset

        kw = {} if args.ppm is None else {"ppm": args.ppm}
        write_rendered_dataset(scenes, args.images, progress=not args.quiet, **kw)
        print(f"rendered {len(scenes)} images to {args.images}")
    return 0


def _write_generated(
    scenario: Any, name: str, n: int, seed: int, out: Path, progress: bool, scenes: list[Scene] | None
) -> int:
    """Write ``n`` scenes of ``scenario`` (``scenes`` when already drawn) to ``out`` as JSONL, atomically,
    with a progress bar; returns how many. A scenario with ``iter_scenes`` (the bundled ones) is drawn one
    scene at a time as the file is written, so memory stays that of a scene whatever ``n`` (the same
    scenes as ``generate``); another is generated whole within the memory budget. Refused before the
    file is begun when the first scenes say that it would not fit the disk's free space."""
    from tqdm.auto import tqdm

    if scenes is not None:
        it: Iterator[Scene] = iter(scenes)
    elif hasattr(scenario, "iter_scenes"):
        it = scenario.iter_scenes(n, seed)
    else:
        it = iter(_generate_within_budget(scenario, name, n, seed))
    head = list(islice(it, GENERATE_SAMPLE))
    _check_disk(out, name, n, head)
    # the built-in scenarios are in metres: say so, so that reports print centimetres (scenescore.scene.units)
    marked = (replace(s, meta={**s.meta, "unit": "m"}) for s in chain(head, it))
    with tqdm(marked, total=n, desc=f"generate {name}", unit="scene", disable=not progress) as bar:
        return write_jsonl(out, bar)


def _check_disk(out: Path, name: str, n: int, head: list[Scene]) -> None:
    """Refuse ``n`` scenes whose JSONL, estimated from the first ones, is larger than the free space where
    ``out`` is written (the file is written whole before it replaces an older one)."""
    if not head:
        return
    text = sum(len((s.to_json(indent=None) + "\n").encode("utf-8")) for s in head) / len(head)
    folder = out.parent
    while not folder.exists():
        folder = folder.parent
    free = shutil.disk_usage(folder).free
    if n * text > free:
        raise UserError(
            f"generate {name}: {n} scenes (~{text:.0f} bytes of JSON each) would write "
            f"~{format_gb(n * text)} GB to {out}, more than the {format_gb(free)} GB free in {folder}; "
            "lower --n or free some space"
        )


def _generate_within_budget(scenario: Any, name: str, n: int, seed: int) -> list[Scene]:
    """``scenario.generate(n, seed)``, refused by the memory budget first when ``n`` scenes would not fit.

    For the images (rendered from a list) and for a scenario without ``iter_scenes``: a scenario draws its
    scenes from one random stream over the whole call, so they cannot be made in batches with the same
    result, and ``n`` of them are held at once. The bytes per scene are estimated from the first
    :data:`GENERATE_SAMPLE` scenes (the same call's, so for as many scenes or fewer they are the answer)."""
    sample = scenario.generate(min(n, GENERATE_SAMPLE), seed)
    if n <= GENERATE_SAMPLE:
        return list(sample)
    text = sum(len(s.to_json(indent=None)) + 1 for s in sample) / len(sample)
    check(
        n * text * GENERATE_BYTES_PER_TEXT_BYTE,
        f"generate {name}: {n} scenes (~{text:.0f} bytes of JSON each)",
        "--n",
    )
    return list(scenario.generate(n, seed))
