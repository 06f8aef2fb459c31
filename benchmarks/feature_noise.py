"""What feature noise in training (``TrainConfig.feature_noise``) does to placement error, on the
dining table (Table 1's scenario) and on Unseen-Class rows (Table 2's hardest column).

    python benchmarks/feature_noise.py [--noise 0,0.3,1.0] [--seed 0] [--rows 8]

One seed, SceneScore only, energy placement (``SceneScorePlacer``); prints a markdown table of the
mean position error in cm per noise level.
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


def error_cm(scenario, train_s, test_s, noise: float, seed: int) -> float:
    cases = make_cases(test_s, scenario.missing)
    placer = SceneScorePlacer(train_config=TrainConfig(feature_noise=noise)).fit(train_s, seed=seed)
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
    args = ap.parse_args()
    torch.set_num_threads(1)
    dining = DiningScenario()
    d_train, d_test = dining.split(args.seed)
    rows = OrderingScenario(rule="unseen_class")
    r_train, r_test = rows.split(args.seed)
    print("| feature noise | dining (cm) | Unseen-Class (cm) | seconds |\n|---:|---:|---:|---:|")
    for noise in (float(v) for v in args.noise.split(",")):
        t0 = time.perf_counter()
        d = error_cm(dining, d_train, d_test, noise, args.seed)
        u = error_cm(rows, r_train, r_test[: args.rows], noise, args.seed)
        print(f"| {noise:g} | {d:.2f} | {u:.2f} | {time.perf_counter() - t0:.0f} |", flush=True)


if __name__ == "__main__":
    main()
