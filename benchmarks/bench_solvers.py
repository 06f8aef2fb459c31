"""Solver timings: time per OSQP (SQP) iteration and per IPOPT solve for N = 3, 8, 12 objects;
the CasADi energy as an MX rebuild against a torch Callback; the projection QP in raw OSQP against cvxpy.

    python benchmarks/bench_solvers.py [--model examples/dining.ckpt] [--seeds 3]

Problems: dining scenes cut to N objects, every object movable (half of them with a known pose), a
fixed box of clutter, energy + 10 * collision (margin 1 cm) + bounds; each refinement starts from the
best of 16 short Langevin particles (the same start for every solver).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np
import torch

import scenescore as ss
from scenescore.solvers.casadi import CasadiSolver
from scenescore.solvers.langevin import LangevinSolver
from scenescore.solvers.projection import LinearisedProjection, project_cvxpy
from scenescore.solvers.sqp import OSQPSolver


def make_problem(model, n: int, seed: int) -> ss.Problem:
    sc = ss.scenarios.get("dining")
    scenes = sc.generate(3, seed)
    objs = [o for s in scenes for o in s.objects]
    objs = [
        ss.SceneObject(f"{o.name}_{k}", o.category, o.size, o.pose, o.color, shape=o.shape)
        for k, o in enumerate(objs[: n - 1])
    ]
    objs.append(ss.SceneObject("clutter", "box", (0.15, 0.1), (0.05, 0.05, 0.3), fixed=True))
    scene = ss.Scene(objs, bounds=sc.bounds)
    cost = ss.costs.LearnedEnergy(model) + 10.0 * ss.costs.HingeCollision(margin=0.01) + ss.costs.Bounds()
    return ss.Problem(scene, cost, movable=[o.name for o in objs[:-1]])


def main(argv=None) -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--model", default=str(Path(__file__).parents[1] / "examples" / "dining.ckpt"))
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    torch.set_num_threads(1)
    if Path(args.model).exists():
        model = ss.models.load(args.model)
        print(f"model: {args.model} ({model.net.cfg.activation}, hidden {model.net.cfg.hidden})")
    else:
        torch.manual_seed(0)
        model = ss.models.ScoreModel.create(ss.FootprintEncoder(), hidden=32, layers=2)
        print("model: untrained (hidden 32, silu); run examples/train_model.py for the trained one")
    lang = LangevinSolver(particles=16, steps=30, final_descent=10)
    print(
        "| N | solver | solves | converged | feasible | iterations (median) | ms / iteration | QP ms / iteration "
        "| solve s (median) | setup s |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for n in (3, 8, 12):
        stats: dict[str, list] = {"osqp": [], "casadi mx": [], "casadi callback": []}
        for seed in range(args.seeds):
            p = make_problem(model, n, seed)
            start = lang.solve(p, seed=seed).poses
            r = OSQPSolver(max_iter=100).solve(p, init=start)
            stats["osqp"].append(r)
            for key, energy in (("casadi mx", "mx"), ("casadi callback", "callback")):
                stats[key].append(CasadiSolver(energy=energy).solve(p, init=start))
        for key, rs in stats.items():
            its = np.array([r.iterations for r in rs])
            ts = np.array([r.time_solve for r in rs])
            ms_it = 1000 * np.median(ts / np.maximum(its, 1))
            qp = f"{1000 * np.median([r.qp_time_mean for r in rs]):.2f}" if key == "osqp" else "-"
            print(
                f"| {n} | {key} | {len(rs)} | {sum(r.status == 'converged' for r in rs)} | "
                f"{sum(r.feasible for r in rs)} | {int(np.median(its))} | {ms_it:.1f} | {qp} | "
                f"{np.median(ts):.3f} | {np.median([r.time_setup for r in rs]):.3f} |"
            )

    # the projection QP: raw OSQP (set up once, values updated) against the same QP in cvxpy
    p = make_problem(model, 12, 0)
    x = p.initial(8, torch.Generator().manual_seed(0))
    proj = LinearisedProjection(p)
    proj(x[:1])  # set up
    t = time.perf_counter()
    proj(x)
    raw = (time.perf_counter() - t) / max(proj.qp_solves - 1, 1)
    t = time.perf_counter()
    for b in range(len(x)):
        project_cvxpy(p, x[b])
    cvx = (time.perf_counter() - t) / len(x)
    print(
        f"\nprojection QP, N = 12 ({len(p.cost['collision'].labels())} pairs): raw OSQP {1000 * raw:.2f} ms per particle "
        f"(incl. Jacobians), cvxpy {1000 * cvx:.1f} ms per particle"
    )


if __name__ == "__main__":
    main()
