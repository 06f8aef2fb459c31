"""How often the out-of-distribution flag fires: on good placements (it should not) and on placements
built to be out of distribution (it should, every time).

    python studies/ood_flags.py [--scenario dining] [--seed 0]

A model is trained at the CLI's defaults (15% of 48 scenes held out as the trust reference). Then:

- in distribution: 16 test scenes, one object removed from each and placed back;
- larger bounds: the same scenes in bounds 10x larger, the removed object pulled to a random point
  near a far edge by a strong target cost (a spurious minimum, forced), solved by ``langevin``;
- novel object: the same scenes with an extra object of a category far from the training data
  (0.4 to 0.9 m long, a saturated colour), placed.
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

import scenescore as ss
from scenescore.experiments.zoo import place_back, zoo_cases
from scenescore.learn import TrainConfig, fit, split_validation
from scenescore.planning.placement import place_many


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="dining")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    t0 = time.perf_counter()
    sc = ss.scenarios.get(args.scenario)
    data, test = sc.split(args.seed)
    tr, held = split_validation(data, seed=args.seed)
    model = fit(tr, TrainConfig(), seed=args.seed, progress=False, validation=held)
    if not hasattr(sc, "missing"):
        raise SystemExit(f"{args.scenario} has no missing categories")
    cases = zoo_cases(sc, test, args.seed)
    rng = np.random.default_rng(args.seed)
    rows = []

    # in distribution
    placed = place_back(model, cases, args.seed)
    t = np.array(
        [100 * math.hypot(*(np.array(p[c.name].pose[:2]) - c.truth[:2])) for c, p in zip(cases, placed)]
    )
    o = np.array([100 * math.hypot(*(np.array(sc.oracle(c.scene, c.name)[:2]) - c.truth[:2])) for c in cases])
    flags = np.array([bool(p.meta["placement"][c.name]["flags"]) for c, p in zip(cases, placed)])
    good = t <= 3 * o.mean()
    rows.append(("in distribution, all", len(cases), int(flags.sum())))
    rows.append(
        (
            f"in distribution, good (within 3 oracle means, {o.mean():.2f} cm)",
            int(good.sum()),
            int(flags[good].sum()),
        )
    )

    # larger bounds with a spurious minimum forced
    n_big = 0
    for c in cases:
        s = c.scene.copy()
        (x0, y0), (x1, y1) = s.bounds
        s.bounds = ((10 * x0, 10 * y0), (10 * x1, 10 * y1))
        side = rng.uniform(-1, 1) * 9 * x1
        target = (side, 9.5 * y1) if rng.random() < 0.5 else (9.5 * x1, side)
        cost = ss.costs.LearnedEnergy(model) + 100.0 * ss.costs.PoseTarget(c.name, target)
        r = ss.solve(ss.Problem(s, cost), "langevin", seed=args.seed, options={"langevin": {"particles": 16}})
        n_big += bool(r.confidence[c.name].flags)
    rows.append(("bounds 10x larger, pulled far away", len(cases), n_big))

    # a novel object
    scenes = []
    for c in cases:
        size = (float(rng.uniform(0.4, 0.9)), float(rng.uniform(0.2, 0.4)))
        colour = tuple(int(v) for v in rng.permutation([255, 0, int(rng.integers(0, 256))]))
        odd = ss.SceneObject("novel_0", "anvil", size, None, color=colour)  # type: ignore[arg-type]
        truth = c.scene.with_poses([c.truth], [c.name])
        scenes.append(ss.Scene([*truth.objects, odd], truth.bounds))
    out = place_many(model, scenes[:8], None, args.seed) + place_many(model, scenes[8:], None, args.seed + 8)
    rows.append(("a novel object", len(out), sum(bool(p.meta["placement"]["novel_0"]["flags"]) for p in out)))

    print(
        f"{args.scenario}, seed {args.seed}: trained on {len(tr)} scenes, {len(held)} held out as the reference\n"
    )
    print("| placements | n | flagged | rate |")
    print("|---|---:|---:|---:|")
    for name, n, k in rows:
        print(f"| {name} | {n} | {k} | {k / max(n, 1):.0%} |")
    print(f"\n{time.perf_counter() - t0:.0f} s")


if __name__ == "__main__":
    main()
