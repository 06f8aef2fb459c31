"""Far-field minima: does the learned energy have low regions far from every example?

    python studies/far_field.py [--scenario zoo-hall] [--seed 0] [--grow 3]

Three models on the same data and seed: the old defaults (edge offsets linear in a fixed 0.1 m length
scale, no edge encoder: ``RAW_EDGES``), the current ones (the data's length scale, linear offsets), and
the data's scale with offsets saturating beyond the data's largest (``TrainConfig(saturate_edges=True)``).
Each places the missing object of 16 test scenes twice: in the scenes' own bounds, and in bounds
``--grow`` times larger (the same objects; the room around them larger than any in training). For
each, the table gives the mean and worst error, how many placements land more than 25 cm and 10
oracle means off, how many end pinned at a bound, and the energy at the placement against the energy
at the truth (a far placement with a lower energy than the truth is a spurious far-field minimum).
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np
import torch

import scenescore as ss
from scenescore.experiments.zoo import zoo_cases
from scenescore.learn import RAW_EDGES, TrainConfig, fit
from scenescore.models.layout import BOUND_TOL, touching_bound
from scenescore.planning.placement import place_many, placement_problem

CONFIGS = {
    "linear offsets, 0.1 m (old)": TrainConfig(
        length_scale=0.1, saturate_edges=False, walls=False, **RAW_EDGES
    ),
    "data's scale, linear (current default)": TrainConfig(),
    "data's scale, saturating": TrainConfig(saturate_edges=True),
}


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="zoo-hall")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--grow", type=float, default=3.0)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    sc = ss.scenarios.get(args.scenario)
    tr, te = sc.split(args.seed)
    cases = zoo_cases(sc, te, args.seed)
    oracle = np.mean([math.dist(sc.oracle(c.scene, c.name)[:2], c.truth[:2]) for c in cases]) * 100
    print(f"{args.scenario}, seed {args.seed}: 16 placements each; oracle mean {oracle:.2f} cm\n")
    print(
        "| model | bounds | mean t (cm) | worst t | catastrophic | at a bound | lower energy than the truth, > 25 cm off |"
    )
    print("|---|---|---:|---:|---:|---:|---:|")
    for label, cfg in CONFIGS.items():
        t0 = time.perf_counter()
        model = fit(tr, cfg, seed=args.seed, progress=False)
        for grow in (1.0, args.grow):
            scenes = []
            for c in cases:
                s = c.scene.copy()
                (x0, y0), (x1, y1) = s.bounds
                s.bounds = ((grow * x0, grow * y0), (grow * x1, grow * y1))
                scenes.append(s)
            out = place_many(model, scenes[:8], None, args.seed) + place_many(
                model, scenes[8:], None, args.seed + 8
            )
            t, pinned, spurious = [], 0, 0
            for c, s, p in zip(cases, scenes, out):
                pose = p[c.name].pose
                assert pose is not None
                t.append(100 * math.dist(pose[:2], c.truth[:2]))
                pinned += (
                    touching_bound(p[c.name], pose, s.bounds, BOUND_TOL * model.config.length_scale)
                    is not None
                )
                cost = placement_problem(model, s).cost
                e = cost(torch.tensor(np.stack([p.poses(), s.with_poses([c.truth], [c.name]).poses()])))
                spurious += bool(t[-1] > 25 and e[0] < e[1])
            ta = np.array(t)
            cat = int(((ta > 25) & (ta > 10 * oracle)).sum())
            print(
                f"| {label} | x{grow:g} | {ta.mean():.2f} | {ta.max():.1f} | {cat} | {pinned} | {spurious} |"
            )
        print(f"<!-- {label}: {time.perf_counter() - t0:.0f} s -->")


if __name__ == "__main__":
    main()
