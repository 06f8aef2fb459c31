"""``scenescore demo``: the main job end to end, offline, in a few minutes on a 2-core CPU.

Generates dining-table arrangements, trains the energy on them, removes a bowl, a fork or a knife
from unseen test scenes, places it back with Langevin on the learned energy, prints the errors next
to the oracle's and writes a picture.
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path
from typing import cast

from . import ITERATIONS, SCENES, add_common, add_device, device_of


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser(
        "demo",
        help="generate data, train, place missing objects, print errors, write a PNG",
        description="The main job end to end, offline, in a few minutes on a 2-core CPU: generate dining-table "
        "arrangements, train the energy on them, remove a bowl, a fork or a knife from unseen test scenes, place "
        "it back with Langevin on the learned energy, print the errors beside the oracle's and draw a picture.",
    )
    p.add_argument("--out", type=Path, default=Path("runs/demo"), help="output folder (default runs/demo)")
    p.add_argument(
        "--iterations", type=ITERATIONS, default=None, help="training iterations (default: the demo's)"
    )
    p.add_argument(
        "--test-scenes", type=SCENES, default=8, help="test scenes to place objects in (default 8)"
    )
    add_common(p)
    add_device(p)
    p.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    import numpy as np

    from ..evaluation.cases import OraclePlacer, make_cases, score_cases
    from ..learn import ONE_NETWORK, TrainConfig
    from ..planning.placement import SceneScorePlacer
    from ..scenarios import DiningScenario
    from ..scene.scene import write_jsonl
    from ..viz.plot import demo_figure

    device = str(device_of(args))  # checked before any work
    t0 = time.perf_counter()
    cfg = (
        TrainConfig(**ONE_NETWORK)
        if args.iterations is None
        else TrainConfig(iterations=args.iterations, **ONE_NETWORK)
    )
    out: Path = args.out
    scenario = DiningScenario()
    train, test = scenario.split(args.seed)
    test = test[: args.test_scenes]
    write_jsonl(out / "train.jsonl", train)
    write_jsonl(out / "test.jsonl", test)
    print(f"1. generated {len(train)} training and {len(test)} test dining scenes -> {out}/train.jsonl")

    placer = SceneScorePlacer(train_config=cfg, progress=not args.quiet, device=device)
    placer.fit(train, seed=args.seed)
    assert placer.model is not None
    placer.model.save(out / "model.ckpt")
    info = placer.model.info
    print(
        f"2. trained the energy in {info.seconds:.0f} s: InfoNCE loss {info.final_loss:.3f} "
        f"(chance {info.chance_loss:.3f}) -> {out}/model.ckpt"
    )

    cases = make_cases(test, scenario.missing)
    pred = placer.predict([c.scene for c in cases], seed=args.seed)
    ours = score_cases(cases, pred, scenario.symmetric)
    oracle = score_cases(cases, OraclePlacer(scenario).predict([c.scene for c in cases]), scenario.symmetric)
    print(f"3. placed {len(cases)} missing objects (one of bowl, fork, knife removed each time):\n")
    print(f"   {'object':8s} {'SceneScore t':>13s} {'R':>8s}   {'oracle t':>9s} {'R':>8s}")
    for cat in scenario.missing:
        r_ours = ours.get(f"{cat}_R_deg", float("nan"))
        r_or = oracle.get(f"{cat}_R_deg", float("nan"))
        print(
            f"   {cat:8s} {ours[f'{cat}_t_cm']:10.2f} cm {r_ours:6.1f} deg"
            f" {oracle[f'{cat}_t_cm']:6.2f} cm {r_or:6.1f} deg".replace("nan deg", "  -    ")
        )
    print(
        f"   {'mean':8s} {ours['mean_t_cm']:10.2f} cm {ours['mean_R_deg']:6.1f} deg"
        f" {oracle['mean_t_cm']:6.2f} cm {oracle['mean_R_deg']:6.1f} deg"
    )
    shown = [(c, p) for c, p in zip(cases, pred)][:: max(1, len(cases) // 6)][:6]
    demo_figure(shown, out / "demo.png")
    errs = np.array(
        [
            100 * np.hypot(*(np.array(cast(tuple[float, float, float], p[c.name].pose)[:2]) - c.truth[:2]))
            for c, p in shown
        ]
    )
    print(
        f"\n4. wrote {out}/demo.png: {len(shown)} test scenes, placed object outlined in red, truth dashed "
        f"(errors {', '.join(f'{e:.1f}' for e in errs)} cm)"
    )
    print(f"done in {time.perf_counter() - t0:.0f} s")
    return 0
