"""How much of a far-off placement the walls pull: the energy at it and at the truth, with and without them.

    python studies/wall_pull.py [--scenario zoo-bedroom] [--seed 1] [--over 15] \\
        [--configs '[{"wall_lines": false}, {}]']

For every config (a JSON object of ``TrainConfig`` fields; ``{}``: the CLI's defaults) a model is trained
on the scenario's 48 training scenes of ``--seed`` and places every test case back as ``place`` does
(the zoo experiment's protocol). For each placement more than ``--over`` cm off, a row gives the
energy of the whole scene at the placement minus at the truth (negative: the energy prefers the wrong
pose), once as the model sees it and once with the bounds' four walls masked out of the graph. A
difference that shrinks to nothing without the walls was put there by the walls. Scenarios whose data
does not stand against its bounds have no walls; their two columns are equal.
"""

from __future__ import annotations

import argparse
import json

import torch

from scenescore.evaluation.cases import case_errors
from scenescore.experiments.zoo import place_back, zoo_cases
from scenescore.learn import TrainConfig, fit
from scenescore.models import ScoreModel
from scenescore.models.network import WALLS
from scenescore.scenarios import get
from scenescore.scene.scene import Scene


def energy(model: ScoreModel, scene: Scene, walls: bool) -> float:
    """The energy of a fully posed ``scene``; ``walls=False`` masks the model's walls out of the graph."""
    st = model.tensors([scene])
    mask = st.mask.clone()
    if model.config.walls and not walls:
        mask[0, -WALLS:] = False  # one scene: its walls are its last nodes
    with torch.no_grad():
        return float(model.net(st.poses, st.feats, st.sizes, mask, round=st.round)[0])


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenario", default="zoo-bedroom")
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--over", type=float, default=15.0, help="placements more than this many cm off")
    ap.add_argument(
        "--configs", default='[{"wall_lines": false}, {}]', help="JSON list of TrainConfig overrides"
    )
    args = ap.parse_args()
    torch.set_num_threads(1)
    sc = get(args.scenario)
    train_s, test_s = sc.split(args.seed)
    cases = zoo_cases(sc, test_s, args.seed)
    print(
        f"{args.scenario} seed {args.seed}: {len(cases)} test cases, rows for placements over {args.over} cm"
    )
    print(
        "| config | object | t (cm) | E placed - E truth | the same without walls |\n|---|---|---:|---:|---:|"
    )
    for overrides in json.loads(args.configs):
        model = fit(train_s, TrainConfig(**overrides), seed=args.seed, progress=False)
        placed = place_back(model, cases, args.seed)
        far = 0
        for c, p in zip(cases, placed):
            pose = p[c.name].pose
            assert pose is not None
            t, _ = case_errors(c, pose, c.category in sc.symmetric)
            if t <= args.over:
                continue
            far += 1
            truth = p.with_poses([c.truth], [c.name])
            d = [energy(model, p, w) - energy(model, truth, w) for w in (True, False)]
            print(f"| `{json.dumps(overrides)}` | {c.name} | {t:.1f} | {d[0]:+.3f} | {d[1]:+.3f} |")
        if not far:
            print(f"| `{json.dumps(overrides)}` | none over {args.over} cm | | | |")


if __name__ == "__main__":
    main()
