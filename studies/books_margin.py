"""How well a trained energy orders a row: zoo-books' catastrophic failure measured without placement.

    python studies/books_margin.py [--seed 0] [--configs '[{}, {"reanchored": 0, "reanchor_restart": 0.0}]']

For every config (a JSON object of ``TrainConfig`` fields; ``{}``: the CLI's defaults) a model is trained
on zoo-books' 48 training scenes of ``--seed``. Then, on those scenes and on the 16 test scenes, every book
is moved to the row's far end (beside the last book, the same gap, its own depth's distance from the
wall: where the zoo's catastrophic placements land) and the energy per object there is compared with the
truth's. A row prints how often the far end is preferred (its energy lower) and the median margin
(energy at the far end minus at the truth, per object: larger is better).
"""

from __future__ import annotations

import argparse
import json
import math
import time

import numpy as np
import torch

from scenescore.learn import TrainConfig, fit
from scenescore.models.trust import energy_per_object
from scenescore.scenarios import get
from scenescore.scene.scene import Scene


def far_end(scene: Scene, gap: float) -> list[Scene]:
    """``scene`` with each book in turn moved beside the last book at the row's free end."""
    end = scene["bookend_0"].pose
    assert end is not None
    books = [o for o in scene.objects if o.category == "book"]
    out = []
    for b in books:
        others = [o for o in books if o is not b]
        direction = math.copysign(1.0, float(np.mean([o.pose[0] for o in others])) - end[0])
        last = max(others, key=lambda o: direction * o.pose[0])
        x = last.pose[0] + direction * (last.size[1] / 2 + gap + b.size[1] / 2)
        out.append(scene.with_poses([(x, b.pose[1], b.pose[2])], [b.name]))
    return out


def margins(model, scenes: list[Scene], gap: float) -> np.ndarray:
    """Energy per object at the far end minus at the truth, every book of every scene."""
    out: list[float] = []
    for s in scenes:
        e = energy_per_object(model, [s, *far_end(s, gap)])
        out += [v - e[0] for v in e[1:]]
    return np.array(out)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--configs", default='[{}, {"reanchored": 0, "reanchor_restart": 0.0}]')
    args = ap.parse_args()
    torch.set_num_threads(1)
    sc = get("zoo-books")
    train_s, test_s = sc.split(args.seed)
    print(
        "| config | far end preferred: train | median margin: train | far end preferred: test "
        "| median margin: test | train seconds |\n|---|---:|---:|---:|---:|---:|"
    )
    for overrides in json.loads(args.configs):
        t0 = time.perf_counter()
        model = fit(train_s, TrainConfig(**overrides), seed=args.seed, progress=False)
        seconds = time.perf_counter() - t0
        a, b = margins(model, train_s, sc.gap), margins(model, test_s, sc.gap)
        print(
            f"| `{json.dumps(overrides, sort_keys=True)}` | {int((a < 0).sum())} of {a.size} | "
            f"{np.median(a):.4f} | {int((b < 0).sum())} of {b.size} | {np.median(b):.4f} | {seconds:.0f} |",
            flush=True,
        )


if __name__ == "__main__":
    main()
