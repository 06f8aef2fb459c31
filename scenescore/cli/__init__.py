"""The ``scenescore`` command line: a thin layer over the library.

Each sub-command lives in a module of this package with ``register(subparsers)``; the module sets
``func`` on its parser. Errors the user can fix (bad files, keys, names) print one line and exit 2.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    import torch

    from ..models import ScoreModel

# modules of this package that add sub-commands, in the order --help lists them
COMMAND_MODULES = [
    "demo",
    "generate",
    "train",
    "evaluate",
    "place",
    "tidy",
    "experiment",
    "report",
    "problems",
    "heatmap",
    "explain",
    "export",
    "inspect_model",
    "info",
    "completion",
]


class UserError(Exception):
    """An error in the user's input; printed without a traceback."""


def _user_errors() -> tuple[type[BaseException], ...]:
    from ..errors import ConfigError
    from ..experiments.cluster import TasksFailed
    from ..models import CheckpointError
    from ..runtime.workers import WorkerDied
    from ..scene.scene import SceneError

    errs: list[type[BaseException]] = [
        UserError,
        SceneError,
        CheckpointError,
        ConfigError,
        FileNotFoundError,
        TasksFailed,
        WorkerDied,
    ]
    try:
        from ..problem.problem import ProblemError

        errs.append(ProblemError)
    except ImportError:
        pass
    return tuple(errs)


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="scenescore",
        description="Learn a cost function for object arrangement from examples, and plan with it.",
    )
    from .. import __version__

    parser.add_argument("--version", action="version", version=f"scenescore {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMAND_MODULES:
        importlib.import_module(f"{__name__}.{name}").register(sub)
    return parser


def number(
    lo: float | None = None,
    hi: float | None = None,
    *,
    integer: bool = False,
    open_lo: bool = False,
    open_hi: bool = False,
):
    """An argparse ``type``: a finite number (an integer if ``integer``) in the range given; anything else is
    refused by argparse with one line naming the option (``argument --val: expected ...``)."""
    import math

    def parse(text: str) -> float | int:
        kind = "an integer" if integer else "a finite number"
        rng = []
        if lo is not None:
            rng.append(f"{'>' if open_lo else '>='} {lo:g}")
        if hi is not None:
            rng.append(f"{'<' if open_hi else '<='} {hi:g}")
        expected = f"expected {kind}{' ' + ' and '.join(rng) if rng else ''}, got {text!r}"
        try:
            value: float | int = int(text) if integer else float(text)
        except ValueError:
            raise argparse.ArgumentTypeError(expected) from None
        ok = math.isfinite(value)
        ok = ok and (lo is None or (value > lo if open_lo else value >= lo))
        ok = ok and (hi is None or (value < hi if open_hi else value <= hi))
        if not ok:
            raise argparse.ArgumentTypeError(expected)
        return value

    return parse


def key_value(text: str, example: str) -> tuple[str, Any]:
    """``KEY=VALUE`` as ``(key, value)``, the value read as YAML (``8`` a number, ``16GB`` text,
    ``[0.05, 2.0]`` a list, ``{qos: high}`` a mapping): what ``train --set`` and ``experiment
    --slurm-set`` take. ValueError saying what is wrong otherwise, with ``example`` of the right form."""
    import yaml

    key, sep, value = text.partition("=")
    if not sep or not key.strip():
        raise ValueError(f"expected KEY=VALUE, e.g. {example}")
    try:
        return key.strip(), yaml.safe_load(value)
    except yaml.YAMLError as e:
        problem = str(e).splitlines()[0] if str(e) else type(e).__name__
        raise ValueError(f"the value {value!r} is not YAML ({problem})") from None


SEED = number(-(2**63), 2**63 - 1, integer=True)  # what torch's generators take
# the ranges of the command line's counts: more than the upper bound is a typo, not a plan
ITERATIONS = number(1, 10_000_000, integer=True)  # training iterations (TrainConfig's range)
SEEDS = number(1, 10_000, integer=True)  # runs over seeds seed .. seed+N-1
JOBS = number(1, 1024, integer=True)  # worker processes
SCENES = number(1, 1_000_000, integer=True)  # scenes to generate or test on
PLACEMENTS = number(1, 1_000_000_000, integer=True)  # placements to judge
PPM = number(0, open_lo=True)  # pixels per metre of a rendered image


def add_common(p: argparse.ArgumentParser, seed: int | None = 0, seed_help: str | None = None) -> None:
    """Options every command has."""
    from ..runtime.threads import MAX_THREADS

    p.add_argument("--seed", type=SEED, default=seed, help=seed_help or f"random seed (default {seed})")
    p.add_argument("--quiet", action="store_true", help="no progress bars")
    p.add_argument(
        "--memory-gb",
        type=float,
        default=None,
        help="memory budget in GB: larger allocations are refused before they are made "
        "(default: SCENESCORE_MEMORY_GB, else half of the machine's memory)",
    )
    p.add_argument(
        "--threads",
        type=number(1, MAX_THREADS, integer=True),
        default=None,
        help="the most threads this run's large batches use at once, in pieces of one torch thread each: "
        "the same results for any N (default: the cores other processes leave free)",
    )


def add_device(p: argparse.ArgumentParser) -> None:
    """``--device`` (the commands that run a model: train, evaluate, place, tidy, heatmap, demo, solve,
    compare, experiment); read it with :func:`device_of`."""
    p.add_argument(
        "--device",
        default="cpu",
        help="where the model and its tensors run: cpu, cuda or cuda:N (default cpu)",
    )


def device_of(args: argparse.Namespace) -> torch.device:
    """``--device`` as a torch device; one that is unknown or missing on this machine is a one-line error
    naming the option."""
    from ..runtime.devices import resolve_device

    return resolve_device(args.device, "--device")


def add_model(p: argparse.ArgumentParser) -> None:
    """The positional ``model`` of a command that loads one: a checkpoint file, or the name of a model
    the package ships; read it with :func:`model_of`."""
    p.add_argument(
        "model",
        help="checkpoint from `scenescore train`, or a scenario's name (dining, tv, zoo-pcb, ...) for the "
        "pretrained model the package ships for it",
    )


def model_of(args: argparse.Namespace, device: torch.device | None = None) -> ScoreModel:
    """``args.model`` loaded onto ``device`` (:func:`named_model`)."""
    return named_model(args.model, device)


def named_model(name: str, device: torch.device | None = None) -> ScoreModel:
    """The model ``name`` names, on ``device``: the checkpoint at that path, or, for a bare name (no
    folder, no extension) that is not a file here, the package's pretrained model of that name."""
    from pathlib import Path

    from ..models import load, pretrained

    path = Path(name)
    if path.exists() or path.suffix or path.name != name:
        return load(path, device=device)
    return pretrained(name, device=device)


def provenance_of(args: argparse.Namespace, seconds: float) -> dict:
    """Where a run's results came from (:func:`scenescore.runtime.provenance.collect_provenance`): the command
    line as typed, every option as parsed (defaults included), ``seconds`` of wall time, the device."""
    from ..runtime.provenance import collect_provenance

    # the handler, the raw line and the commit at the start (recorded apart), a temporary folder
    skip = {"func", "argv", "commit_at_start", "model_cache"}
    options = {k: v for k, v in vars(args).items() if k not in skip}
    return collect_provenance(
        getattr(args, "argv", None),
        options,
        seconds,
        getattr(args, "device", None),
        getattr(args, "commit_at_start", None),
    )


FOLDER_OUTPUTS = {"demo", "experiment", "compare"}  # commands whose --out is a folder


def _check_outputs(args: argparse.Namespace) -> None:
    """Every output path the command was given can be written, checked before any work is done."""
    from ..scene.outputs import check_output_path

    for attr in ("out", "plot", "report", "scene_out", "images", "state"):
        value = getattr(args, attr, None)
        if isinstance(value, (str, os.PathLike)):
            folder = attr == "images" or (attr == "out" and args.command in FOLDER_OUTPUTS)
            check_output_path(value, "--" + attr.replace("_", "-"), folder=folder)


def main(argv: list[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    args.argv = list(sys.argv[1:] if argv is None else argv)  # the command line as typed, for provenance
    if args.command == "experiment":  # the code a long run started from, before the checkout can move
        from ..runtime.provenance import git_commit

        args.commit_at_start = git_commit()
    if not getattr(args, "func", None):
        parser.print_help()
        return 0
    try:
        from ..runtime.memory import budget, set_budget
        from ..runtime.threads import thread_budget

        set_budget(getattr(args, "memory_gb", None))  # this run's budget; a bad value is an error now
        budget()
        _check_outputs(args)
        with thread_budget(getattr(args, "threads", None)):  # torch's setting restored on the way out
            rc = args.func(args)
    except _user_errors() as e:
        msg = e.args[0] if isinstance(e, KeyError) and e.args else str(e)
        print(f"scenescore {args.command}: error: {msg}", file=sys.stderr)
        return 2
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:  # the reader went away (``scenescore generate --list | head``)
        sys.stderr.close()
        return 0
    finally:
        from ..runtime.memory import set_budget

        set_budget(None)
    return int(rc or 0)


if __name__ == "__main__":
    sys.exit(main())
