"""``scenescore experiment``: the paper's experiments, our tables beside the paper's figures."""

from __future__ import annotations

import argparse
import time
from pathlib import Path

from ..models.ensemble import MAX_MEMBERS
from . import ITERATIONS, JOBS, SCENES, SEEDS, UserError, add_common, add_device, device_of, key_value, number
from .experiment_runs import RUNNERS

EXPERIMENTS = ["missing", "novel", "heatmap", "compose", "zoo", "tidy", "relations"]

# the options that only some experiments read (every other option applies to all); their defaults are
# None or False, so a value other than those was given on the command line
OWN_OPTIONS: dict[str, tuple[str, ...]] = {
    "--methods": ("missing", "novel", "compose", "relations"),
    "--scenarios": ("zoo", "tidy"),
    "--energy-only": ("zoo",),
    "--train-scenes": ("zoo",),
    "--members": ("zoo",),
    "--test-scenes": ("tidy",),
    "--efforts": ("tidy",),
    "--iterations": ("tidy", "relations"),
    "--problems": ("relations",),
    "--sizes": ("relations",),
    "--tries": ("relations",),
    "--examples": ("relations",),
    "--restarts": ("relations",),
    "--pool": ("relations",),
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
        "'SceneScore (langevin>casadi)'; relations: 'Relations (langevin)', 'Relations (langevin>alm)', "
        "'Whole scenes (langevin>alm)', 'Rejection (uniform)'",
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
        help="worker processes, one thread each (default: one per usable core, or up to two per core where "
        "an experiment's tasks then end sooner, as three seeds on two cores in three processes; with "
        "--device cuda, as many "
        "sharing the GPU as its free memory holds at 2 GiB each, at most one per usable core; "
        "1 runs everything in this process): compose, heatmap, missing and novel run their seeds in "
        "them, relations its seed and size pairs, zoo its scenario and seed pairs, tidy its scenarios; "
        "the figures do not depend on it",
    )
    p.add_argument(
        "--fresh",
        action="store_true",
        help="compute every task again: by default each finished task's record is kept under OUT/tasks and "
        "the same command run again reuses those of the same settings and code, computing only the rest "
        "(an interrupted run resumes)",
    )
    p.add_argument(
        "--model-cache",
        type=Path,
        default=None,
        metavar="DIR",
        help="keep every model the run trains in DIR, and read from there each model a run of the same "
        "code trains alike (the same data, settings, seed and device); the models are named by all "
        "of these, so DIR may serve many runs (default: none kept; all shares a folder of its own "
        "between its experiments for the length of the run)",
    )
    p.add_argument(
        "--train-scenes",
        type=number(2, 48, integer=True),
        default=None,
        help="zoo: train on the first N of each split's 48 training scenes, the same test scenes "
        "(12: the small-data variant; default all 48)",
    )
    p.add_argument(
        "--members",
        type=number(1, MAX_MEMBERS, integer=True),
        default=None,
        help="zoo: each model an ensemble of this many networks (TrainConfig.members; default 1, the "
        "paper's one network, as every experiment trains)",
    )
    p.add_argument(
        "--energy-only",
        action="store_true",
        help="zoo: place by the learned energy alone (default: as `place` does, energy and non-overlap)",
    )
    p.add_argument(
        "--quick", action="store_true", help="short training, for a smoke test (figures not comparable)"
    )


def _key_value(text: str) -> tuple[str, object]:
    """``--slurm-set KEY=VALUE``: a submitit parameter, the value read as YAML (:func:`key_value`)."""
    try:
        return key_value(text, "slurm_mem=16GB (a submitit parameter)")
    except ValueError as e:
        raise argparse.ArgumentTypeError(f"{text!r}: {e}") from None


def _add_cluster(p: argparse.ArgumentParser) -> None:
    """Where the tasks run: this machine's worker processes, a SLURM cluster, or submitit's local jobs."""
    p.add_argument(
        "--executor",
        choices=["local", "slurm", "submitit-local"],
        default=None,
        help="what runs the tasks (default local: this machine's worker processes, --jobs of them); slurm: "
        "each task a job of one SLURM job array, submitted through submitit from this machine (a login "
        "node; needs the cluster extra), its logs under OUT/slurm; submitit-local: the slurm path on this "
        "machine's processes, --jobs at a time (to try a sweep before submitting it)",
    )
    p.add_argument("--slurm-partition", default=None, help="slurm: the partition (default the cluster's)")
    p.add_argument(
        "--slurm-time",
        type=number(1, 60 * 24 * 30, integer=True),
        default=None,
        help="slurm, submitit-local: each job's time limit in minutes (default 240)",
    )
    p.add_argument(
        "--slurm-gpus", type=number(0, 64, integer=True), default=None, help="slurm: GPUs per job (default 0)"
    )
    p.add_argument(
        "--slurm-cpus",
        type=number(1, 1024, integer=True),
        default=None,
        help="slurm, submitit-local: CPU cores per job, and the torch threads a task runs on (default 1)",
    )
    p.add_argument(
        "--slurm-set",
        type=_key_value,
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="slurm: any other submitit parameter by its name, the value read as YAML; repeat for several "
        "(slurm_mem=16GB, slurm_account=lab, slurm_array_parallelism=8, "
        "'slurm_additional_parameters={qos: high}')",
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
        help="tidy: training iterations per scenario (default the trainer's 600; 30 with --quick); "
        "relations: per relation model (default 600; 100 with --quick)",
    )


def _add_relations(p: argparse.ArgumentParser) -> None:
    """The relations experiment's problems: how many per size, which sizes, how many tries."""
    p.add_argument(
        "--problems",
        type=SCENES,
        default=None,
        help="relations: random consistent problems per number of objects (default 100; 5 with --quick)",
    )
    p.add_argument(
        "--sizes",
        default=None,
        help="relations: comma-separated numbers of objects per problem, each 2 to 10 (default 2,3,...,10; "
        "2,3 with --quick)",
    )
    p.add_argument(
        "--tries",
        type=number(1, 10_000, integer=True),
        default=None,
        help="relations: tries (samples) per problem and method, each the best of --pool particles; "
        "rejection sampling draws tries x pool x 100 (default 10)",
    )
    p.add_argument(
        "--pool",
        type=number(1, 1000, integer=True),
        default=None,
        help="relations: Langevin particles per try, each try the best of them by the method's own cost "
        "(default 16)",
    )
    p.add_argument(
        "--examples",
        type=SCENES,
        default=None,
        help="relations: example scenes each relation model learns from (default 2048; 256 with --quick)",
    )
    p.add_argument(
        "--restarts",
        type=number(0, 10, integer=True),
        default=None,
        help="relations: how many times at most a relation model whose edge is flat on its held-out examples "
        "is trained again, with the next member seed (default 3; 0: each trained once)",
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
            "versions, device, cores, wall time, options) under --out; `scenescore report` renders it. Each "
            "finished task's record is kept under OUT/tasks, so the same command run again after an interruption "
            "computes only the tasks not yet done (--fresh: every one)."
        ),
    )
    _add_selection(p)
    _add_running(p)
    _add_cluster(p)
    _add_tidy(p)
    _add_relations(p)
    _add_variants(p)
    add_common(
        p, seed_help="torch's global random seed before each experiment; tidy: its first seed (default 0)"
    )
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    check_options(args)
    args.device = device_of(args)  # checked before any work; every runner passes it on
    # on a CPU by default, up to two worker processes per core where an experiment's tasks then end sooner
    args.balance = args.jobs is None and args.device.type == "cpu"
    if args.jobs is None:
        from ..runtime.workers import default_jobs

        args.jobs = default_jobs(args.device)
        if args.jobs > 1 and args.balance:
            print(
                f"experiment: worker processes on {args.jobs} cores, one per core, or up to two where an "
                "experiment's tasks then end sooner (--jobs N: N processes; 1: this one)"
            )
        elif args.jobs > 1:
            how = f"sharing {args.device}, as many as its free memory holds and at most one per usable core"
            print(f"experiment: {args.jobs} worker processes, {how} (--jobs 1: one process)")
    # args.model_cache: the folder every runner passes to training as its model cache
    if args.name != "all":
        return _run_each(args, [args.name])
    from ..learn.cache import run_cache

    root = args.out or Path("runs") / "experiment-all"
    root.mkdir(parents=True, exist_ok=True)
    # a model that two experiments train alike (the dining energy of Table 1 and of tidying, say) is
    # trained once: in the folder given, else in one that lives as long as this run
    with run_cache(args.model_cache, within=root) as folder:
        args.model_cache = folder
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
        from ..scene.outputs import atomic_write_text

        atomic_write_text(
            root / "report.md", "# SceneScore: the paper's experiments\n\n" + "\n\n".join(sections) + "\n"
        )
        write_document(root / "results.json", entries, provenance_of(args, time.perf_counter() - start))
        print(f"wrote {root}/report.md and {root}/results.json (scenescore report renders it)")
    return 0
