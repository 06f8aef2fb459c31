"""``scenescore train``: its options, and the run that reads the data and settings and trains."""

from __future__ import annotations

import argparse
from pathlib import Path

from ..learn import RAW_EDGES, VALIDATION_FRACTION, check_training_data
from ..learn.logs import require_tensorboard
from ..learn.training_state import SAVE_EVERY
from ..models.ensemble import MAX_MEMBERS
from ..scene.outputs import check_output_path
from ..scene.scene import read_jsonl
from ..workflow.crossval import CROSS_VALIDATE_BELOW, FOLDS, LEAVE_ONE_OUT_FROM, MIN_SCENES
from . import ITERATIONS, JOBS, PPM, UserError, add_common, add_device, device_of, named_model, number
from .train_settings import build_config, parse_overrides, read_config


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "train",
        help="train an energy model on example arrangements",
        description=(
            "Train the SceneScore energy (InfoNCE with Langevin counter-examples) on a .jsonl of scenes "
            "or a folder of top-down images."
        ),
        epilog=(
            "Training settings: every TrainConfig field can be set with --set KEY=VALUE or in a --config "
            "file, the network's and the chains' as network.KEY and chain.KEY (e.g. --set feature_noise=0.3 "
            "--set network.hidden=64). Precedence, lowest first: the defaults, --config, the options that "
            "set a field (--iterations, --negatives, --members, --average, --raw-edges, --activation, --message, "
            "--absolute), --set."
        ),
    )
    p.add_argument("data", type=Path, help=".jsonl of scenes, or a folder of images")
    p.add_argument("--out", type=Path, required=True, help="checkpoint to write (safetensors)")
    p.add_argument("--iterations", type=ITERATIONS, default=None, help="training iterations (default 600)")
    p.add_argument(
        "--negatives",
        type=number(1, 100_000, integer=True),
        default=None,
        help="counter-examples per scene (default 16)",
    )
    p.add_argument(
        "--members",
        type=number(1, MAX_MEMBERS, integer=True),
        default=None,
        help="the networks of the model's ensemble (seeds SEED, SEED+1000, ...): their mean energy "
        "places, and a placed object most members doubt is flagged; members times the training "
        "work (default 3; 1: one network; --set ensemble=snapshots takes the members from one run "
        "instead, 1 + (members - 1) x snapshot_cycle times the training)",
    )
    p.add_argument(
        "--activation",
        choices=["silu", "softplus", "leaky_relu"],
        default=None,
        help="the network's activation (default silu)",
    )
    p.add_argument(
        "--message",
        choices=["mlp", "linear"],
        default=None,
        help="message function f: an MLP or the paper's single linear layer (default mlp)",
    )
    p.add_argument("--absolute", action="store_true", help="the Abs ablation: absolute poses, no edges")
    p.add_argument(
        "--average",
        type=float,
        default=None,
        help="the trained model is the moving average of the weights over the second half of training, "
        "with this decay per iteration (default 0.99; 0: the last iterate)",
    )
    p.add_argument(
        "--raw-edges",
        action="store_true",
        help="no edge encoder: the message layers read the raw relative poses, with feature noise 0.3, "
        "no size noise and no re-anchored counter-examples (better on Table 2's ordered rows, worse on "
        "larger rooms)",
    )
    _add_train_run(p)
    _add_train_inputs(p)
    _add_train_outputs(p)
    _add_train_state(p)
    add_common(p)
    add_device(p)
    p.set_defaults(func=run_train)


def _add_train_run(p: argparse.ArgumentParser) -> None:
    """How ``scenescore train`` runs: compiled or not, in how many processes."""
    p.add_argument(
        "--compile",
        choices=["auto", "on", "off"],
        default=None,
        help="run the network's training passes compiled (torch.compile, kept in the user's cache folder): "
        "auto does where the training is large enough that the first run's compile pays for itself "
        "and a compiler is installed (default auto; off: eager)",
    )
    p.add_argument(
        "--init",
        default=None,
        metavar="MODEL",
        help="start from the weights of this model (a checkpoint, or the name of a model the package "
        "ships) instead of random ones, and fine-tune them on the data: a model trained on other "
        "arrangements lends its relations to a few examples. Its network's architecture and encoder "
        "must be this training's; the data's own length scale, walls and graph are kept",
    )
    p.add_argument(
        "--jobs",
        type=JOBS,
        default=None,
        help="worker processes, one thread each, that the model's trainings run in side by side: the final "
        "model's members and cross-validation's folds' networks (default: one per usable core, up to two "
        "where the trainings then end sooner, at most one per training; the model does not depend on it)",
    )


def _add_train_inputs(p: argparse.ArgumentParser) -> None:
    """``scenescore train``'s encoder, image scale and the settings given as a file or one by one."""
    p.add_argument(
        "--encoder",
        default=None,
        help=(
            "semantic encoder: footprint (default for .jsonl), image (default for a folder), "
            "efficientnet (ImageNet EfficientNet-Lite0; the 'pretrained' extra), clip"
        ),
    )
    p.add_argument(
        "--ppm",
        type=PPM,
        default=None,
        help="pixels per metre of the images (folder input; default: from the folder's dataset.json)",
    )
    p.add_argument(
        "--config",
        type=Path,
        default=None,
        help="a YAML mapping of training settings (TrainConfig's fields; network and chain as nested "
        "mappings or dotted keys); unknown keys are refused",
    )
    p.add_argument(
        "--set",
        action="append",
        default=None,
        metavar="KEY=VALUE",
        help="set one training setting, the value read as YAML (repeatable; overrides --config and the "
        "options above): feature_noise=0.3, walls=true, network.hidden=64, chain.steps=40",
    )


def _add_train_outputs(p: argparse.ArgumentParser) -> None:
    """``scenescore train``'s held-out scenes and what it writes besides the checkpoint."""
    p.add_argument(
        "--val",
        type=number(0, 1, open_hi=True),
        default=VALIDATION_FRACTION,
        help=f"fraction of the scenes held out for validation (default {VALIDATION_FRACTION:g}, at least 4 "
        "scenes; 0: none)",
    )
    p.add_argument(
        "--folds",
        type=number(1, 100, integer=True),
        default=None,
        help=f"validate by K-fold cross-validation and train the model on every scene (K more trainings); "
        f"1: one hold-out of --val (default {FOLDS} folds for {MIN_SCENES} to {CROSS_VALIDATE_BELOW - 1} "
        f"scenes, one hold-out for more, and one fold per scene, leaving one scene out, for "
        f"{LEAVE_ONE_OUT_FROM} to {MIN_SCENES - 1})",
    )
    p.add_argument(
        "--val-data", type=Path, default=None, help="a .jsonl of held-out scenes to validate on instead"
    )
    p.add_argument(
        "--report",
        type=Path,
        default=None,
        help="where to write the training report (default: train_report.json beside --out)",
    )
    p.add_argument(
        "--plot", type=Path, default=None, help="draw the learning curve and held-out placements here"
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="write the checkpoint even when the loss never fell below chance (a model that learned nothing)",
    )
    p.add_argument(
        "--log-dir",
        type=Path,
        default=None,
        help="write a TensorBoard log to this folder: the loss and learning rate of every iteration, then "
        "the held-out figures (needs the 'tensorboard' extra)",
    )


def _add_train_state(p: argparse.ArgumentParser) -> None:
    """``scenescore train``'s training state: where a run that is killed resumes from."""
    p.add_argument(
        "--state",
        type=Path,
        default=None,
        help="where the training state is written every --save-every iterations (weights, optimiser, "
        "averaged weights, chains, random streams; default: --out with .state appended); removed once "
        "the checkpoint is written",
    )
    p.add_argument(
        "--resume",
        action="store_true",
        help="go on from the training state (when there is one) to the checkpoint an uninterrupted run "
        "with the same data, settings and --seed writes (bit for bit on the CPU); a state of "
        "another training is refused",
    )
    p.add_argument(
        "--save-every",
        type=number(1, integer=True),
        default=SAVE_EVERY,
        metavar="N",
        help=f"iterations between two training states (default {SAVE_EVERY})",
    )


def _flag_settings(args: argparse.Namespace) -> dict[str, object]:
    """The training settings ``scenescore train``'s own options set (those given), as dotted keys."""
    out: dict[str, object] = dict(RAW_EDGES) if args.raw_edges else {}
    given = {
        "iterations": args.iterations,
        "negatives": args.negatives,
        "average": args.average,
        "members": args.members,
        "compile": args.compile,
    }
    out.update({k: v for k, v in given.items() if v is not None})
    network = {"network.activation": args.activation, "network.message": args.message}
    out.update({k: v for k, v in network.items() if v})
    if args.absolute:
        out["network.absolute"] = True
    return out


def run_train(args: argparse.Namespace) -> int:
    from ..encoders import make_encoder
    from ..learn import Run
    from ..workflow import NothingLearned, Outputs, Validation, train

    # settings first: a bad value fails before any data is read or any training is done
    cfg = build_config(
        read_config(args.config) if args.config is not None else {},
        _flag_settings(args),
        parse_overrides(args.set or []),
    )
    device = device_of(args)
    init = None
    if args.init is not None:  # a model that cannot be read fails before the data is read
        from ..learn.warm_start import Start

        init = Start.of(named_model(args.init), source=args.init)
    if args.log_dir is not None:
        check_output_path(args.log_dir, "--log-dir", folder=True)
        require_tensorboard()
    encoder = make_encoder(args.encoder or ("image" if args.data.is_dir() else "footprint"))
    if args.data.is_dir():
        from ..vision.graph import scenes_from_image_folder

        kw = {} if args.ppm is None else {"ppm": args.ppm}
        scenes = scenes_from_image_folder(args.data, encoder, progress=not args.quiet, **kw)
    elif args.data.exists():
        scenes = read_jsonl(args.data)
    else:
        raise UserError(f"{args.data}: no such file or folder")
    check_training_data(scenes)
    heldout = None
    if args.val_data is not None:
        if not args.val_data.exists():
            raise UserError(f"--val-data {args.val_data}: no such file")
        heldout = read_jsonl(args.val_data)
    try:
        train(
            scenes,
            cfg,
            seed=args.seed,
            encoder=encoder,
            validation=Validation(heldout=heldout, fraction=args.val, folds=args.folds),
            outputs=Outputs(checkpoint=args.out, report=args.report, plot=args.plot, source=args.data),
            device=device,
            progress=not args.quiet,
            run=Run(
                log_dir=args.log_dir,
                state=args.state or args.out.with_name(args.out.name + ".state"),
                resume=args.resume,
                save_every=args.save_every,
                jobs=args.jobs,
                init=init,
            ),
            force=args.force,
        )
    except NothingLearned as e:
        raise UserError(
            f"the training loss ({e.final_loss:.3f}) never fell below chance ({e.chance_loss:.3f}): "
            f"the model learned nothing, so {args.out} was not written; train longer (--iterations) or "
            "pass --force to write it anyway (with --resume: without training again)"
        ) from None
    return 0
