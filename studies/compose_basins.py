"""Where Fig. 4's incorrect samples come from: the Langevin schedule, the refinement, the energy.

    python studies/compose_basins.py [--seeds 0,1,2] [--levels 2,3,4,5] [--per-scene 200]
        [--configs '[{}, {"steps": 120}]'] [--train '{"iterations": 2000}'] [--model-dir DIR] [--threads 1]

The compose experiment's setting (``scenescore experiment compose``: its energy, cost, test scenes and
clutter) at a smaller budget: for each seed, clutter level and Langevin configuration (changes to
``langevin_options``, given as JSON), ``--per-scene`` samples in each of the five cluttered test
scenes, counted correct by the scenario's check four ways: the Langevin samples as drawn, repaired
by ``alm`` (``polish: false``: each sample stops once feasible), refined as the experiment's
langevin>alm row does (``REFINE``) and polished by ``alm`` (each sample minimises the energy until
stationary). The median asymmetry of the Langevin samples (the difference of the speakers' distances
from the television along its axis; the check allows 5 cm) shows where the energy puts its minimum.
Each cell is ``correct / distinct`` (positions rounded to 1 cm) over the
five scenes; the last columns give the repaired correct count per scene, which shows whether the
misses are spread over every scene or are whole populations in one wrong basin, and the cost of the
repaired samples (energy + penalties), correct against incorrect (medians), which shows how far apart
the energy puts them. The energies train in ``--threads`` threads (default 1, as in the experiment's
worker processes; float rounding carries the thread count into the trained weights).

``--train`` changes the experiment's training settings (``TrainConfig`` fields, as JSON), e.g.
``{"iterations": 2000}``, ``{"perturbed": 8}`` or, for the network without its edge encoder that Fig. 4
was first measured with, ``{"edge_encoder": null, "feature_noise": 0.3, "size_noise": 0.0, "reanchored":
0, "reanchor_restart": 0.0}`` (``RAW_EDGES``).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import time
from pathlib import Path
from typing import Any

import numpy as np
import torch

from scenescore.experiments.compose import REFINE, correct_samples, langevin_options, train_config, tv_problem
from scenescore.learn import TrainConfig, fit
from scenescore.models import ScoreModel, load
from scenescore.scenarios.tv import TVScenario
from scenescore.scene.scene import Scene
from scenescore.solvers import get, solve


def energy(seed: int, changes: dict[str, Any], model_dir: Path | None) -> ScoreModel:
    """The compose experiment's energy for ``seed``, its training settings changed by ``changes``, cached
    in ``model_dir``."""
    tag = hashlib.sha1(json.dumps(changes, sort_keys=True).encode()).hexdigest()[:8]
    path = model_dir / f"tv-seed{seed}-{tag}.ckpt" if model_dir else None
    if path is not None and path.exists():
        return load(path)
    train_scenes, _ = TVScenario().split(seed)
    tc = TrainConfig(**{**train_config().to_dict(), **changes})
    model = fit(train_scenes, tc, seed=seed, progress=False)
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        model.save(path)
    return model


def asymmetry(scene: Scene, poses: np.ndarray) -> np.ndarray:
    """``(S,)`` the difference of the two speakers' distances from the television along its axis (m)."""
    tv, s0, s1 = (poses[:, scene.index(n)] for n in ("television", "speaker_0", "speaker_1"))
    axis = np.stack([np.cos(tv[:, 2]), np.sin(tv[:, 2])], axis=1)
    along = [np.abs(((s[:, :2] - tv[:, :2]) * axis).sum(axis=1)) for s in (s0, s1)]
    return np.abs(along[0] - along[1])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", default="0,1,2", help="training seeds (default 0,1,2)")
    ap.add_argument("--levels", default="2,3,4,5", help="clutter levels (default 2,3,4,5)")
    ap.add_argument("--per-scene", type=int, default=200, help="samples per test scene (default 200)")
    ap.add_argument(
        "--configs",
        default='[{}, {"steps": 120}]',
        help="JSON list of changes to the experiment's Langevin options (default: as is, and 120 steps)",
    )
    ap.add_argument(
        "--train", default="{}", help="JSON changes to the experiment's TrainConfig (default none)"
    )
    ap.add_argument("--model-dir", type=Path, default=None, help="cache the trained energies here")
    ap.add_argument(
        "--threads", type=int, default=1, help="torch threads (default 1, as the experiment's workers)"
    )
    args = ap.parse_args()
    torch.set_num_threads(args.threads)
    configs = json.loads(args.configs)
    changes = json.loads(args.train)
    scenario = TVScenario()
    n_scenes = 5
    print(
        f"compose basins: {args.per_scene} samples in each of {n_scenes} scenes per level; training as the "
        f"experiment's{', changed by ' + json.dumps(changes) if changes else ''}; cells: correct / distinct "
        f"of {n_scenes * args.per_scene}\n"
    )
    print(
        "| seed | clutter | langevin options | langevin | repaired | refined | polished | repaired, per scene "
        "| cost correct / incorrect | asymmetry (cm) | langevin s |"
    )
    print("|---:|---:|---|---:|---:|---:|---:|---|---|---:|---:|")
    repair, refine, polish = get("alm", polish=False), get("alm", **REFINE), get("alm", polish=True)
    for seed in [int(s) for s in args.seeds.split(",")]:
        model = energy(seed, changes, args.model_dir)
        _, test_scenes = scenario.split(seed)
        for cfg in configs:
            for n in [int(v) for v in args.levels.split(",")]:
                cells = {"lan": [0, 0], "rep": [0, 0], "ref": [0, 0], "pol": [0, 0]}
                per_scene, good, bad, asym = [], [], [], []
                t_lan = 0.0
                for k in range(n_scenes):
                    scene = scenario.clutter(
                        test_scenes[k % len(test_scenes)], n, seed=1000 * seed + 10 * n + k
                    )
                    problem = tv_problem(scene, model)
                    t = time.perf_counter()
                    opts = {**langevin_options(args.per_scene), **cfg}
                    lan = solve(problem, "langevin", seed=k, options={"langevin": opts})
                    t_lan += time.perf_counter() - t
                    assert lan.samples is not None
                    start = torch.as_tensor(lan.samples)
                    rep = repair.solve(problem, init=start).samples
                    ref = refine.solve(problem, init=start).samples
                    pol = polish.solve(problem, init=start).samples
                    assert rep is not None and ref is not None and pol is not None
                    asym.extend(asymmetry(scene, np.asarray(lan.samples)))
                    for key, poses in (("lan", lan.samples), ("rep", rep), ("ref", ref), ("pol", pol)):
                        c, d = correct_samples(scenario, scene, np.asarray(poses))
                        cells[key][0] += c
                        cells[key][1] += d
                    ok = scenario.correct_many(scene, np.asarray(rep))
                    per_scene.append(int(ok.sum()))
                    with torch.no_grad():
                        cost = problem.evaluate(torch.as_tensor(np.asarray(rep))).numpy()
                    good.extend(cost[ok])
                    bad.extend(cost[~ok])
                costs = f"{np.median(good):.3f} / " if good else "- / "
                costs += f"{np.median(bad):.3f}" if bad else "-"
                print(
                    f"| {seed} | {n} | {json.dumps(cfg) if cfg else 'as in the experiment'} | "
                    + " | ".join(f"{c} / {d}" for c, d in cells.values())
                    + f" | {' '.join(map(str, per_scene))} | {costs} | {100 * np.median(asym):.1f} | {t_lan:.1f} |",
                    flush=True,
                )


if __name__ == "__main__":
    main()
