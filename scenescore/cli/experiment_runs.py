"""Each experiment of ``scenescore experiment``: read its options, run it, write its files, and return its
table (markdown) and rows (:data:`RUNNERS`, by name)."""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from . import UserError

if TYPE_CHECKING:
    from ..experiments.execution import Execution
    from ..experiments.report import Row
    from ..experiments.tasks import Sweep


def _sweep(args: argparse.Namespace, out: Path) -> Sweep:
    """Where the experiment keeps each finished task's record (``out/tasks``), so that the same command
    run again computes only the tasks it has no record of (``--fresh``: every one), and what runs the
    tasks (``--executor``: this machine's workers, without ``--jobs`` on a CPU up to two per core where
    the tasks then end sooner; or submitit's jobs with their logs under ``out/slurm``)."""
    from ..experiments.tasks import Sweep

    sweep = Sweep(out / "tasks", fresh=bool(getattr(args, "fresh", False)))
    slurm = {k: getattr(args, k, None) for k in SLURM_OPTIONS}
    executor = getattr(args, "executor", None) or "local"
    if executor == "local":
        given = [f"--{k.replace('_', '-')}" for k, v in slurm.items() if v is not None]
        if given:
            raise UserError(f"{', '.join(given)}: options of --executor slurm or submitit-local")
        if getattr(args, "balance", False):  # --jobs not given, on a CPU: --jobs is then the cores
            from ..runtime.workers import map_balanced

            sweep.executor = map_balanced
        return sweep
    from ..experiments.cluster import SlurmConfig, SubmititExecutor

    try:
        config = SlurmConfig(
            out / "slurm",
            cluster="slurm" if executor == "slurm" else "local",
            partition=slurm["slurm_partition"],
            time_min=slurm["slurm_time"] or 240,
            gpus=slurm["slurm_gpus"] or 0,
            cpus=slurm["slurm_cpus"] or 1,
            extra=dict(slurm["slurm_set"] or []),
        )
    except ValueError as e:
        raise UserError(f"--slurm-set: {e}") from e
    sweep.executor = SubmititExecutor(config)
    return sweep


SLURM_OPTIONS = ("slurm_partition", "slurm_time", "slurm_gpus", "slurm_cpus", "slurm_set")


def _methods(args: argparse.Namespace) -> list[str] | None:
    """``--methods`` as a list (``None``: every method of the experiment)."""
    return args.methods.split(",") if args.methods else None


def _shared(args: argparse.Namespace, out: Path) -> Execution:
    """How every experiment runs alike: progress unless ``--quiet``, the device, worker processes, model
    cache and the task records under ``out`` (:func:`_sweep`)."""
    from ..experiments.execution import Execution

    return Execution(
        progress=not args.quiet,
        device=args.device,
        jobs=args.jobs,
        cache=args.model_cache,
        sweep=_sweep(args, out),
    )


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
        scenes_fn=scenes_fn,
        encoder=encoder,
        execution=_shared(args, out),
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
        encoders=encoders,
        scenes_fn=scenes_fn,
        execution=_shared(args, out),
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
        out=out,
        execution=_shared(args, out),
    )
    md = heatmap.format_heatmap(res)
    return md, res.rows()


def _compose(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..experiments import compose

    res = compose.run(
        seeds=args.seeds,
        methods=_methods(args),
        quick=args.quick,
        refine_options=None if args.alm is None else _alm_options(args.alm),
        execution=_shared(args, out),
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
    from ..learn import ONE_NETWORK, TrainConfig
    from ..scenarios.zoo import ROOMS
    from ..scene.outputs import atomic_write_text
    from ..viz.plot import demo_figure

    names = args.scenarios.split(",") if args.scenarios else None
    cfg = TrainConfig(iterations=150 if args.quick else 600, members=args.members or ONE_NETWORK["members"])
    res = zoo.run(
        seeds=args.seeds,
        scenarios=names,
        config=cfg,
        energy_only=args.energy_only,
        train_scenes=args.train_scenes,
        execution=_shared(args, out),
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
    from dataclasses import replace

    from ..experiments import tidy
    from ..learn import ONE_NETWORK, TrainConfig
    from ..scene.outputs import atomic_write_text

    names = tuple(args.scenarios.split(",")) if args.scenarios else tidy.SCENARIOS
    if args.quick and not args.scenarios:
        names = ("dining",)
    iterations = args.iterations or (30 if args.quick else None)
    test_scenes = args.test_scenes or (1 if args.quick else tidy.TEST_SCENES)
    cfg = TrainConfig(iterations=iterations, **ONE_NETWORK) if iterations else TrainConfig(**ONE_NETWORK)
    efforts = tidy.EFFORTS if args.efforts is None else _efforts(args.efforts)
    log = (lambda s: None) if args.quiet else print
    # tidy's own lines follow --quiet; its training's bars are off whatever it is (tidy's default)
    execution = replace(_shared(args, out), progress=False, log=log)
    res = tidy.run(
        names,
        efforts=efforts,
        test_scenes=test_scenes,
        seeds=range(args.seed, args.seed + args.seeds),
        config=cfg,
        execution=execution,
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


def _sizes(text: str) -> list[int]:
    """``--sizes`` as numbers of objects, each 2 to 10, each once, in order."""
    from ..scenarios.relation_problems import MAX_OBJECTS

    try:
        out = [int(v) for v in text.split(",")]
    except ValueError:
        out = []
    if not out or not all(2 <= v <= MAX_OBJECTS for v in out) or len(set(out)) != len(out):
        raise UserError(
            f"--sizes: expected distinct whole numbers 2 to {MAX_OBJECTS} separated by commas, got {text!r}"
        )
    return sorted(out)


def _relations(args: argparse.Namespace, out: Path) -> tuple[str, list[Row]]:
    from ..experiments import relation_models, relations

    sizes = _sizes(args.sizes) if args.sizes else ([2, 3] if args.quick else list(relations.SIZES))
    problems = args.problems or (5 if args.quick else 100)
    settings = relations.RelationSettings(
        sizes=sizes,
        problems=problems,
        tries=args.tries or 10,
        pool=args.pool or relations.POOL,
        methods=_methods(args),
        examples=args.examples or (256 if args.quick else relations.EXAMPLES),
        restarts=relation_models.RESTARTS if args.restarts is None else args.restarts,
        config=relations.train_config(args.iterations, args.quick),
    )
    res = relations.run(seeds=args.seeds, settings=settings, execution=_shared(args, out))
    out.mkdir(parents=True, exist_ok=True)
    relations.plot_relations(res, out / "solved.png")
    iterations = relations.train_config(args.iterations, args.quick).iterations
    md = "## Composing learned relations: random consistent problems (Diffusion-CCSP's protocol)\n\n"
    md += (
        f"One relation model per relation ({', '.join(res.relations)}), trained on {res.examples} example "
        f"scenes of 2 or 3 objects ({iterations} iterations each, {relations.PERTURBED} perturbed "
        "counter-examples per example; trained again with the next member seed, at most "
        f"{res.restarts} times, while its edge on {relation_models.VALIDATION} held-out examples "
        "is flat); problems of N objects with about 1.5 N relations, non-overlap and "
        "bounds, drawn backwards from "
        f"a random arrangement; each try is the best of {res.pool} particles by the method's own cost, "
        f"every heading swept over {relations.HEADINGS} before the final descent; "
        f"rejection sampling draws up to {res.tries * res.pool * relations.STEPS} uniform arrangements "
        "per problem.\n\n"
    )
    md += relations.format_relations(res) + "\n\nFigure: solved.png (fraction solved against N)."
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
    "relations": _relations,
}
