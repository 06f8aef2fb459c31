"""Does a network trained compiled place faster through its compiled pose gradient, counting the first compile?

    python studies/compiled_placements.py [--scenario zoo-pcb|dining|tidy-dining] [--seed 0] [--rounds 2]

One network is trained as the experiments train it when they settle its compile ``"on"`` (600
iterations, one network, ``compile="on"``), then the same placements are timed in turn, eager and within
``ScoreModel.compiled_chains()``, ``--rounds`` times in one process: the first compiled round includes
compiling the placements' graphs (or reading them from the cache folder, ``SCENESCORE_CACHE_DIR``, when
a run before left them there), the later ones do not. ``dining``: Table 1's 96 placements (its test
scenes, each place setting's bowl, fork or knife removed, as ``experiment missing`` places them);
``tidy-dining``: the tidy experiment's dining cases (its first 3 test scenes displaced every way, as
``experiment tidy`` makes them) tidied at the default effort after the move gain's calibration, both as
``experiment tidy`` runs them; another scenario: the zoo's test cases (``experiment zoo``'s
``place_back``). Prints the seconds of each round and the largest difference between the eager and
compiled placements' poses.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from dataclasses import replace

import numpy as np
import torch

import scenescore as ss
from scenescore.evaluation.cases import make_cases
from scenescore.experiments import zoo
from scenescore.experiments.messy import messy_cases
from scenescore.experiments.tidy import TEST_SCENES, calibration_scenes
from scenescore.learn import ONE_NETWORK, TrainConfig
from scenescore.planning.tidying import calibrate, tidy_many


def placements(
    scenario: str, seed: int
) -> tuple[list[ss.Scene], Callable[[ss.models.ScoreModel], list[ss.Scene]]]:
    """The training scenes and a function placing the test cases with a model."""
    if scenario == "dining":
        sc = ss.scenarios.get("dining")
        train, test = sc.split(seed)
        missing = make_cases(test, sc.missing)  # placed as SceneScorePlacer.predict places them
        return train, lambda m: zoo.place_back(m, missing, seed, energy_only=True)
    if scenario == "tidy-dining":
        sc = ss.scenarios.get("dining")
        train, test = sc.split(seed)
        messy = [c.messy for c in messy_cases(sc, test[:TEST_SCENES], seed)]
        held = calibration_scenes(train, test, TEST_SCENES)

        def tidied(m: ss.models.ScoreModel) -> list[ss.Scene]:
            calibrate(m, held, seed=seed)
            return [r.after for r in tidy_many(m, messy, seed=seed)]

        return train, tidied
    train, _, test = zoo.training_split(scenario, seed)
    cases = zoo.zoo_cases(ss.scenarios.get(scenario), test, seed)
    return train, lambda m: zoo.place_back(m, cases, seed)


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="zoo-pcb")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rounds", type=int, default=2)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    train, place = placements(args.scenario, args.seed)
    t = time.perf_counter()
    cfg = replace(TrainConfig(iterations=600, **ONE_NETWORK), compile="on")
    model = ss.learn.fit(train, cfg, seed=args.seed, progress=False)
    print(f"{args.scenario}, seed {args.seed}: trained in {time.perf_counter() - t:.1f} s")
    print("| round | eager (s) | compiled (s) | largest pose difference |")
    print("|---:|---:|---:|---:|")
    for r in range(args.rounds):
        t = time.perf_counter()
        eager = place(model)
        t_eager = time.perf_counter() - t
        t = time.perf_counter()
        with model.compiled_chains():
            compiled = place(model)
        t_compiled = time.perf_counter() - t
        diff = max(float(np.abs(a.poses() - b.poses()).max()) for a, b in zip(eager, compiled))
        print(f"| {r + 1} | {t_eager:.1f} | {t_compiled:.1f} | {diff:.2e} |")


if __name__ == "__main__":
    main()
