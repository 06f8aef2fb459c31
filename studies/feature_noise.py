"""What feature noise in training (``TrainConfig.feature_noise``) does to placement error, on the
dining table (Table 1's scenario) and on Unseen-Class rows (Table 2's hardest column).

    python studies/feature_noise.py [--noise 0,0.3,1.0] [--seed 0] [--rows 8] [--edge-encoder 32]
        [--size-noise 0.3] [--only dining|unseen]

One seed, SceneScore only, energy placement (``SceneScorePlacer``); prints a markdown table of the
mean position error in cm per noise level. ``--edge-encoder W`` trains with the network's edge encoder
of width ``W`` (``TrainConfig.edge_encoder``; ``0``: none); ``--size-noise S`` adds noise of std ``S``
length scales to the scale descriptor (``TrainConfig.size_noise``); both default to the trainer's.
``--only`` runs one column.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from scenescore.evaluation.cases import make_cases
from scenescore.learn import TrainConfig
from scenescore.planning.placement import SceneScorePlacer
from scenescore.scenarios import DiningScenario, OrderingScenario


def error_cm(scenario, train_s, test_s, noise: float, seed: int, **config) -> float:
    cases = make_cases(test_s, scenario.missing)
    tc = TrainConfig(feature_noise=noise, **config)
    placer = SceneScorePlacer(train_config=tc).fit(train_s, seed=seed)
    pred = placer.predict([c.scene for c in cases], seed=seed)
    errs = [
        100 * math.hypot(p[c.name].pose[0] - c.truth[0], p[c.name].pose[1] - c.truth[1])
        for p, c in zip(pred, cases)
    ]
    return float(np.mean(errs))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--noise", default="0,0.3,1.0", help="comma-separated feature noise levels")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--rows", type=int, default=8, help="Unseen-Class test rows (6 cases each)")
    default = TrainConfig()
    ap.add_argument(
        "--edge-encoder",
        type=int,
        default=default.edge_encoder or 0,
        help=f"edge encoder width, 0 for none (default {default.edge_encoder or 0})",
    )
    ap.add_argument(
        "--size-noise",
        type=float,
        default=default.size_noise,
        help=f"noise on the scale descriptor, length scales (default {default.size_noise:g})",
    )
    ap.add_argument("--only", choices=["dining", "unseen"], default=None, help="one column only")
    args = ap.parse_args()
    torch.set_num_threads(1)
    dining = DiningScenario()
    d_train, d_test = dining.split(args.seed)
    rows = OrderingScenario(rule="unseen_class")
    r_train, r_test = rows.split(args.seed)
    config = {"edge_encoder": args.edge_encoder or None, "size_noise": args.size_noise}
    print(f"edge encoder: {args.edge_encoder or 'none'}, size noise {args.size_noise:g}, seed {args.seed}")
    print("| feature noise | dining (cm) | Unseen-Class (cm) | seconds |\n|---:|---:|---:|---:|")
    for noise in (float(v) for v in args.noise.split(",")):
        t0 = time.perf_counter()
        d = u = math.nan
        if args.only != "unseen":
            d = error_cm(dining, d_train, d_test, noise, args.seed, **config)
        if args.only != "dining":
            u = error_cm(rows, r_train, r_test[: args.rows], noise, args.seed, **config)
        print(f"| {noise:g} | {d:.2f} | {u:.2f} | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
