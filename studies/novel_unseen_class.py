"""Where SceneScore puts a missing piece in Unseen-Class rows (Table 2), and whether composing with
the hinge collision cost helps: a diagnostic for ``experiment novel``.

    python studies/novel_unseen_class.py [--rows 8] [--seed 0]

Prints, per test case, the true and predicted slot (0 = next to the board) and the error, then the
mean error of the energy alone (``placement.place``) and of energy + hinge collision + bounds through
``ss.solve(..., "langevin")``.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

import scenescore as ss
from scenescore.evaluation.cases import make_cases
from scenescore.planning.placement import SceneScorePlacer
from scenescore.scenarios import OrderingScenario


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", type=int, default=8, help="test rows (6 cases each)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    torch.set_num_threads(1)
    sc = OrderingScenario(rule="unseen_class")
    train_s, test_s = sc.split(args.seed)
    cases = make_cases(test_s[: args.rows], sc.missing)
    placer = SceneScorePlacer(progress=False).fit(train_s, seed=args.seed)
    pred = placer.predict([c.scene for c in cases], seed=args.seed)
    t0 = time.perf_counter()
    err_e, err_c = [], []
    print("| case | true slot | predicted slot (energy) | error (cm) |\n|---|---:|---:|---:|")
    for c, p in zip(cases, pred):
        board_x = c.scene["board"].pose[0]
        x, y, _ = p[c.name].pose
        err_e.append(100 * math.hypot(x - c.truth[0], y - c.truth[1]))

        def slot(px: float, board_x: float = board_x) -> float:
            return (px - board_x - sc.first_gap) / sc.spacing

        print(f"| {c.name} | {slot(c.truth[0]):.1f} | {slot(x):.2f} | {err_e[-1]:.1f} |")
        cost = (
            ss.costs.LearnedEnergy(placer.model)
            + 10.0 * ss.costs.HingeCollision(margin=0.0)
            + 10.0 * ss.costs.Bounds()
        )
        r = ss.solve(
            ss.Problem(c.scene, cost),
            "langevin",
            seed=args.seed,
            options={"langevin": {"particles": 64, "steps": 60}},
        )
        x, y, _ = r.scene[c.name].pose
        err_c.append(100 * math.hypot(x - c.truth[0], y - c.truth[1]))
    print(f"\nenergy only (placement.place): mean {np.mean(err_e):.2f} cm")
    print(
        f"energy + hinge collision + bounds (ss.solve langevin): mean {np.mean(err_c):.2f} cm "
        f"({time.perf_counter() - t0:.0f} s)"
    )


if __name__ == "__main__":
    main()
