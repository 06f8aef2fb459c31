"""Where an experiment's time goes: one slice of it under cProfile, by phase, on one torch thread.

    python benchmarks/profile_experiment.py compose [--level 3] [--samples 5000]
    python benchmarks/profile_experiment.py zoo [--scenario zoo-banquet] [--seed 0]
    python benchmarks/profile_experiment.py tidy [--model model.ckpt]
    [--top 25]

``compose``: Fig. 4's protocol at one clutter level (its energy trained, ``--samples`` Langevin samples
over five cluttered scenes, all of them repaired by ``alm``, both counted by the scenario's exact check),
the SceneScore rows only. ``zoo``: one scenario and seed of ``scenescore experiment zoo`` (training on 48
scenes, the 16 placements). ``tidy``: the README's ``scenescore tidy model.ckpt examples/messy_dining.json
--out tidy.json --plot tidy.png`` after its import (``--model``: that checkpoint; default: trained first
as the README does, 48 generated dining scenes and 150 iterations, outside the profile). Prints the wall
time, the cumulative seconds of each phase (a phase is a function; phases nest, so the shares need not
add up) and the ``--top`` functions by cumulative time.
"""

from __future__ import annotations

import argparse
import cProfile
import pstats
import tempfile
import time
from pathlib import Path

import torch

# phase -> (file suffix, function name) whose cumulative time is the phase's
PHASES = {
    "training (scenescore.learn.loop.fit)": ("scenescore/learn/loop.py", "fit"),
    "Langevin chains (sampling.langevin: training's counter-examples and the sampler)": (
        "scenescore/sampling.py",
        "langevin",
    ),
    "energy network forward (EnergyNet._pooled)": ("scenescore/models/network.py", "_pooled"),
    "placement (placement.place_many)": ("scenescore/placement.py", "place_many"),
    "exact checks (Problem.check)": ("scenescore/problem.py", "check"),
    "batched repair (alm)": ("scenescore/solvers/alm.py", "_solve"),
    "tidy: choosing the objects to move (tidying.selection.select_moves)": (
        "scenescore/tidying/selection.py",
        "select_moves",
    ),
    "tidy: its rounds of re-placing sets (tidying.selection.best_replacements)": (
        "scenescore/tidying/selection.py",
        "best_replacements",
    ),
    "screening draws (sampling.screen: the selection's and the placement's)": (
        "scenescore/sampling.py",
        "screen",
    ),
    "tidy: placing the moved objects again (tidying.pruning.place_again)": (
        "scenescore/tidying/pruning.py",
        "place_again",
    ),
    "tidy: refining and planning (tidying.pruning.refine_and_plan)": (
        "scenescore/tidying/pruning.py",
        "refine_and_plan",
    ),
}


def readme_model(folder: Path) -> Path:
    """The README's dining model: ``scenescore generate dining --n 48``, then ``scenescore train`` for 150
    iterations."""
    from scenescore.cli import main

    data, model = folder / "data.jsonl", folder / "model.ckpt"
    assert main(["generate", "dining", "--n", "48", "--out", str(data)]) == 0
    assert main(["train", str(data), "--out", str(model), "--iterations", "150", "--quiet"]) == 0
    return model


def run(args: argparse.Namespace, folder: Path) -> None:
    from scenescore.runtime.threads import thread_budget

    if args.what == "tidy":  # as the command runs it: torch's own threads (tidy chooses its own)
        from scenescore.cli import main

        example = Path(__file__).resolve().parents[1] / "examples" / "messy_dining.json"
        out = ["--out", str(folder / "tidy.json"), "--plot", str(folder / "tidy.png"), "--quiet"]
        assert main(["tidy", str(args.model), str(example), *out]) == 0
        return
    with thread_budget(1):
        if args.what == "compose":
            from scenescore.experiments import compose
            from scenescore.experiments.execution import Execution

            compose.run(
                seeds=1,
                methods=["SceneScore", compose.BATCHED],
                levels=[args.level],
                samples=args.samples,
                execution=Execution(progress=False),
            )
        else:
            from scenescore.experiments import zoo

            zoo.run_one(args.scenario, args.seed)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("what", choices=["compose", "zoo", "tidy"])
    ap.add_argument("--level", type=int, default=3, help="compose: clutter boxes (default 3)")
    ap.add_argument("--samples", type=int, default=5000, help="compose: samples (default 5000)")
    ap.add_argument("--scenario", default="zoo-banquet", help="zoo: the scenario (default zoo-banquet)")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--model", type=Path, default=None, help="tidy: the checkpoint (default: trained first)")
    ap.add_argument("--top", type=int, default=25, help="functions listed by cumulative time (default 25)")
    args = ap.parse_args()
    torch.manual_seed(args.seed)
    with tempfile.TemporaryDirectory() as folder:
        if args.what == "tidy" and args.model is None:
            args.model = readme_model(Path(folder))
        prof = cProfile.Profile()
        t = time.perf_counter()
        prof.enable()
        run(args, Path(folder))
        prof.disable()
        wall = time.perf_counter() - t
    stats = pstats.Stats(prof)
    threads = "torch's own threads" if args.what == "tidy" else "one torch thread"
    print(f"{args.what}: {wall:.1f} s wall on {threads} (under the profiler, which slows it)\n")
    print("| phase | seconds | share of the wall time |")
    print("|---|---:|---:|")
    raw = stats.stats  # type: ignore[attr-defined]
    for label, (suffix, name) in PHASES.items():
        cum = sum(v[3] for (f, _, fn), v in raw.items() if f.endswith(suffix) and fn == name)
        if cum > 0:  # the phases this slice has
            print(f"| {label} | {cum:.1f} | {cum / wall:.0%} |")
    print()
    stats.sort_stats("cumulative").print_stats(args.top)


if __name__ == "__main__":
    main()
