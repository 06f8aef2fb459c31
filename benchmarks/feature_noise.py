"""What feature noise in training (``TrainConfig.feature_noise``) does to placement error, on the
dining table (Table 1's scenario) and on Unseen-Class rows (Table 2's hardest column).

    python benchmarks/feature_noise.py [--noise 0,0.3,1.0] [--seed 0] [--rows 8] [--edge-encoder 32]

One seed, SceneScore only, energy placement (``SceneScorePlacer``); prints a markdown table of the
mean position error in cm per noise level. ``--edge-encoder W`` trains with the network's edge encoder
of width ``W`` (``TrainConfig.edge_encoder``; default none, as the trainer's default).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

from scenescore.evaluation import make_cases
from scenescore.placement import SceneScorePlacer
from scenescore.scenarios import DiningScenario, OrderingScenario
from scenescore.training import TrainConfig


def error_cm(scenario, train_s, test_s, noise: float, seed: int, edge_encoder: int | None = None) -> float:
    cases = make_cases(test_s, scenario.missing)
    tc = TrainConfig(feature_noise=noise, edge_encoder=edge_encoder)
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
    ap.add_argument("--edge-encoder", type=int, default=None, help="edge encoder width (default none)")
    args = ap.parse_args()
    torch.set_num_threads(1)
    dining = DiningScenario()
    d_train, d_test = dining.split(args.seed)
    rows = OrderingScenario(rule="unseen_class")
    r_train, r_test = rows.split(args.seed)
    print(f"edge encoder: {args.edge_encoder or 'none'}, seed {args.seed}")
    print("| feature noise | dining (cm) | Unseen-Class (cm) | seconds |\n|---:|---:|---:|---:|")
    for noise in (float(v) for v in args.noise.split(",")):
        t0 = time.perf_counter()
        d = error_cm(dining, d_train, d_test, noise, args.seed, args.edge_encoder)
        u = error_cm(rows, r_train, r_test[: args.rows], noise, args.seed, args.edge_encoder)
        print(f"| {noise:g} | {d:.2f} | {u:.2f} | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
