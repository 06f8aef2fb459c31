"""``scenescore experiment``: the paper's experiments, our tables beside the paper's figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import TYPE_CHECKING

from . import ITERATIONS, JOBS, SCENES, SEEDS, UserError, add_common, add_device, device_of, number

if TYPE_CHECKING:
    from ..experiments.report import Row

EXPERIMENTS = ["missing", "novel", "heatmap", "compose", "zoo", "tidy"]

# the options that only some experiments read (every other option applies to all); their defaults are
# None or False, so a value other than those was given on the command line
OWN_OPTIONS: dict[str, tuple[str, ...]] = {
    "--methods": ("missing", "novel", "compose"),
    "--scenarios": ("zoo", "tidy"),
    "--jobs": ("missing", "novel", "compose", "zoo", "tidy"),
    "--energy-only": ("zoo",),
    "--train-scenes": ("zoo",),
    "--test-scenes": ("tidy",),
    "--efforts": ("tidy",),
    "--iterations": ("tidy",),
    "--alm": ("compose",),
    "--from-images": ("missing", "novel"),
    "--encoders": ("novel",),
}


def check_options(args: argparse.Namespace) -> None:
    """Refuse an option given for an experiment that does not read it (``all`` reads every one), naming
    the option and the experiments it belongs to."""
    if args.name == "all":
        return
    for option, owners in OWN_OPTIONS.items():
        value = getattr(args, option[2:].replace("-", "_"))
        if value not in (None, False) and args.name not in owners:
            raise UserError(
                f"{option} is an option of the {', '.join(owners)} experiment{'s' if len(owners) > 1 else ''} "
                f"(or all), not of {args.name}"
            )


def _add_selection(p: argparse.ArgumentParser) -> None:
    """Which experiment, over how many seeds, which methods and scenarios, and where it writes."""
    p.add_argument("name", choices=EXPERIMENTS + ["all"], help="which experiment")
    p.add_argument(
        "--seeds",
        type=SEEDS,
        default=3,
        help="how many seeds to average over: seeds 0 .. N-1 (tidy: --seed .. --seed+N-1), each its own data "
        "split and model (default 3)",
    )
    p.add_argument("--out", type=Path, default=None, help="output folder (default runs/experiment-NAME)")
    p.add_argument(
        "--methods",
        default=None,
        help="comma-separated subset of the methods (default all). missing: "
        "NeatNet, Nearest-Nbr, SceneScore-Abs, 'SceneScore (LeakyReLU)', SceneScore, Oracle, and only "
        "when named 'SceneScore (raw edges)' (no edge encoder, as train --raw-edges); novel: "
        "NeatNet-R, SceneScore, Oracle; compose: NeatNet, SceneScore, 'SceneScore (langevin>alm)', "
        "'SceneScore (langevin>osqp)', "
        "'SceneScore (langevin>casadi)'",
    )
    p.add_argument(
        "--scenarios",
        default=None,
        help="zoo: comma-separated subset of the zoo's scenarios (default the ten table-top ones; the rooms "
        "zoo-classroom and zoo-cafe run only when named); tidy: of its scenarios "
        "(default dining,desk,tv,zoo-workstation,zoo-hall)",
    )


def _add_running(p: argparse.ArgumentParser) -> None:
    """How the runs are carried out: worker processes, placement by the energy alone, a short smoke test."""
    p.add_argument(
        "--jobs",
        type=JOBS,
        default=None,
        help="worker processes, one thread each (default: one per usable core, 1 with --device cuda; "
        "1 runs everything in this process): compose, missing and novel run their seeds in them, zoo its "
        "scenario and seed pairs, tidy its scenarios; the figures do not depend on it",
    )
    p.add_argument(
        "--train-scenes",
        type=number(2, 48, integer=True),
        default=None,
        help="zoo: train on the first N of each split's 48 training scenes, the same test scenes "
        "(12: the small-data variant; default all 48)",
    )
    p.add_argument(
        "--energy-only",
        action="store_true",
        help="zoo: place by the learned energy alone (default: as `place` does, energy and non-overlap)",
    )
    p.add_argument(
        "--quick", action="store_true", help="short training, for a smoke test (figures not comparable)"
    )


def _add_tidy(p: argparse.ArgumentParser) -> None:
    """The tidy experiment's test scenes, effort weights and training length."""
    p.add_argument(
        "--test-scenes",
        type=SCENES,
        default=None,
        help="tidy: test scenes per scenario, each displaced five ways (default 3; 1 with --quick)",
    )
    p.add_argument(
        "--efforts",
        default=None,
        help="tidy: comma-separated effort weights, one row each (default 0.3,1,3; the Pareto chart needs two)",
    )
    p.add_argument(
        "--iterations",
        type=ITERATIONS,
        default=None,
        help="tidy: training iterations per scenario (default the trainer's 600; 30 with --quick)",
    )


def _add_variants(p: argparse.ArgumentParser) -> None:
    """Variants of the methods: compose's refinement options, graphs from images, novel's encoders."""
    p.add_argument(
        "--alm",
        default=None,
        help="compose: the refined row's alm options as JSON (default '{\"tol_grad\": 1.0}'; "
        "'{\"polish\": false}': a repair; '{\"tol_grad\": 0.01}': polished to the minimum)",
    )
    p.add_argument(
        "--from-images",
        action="store_true",
        help="missing, novel: build every graph from rendered images (detection, moments, crops)",
    )
    p.add_argument(
        "--encoders",
        default=None,
        help=(
            "novel: comma-separated semantic encoders, one SceneScore row each, from footprint, image, "
            "efficientnet (the 'pretrained' extra), clip (its weights in SCENESCORE_CLIP_WEIGHTS) "
            "(default with --from-images: footprint,image, with efficientnet where installed and clip where "
            "its weights are set; default without: the one SceneScore row, footprint encoder)"
        ),
    )


def register(sub: argparse._SubParsersAction) -> None:
    """Add ``scenescore experiment`` to the command line's subcommands."""
    p = sub.add_parser(
        "experiment",
        help="run one of the paper's experiments",
        description=(
            "Run one of the paper's experiments and print its table with the paper's figures beside ours; "
            "writes table.md and results.json (the rows, the table and where they came from: commit, "
            "versions, device, cores, wall time, options) under --out; `scenescore report` renders it."
        ),
    )
    _add_selection(p)
    _add_running(p)
    _add_tidy(p)
    _add_variants(p)
    add_common(
        p, seed_help="torch's global random seed before each experiment; tidy: its first seed (default 0)"
    )
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_options(args)
    args.device = device_of(args)  # checked before any work; every runner passes it on
    if args.jobs is None:  # experiments that run no workers (heatmap) take one process
        from ..workers import default_jobs

        uses_workers = args.name == "all" or args.name in OWN_OPTIONS["--jobs"]
        args.jobs = default_jobs(args.device) if uses_workers else 1
        if args.jobs > 1:
            print(f"experiment: {args.jobs} worker processes, one per usable core (--jobs 1: one process)")
    args.model_cache = None  # the folder every runner passes to training as its model cache
    if args.name != "all":
        return _run_each(args, [args.name])
    import tempfile

    root = args.out or Path("runs") / "experiment-all"
    root.mkdir(parents=True, exist_ok=True)
    # a model that two experiments train alike (the dining energy of Table 1 and of tidying, say) is
    # trained once; the folder lives as long as this run, so no model of other code is ever read
    with tempfile.TemporaryDirectory(prefix=".models-", dir=root) as folder:
        args.model_cache = Path(folder)
        return _run_each(args, EXPERIMENTS, root)


def _run_each(args: argparse.Namespace, names: list[str], root: Path | None = None) -> int:
    """Each experiment of ``names`` in turn, its table printed and written; with ``root`` (``all``),
    each in its own folder there and every table and figure in ``root/report.md``."""
    import torch

    from ..experiments.report import write_document, write_results
    from . import provenance_of

    sections: list[str] = []
    entries: list[dict] = []  # every experiment's table and rows, for root/results.json
    start = time.perf_counter()
    for name in names:
        out = root / name if root is not None else args.out or Path("runs") / f"experiment-{name}"
        t0 = time.perf_counter()
        torch.manual_seed(args.seed)
        md, rows = RUNNERS[name](args, out)
        dt = time.perf_counter() - t0
        prov = provenance_of(args, time.perf_counter() - start)
        entries.append(write_results(out, rows, md, name=name, seconds=dt, provenance=prov))
        print(md)
        print(f"\n{name}: {dt:.0f} s; wrote {out}/table.md and {out}/results.json")
        figures = sorted(p.name for p in out.glob("*.png")) if out.is_dir() else []
        sections.append(
            md
            + f"\n\n{name}: {dt:.0f} s; table `{name}/table.md`, figures in `{name}/`"
            + "".join(f"\n\n![{f}]({name}/{f})" for f in figures)
        )
    if root is not None:
        from ..scene import atomic_write_text

        atomic_write_text(
            root / "report.md", "# SceneScore: the paper's experiments\n\n" + "\n\n".join(sections) + "\n"
        )
        write_document(root / "results.json", entries, provenance_of(args, time.perf_counter() - start))
        print(f"wrote {root}/report.md and {root}/results.json (scenescore report renders it)")
    return 0


def _methods(args: argparse.Namespace) -> list[str] | None:
    """``--methods`` as a list (``None``: every method of the experiment)."""
    return args.methods.split(",") if args.methods else None


def _missing(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..experiments import missing
    from ..experiments.report import over_seeds

    scenes_fn, encoder = None, None
    if args.from_images:
        from ..encoders import make_encoder
        from ..vision.graph import graphs_from_renders

        encoder = make_encoder("image")

        def scenes_fn(train, test):
            return graphs_from_renders(train, encoder=encoder), graphs_from_renders(test, encoder=encoder)

    res = missing.run(
        seeds=args.seeds,
        methods=_methods(args),
        quick=args.quick,
        progress=not args.quiet,
        scenes_fn=scenes_fn,
        encoder=encoder,
        device=args.device,
        jobs=args.jobs,
        cache=args.model_cache,
    )
    md = (
        "## Table 1: missing objects"
        + (" (graphs from rendered images)" if args.from_images else "")
        + "\n\n"
    )
    md += (
        "Position error t in cm, orientation error R in degrees (none for the symmetric bowl); "
        f"{over_seeds(args.seeds)}; the paper's figures in brackets.\n\n"
    )
    md += missing.format_missing(res)
    return md, res.rows()


def _encoder_names(args: argparse.Namespace) -> list[str] | None:
    """``--encoders`` as a list, checked (``None``: not given)."""
    if not args.encoders:
        return None
    from ..encoders import available_encoders

    names = [n.strip() for n in args.encoders.split(",") if n.strip()]
    unknown = [n for n in names if n not in available_encoders()]
    if unknown or not names:
        raise UserError(
            f"--encoders: unknown {unknown or args.encoders!r}; choose from {available_encoders()}"
        )
    if len(set(names)) != len(names):
        raise UserError(f"--encoders: each encoder once, got {args.encoders!r}")
    return names


def _novel(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..encoders import make_encoder
    from ..experiments import novel
    from ..experiments.report import over_seeds

    names = _encoder_names(args)
    if names is None and args.from_images:
        names = novel.default_encoders(print if not args.quiet else lambda s: None)
    encoders = [make_encoder(n) for n in names] if names else None
    scenes_fn = None
    if args.from_images:
        from ..vision.graph import graphs_from_renders

        def scenes_fn(train, test, encoder):
            return graphs_from_renders(train, encoder=encoder), graphs_from_renders(test, encoder=encoder)

    res = novel.run(
        seeds=args.seeds,
        methods=_methods(args),
        quick=args.quick,
        progress=not args.quiet,
        encoders=encoders,
        scenes_fn=scenes_fn,
        device=args.device,
        jobs=args.jobs,
        cache=args.model_cache,
    )
    md = (
        "## Table 2: novel objects (ordered rows of cutlery)"
        + (" (graphs from rendered images)" if args.from_images else "")
        + "\n\n"
    )
    md += (
        "Mean position error in cm of a removed piece of cutlery, per ordering rule; test sizes never "
        f"seen in training; {over_seeds(args.seeds)}; the paper's figures in brackets.\n\n"
    )
    if encoders and any(r.method.startswith("SceneScore (") for r in res.rows()):
        md += (
            "One SceneScore row per semantic encoder: "
            + ", ".join(f"{e.name} ({e.dim} numbers)" for e in encoders)
            + ".\n\n"
        )
    md += novel.format_novel(res)
    return md, res.rows()


def _heatmap(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..experiments import heatmap

    res = heatmap.run(
        seeds=args.seeds,
        quick=args.quick,
        progress=not args.quiet,
        out=out,
        device=args.device,
        cache=args.model_cache,
    )
    md = heatmap.format_heatmap(res)
    return md, res.rows()


def _compose(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..experiments import compose

    res = compose.run(
        seeds=args.seeds,
        methods=_methods(args),
        quick=args.quick,
        progress=not args.quiet,
        device=args.device,
        jobs=args.jobs,
        refine_options=None if args.alm is None else _alm_options(args.alm),
        cache=args.model_cache,
    )
    out.mkdir(parents=True, exist_ok=True)
    compose.plot_compose(res, out / "fig4.png")
    md = "## Fig. 4: composing with constraints (television, speakers, clutter)\n\n"
    md += (
        "Correct samples (aligned, symmetric, collision-free, inside the room) against the number of objects; "
        f"mean over {args.seeds} seed(s); the paper gives this as a plot only.\n\n"
    )
    md += (
        compose.format_compose(res) + "\n\nFigure: fig4.png (correct samples against the number of objects)."
    )
    return md, res.rows()


def _zoo(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    import json

    from ..experiments import zoo
    from ..learn import TrainConfig
    from ..plot import demo_figure
    from ..scenarios.zoo import ROOMS
    from ..scene import atomic_write_text

    names = args.scenarios.split(",") if args.scenarios else None
    cfg = TrainConfig(iterations=150) if args.quick else TrainConfig()
    res = zoo.run(
        seeds=args.seeds,
        scenarios=names,
        progress=not args.quiet,
        config=cfg,
        jobs=args.jobs,
        energy_only=args.energy_only,
        device=args.device,
        cache=args.model_cache,
        train_scenes=args.train_scenes,
    )
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "cases.json", json.dumps(res.per_case, indent=1) + "\n")
    demo_figure(
        res.worst_examples(),
        out / "worst.png",
        title="the zoo: each scenario's worst placement (truth dashed)",
    )
    md = "## The zoo: your own arrangements, at the CLI's defaults\n\n"
    how = (
        "by the learned energy alone (--energy-only)"
        if args.energy_only
        else "as `place` does (energy and non-overlap)"
    )
    rooms = [n for n in names or [] if n in ROOMS]
    removed = "one object removed per test scene"
    if rooms:
        removed += f" (three chairs at once in {', '.join(rooms)}, matched to the truths by assignment)"
    md += (
        f"{args.train_scenes or 48} training and 16 test scenes per scenario and seed, {removed} and placed "
        f"back {how}; {args.seeds} seed(s); every placement in cases.json; each scenario's worst in worst.png.\n\n"
    )
    return md + zoo.format_zoo(res), res.rows()


def _alm_options(text: str) -> dict[str, object]:
    """``--alm`` as ``alm`` options: a JSON object whose keys and values the ``alm`` solver accepts
    (checked by :func:`scenescore.solvers.get`, which names an unknown option and the valid ones)."""
    import json

    from ..solvers import get

    try:
        opts = json.loads(text)
    except json.JSONDecodeError as e:
        raise UserError(
            f"--alm: expected a JSON object such as '{{\"tol_grad\": 1.0}}', got {text!r} ({e.msg})"
        ) from None
    if not isinstance(opts, dict):
        raise UserError(f"--alm: expected a JSON object such as '{{\"tol_grad\": 1.0}}', got {text!r}")
    try:
        get("alm", **opts)
    except ValueError as e:  # ProblemError: an unknown option or a bad value, named
        raise UserError(f"--alm: {e}") from None
    return opts


def _efforts(text: str) -> tuple[float, ...]:
    """``--efforts`` as weights, each a finite number >= 0, each once."""
    try:
        out = tuple(float(v) for v in text.split(","))
    except ValueError:
        out = ()
    if not out or not all(0 <= v < float("inf") for v in out) or len(set(out)) != len(out):
        raise UserError(f"--efforts: expected distinct finite weights >= 0 separated by commas, got {text!r}")
    return out


def _tidy(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    import json

    from ..experiments import tidy
    from ..learn import TrainConfig
    from ..scene import atomic_write_text

    names = tuple(args.scenarios.split(",")) if args.scenarios else tidy.SCENARIOS
    if args.quick and not args.scenarios:
        names = ("dining",)
    iterations = args.iterations or (30 if args.quick else None)
    test_scenes = args.test_scenes or (1 if args.quick else 3)
    cfg = TrainConfig(iterations=iterations) if iterations else TrainConfig()
    efforts = tidy.EFFORTS if args.efforts is None else _efforts(args.efforts)
    log = (lambda s: None) if args.quiet else print
    res = tidy.run(
        names,
        efforts=efforts,
        test_scenes=test_scenes,
        seeds=range(args.seed, args.seed + args.seeds),
        config=cfg,
        log=log,
        device=args.device,
        jobs=args.jobs,
        cache=args.model_cache,
    )
    out.mkdir(parents=True, exist_ok=True)
    atomic_write_text(out / "cases.json", json.dumps(res.per_case(), indent=1) + "\n")
    tidy.plot_pareto(res, out / "pareto.png")
    md = "## Tidying messy scenes\n\n"
    md += (
        f"Scenarios {', '.join(names)}; {test_scenes} test scene(s) each, displaced five ways (one or two "
        f"objects shifted by {' or '.join(f'{f:g}' for f in tidy.SIZES)} of the bounds' half-extent and turned, "
        "or two objects of different kinds swapped); training "
        f"{cfg.iterations} iterations; {_seeds_named(args.seed, args.seeds)}, each its own split, model and "
        "displacements, the cases pooled. accepted: the scenario's check; precision and recall "
        "of the moved objects against the displaced ones; displacement and put-back in metres (centre and tip), "
        "ratio their totals' quotient; plan steps include buffer moves; no plan: the targets admit none (one "
        "outside the bounds, say); plans valid: of the plans made, the share valid when replayed.\n\n"
    )
    md += (
        tidy.format_tidy(res)
        + "\n\nFigure: pareto.png (accepted against displacement as the effort weight varies). Every case, "
        "with what each method moved and whether the check accepted it: cases.json."
    )
    return md, res.rows()


def _seeds_named(first: int, count: int) -> str:
    """``seed 0`` or ``seeds 0 to 2``."""
    return f"seed {first}" if count == 1 else f"seeds {first} to {first + count - 1}"


RUNNERS = {
    "missing": _missing,
    "novel": _novel,
    "heatmap": _heatmap,
    "compose": _compose,
    "zoo": _zoo,
    "tidy": _tidy,
}
