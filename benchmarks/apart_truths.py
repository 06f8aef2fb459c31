"""How often the trust check's ``apart`` test doubts a true arrangement: no model, geometry only.

    python benchmarks/apart_truths.py [--scenarios dining,zoo-cafe] [--seeds 3]

For each scenario and seed, the limits (:func:`scenescore.models.layout.apart_limits`) come from the
training split (all 48 scenes, and the first 12), and every object of the scenario's ``missing``
categories in the 16 test scenes is judged at its true pose, as placement's ``outside_data`` judges a
particle: doubted when it stands farther from every object of some category than 1.5 times the
farthest any object of its category stands in the training scenes. A doubted truth would be a good
placement flagged, and a particle near the truth ranked after worse ones.
"""

from __future__ import annotations

import argparse

import numpy as np

import scenescore as ss
from scenescore.models.layout import apart_limits
from scenescore.models.trust import FAR_FACTOR
from scenescore.scenarios.zoo import ROOMS, SCENARIOS

PAPER = ("dining", "desk", "tv")


def doubted(scene: ss.Scene, i: int, limits: dict[str, dict[str, float]]) -> bool:
    """Whether object ``i`` of ``scene`` (every pose known) stands farther from every object of some
    category than :data:`FAR_FACTOR` times ``limits`` (metres)."""
    p = scene.poses()
    cats = np.array([o.category for o in scene.objects])
    d = np.linalg.norm(p[:, :2] - p[i, :2], axis=-1)
    d[i] = np.inf
    return any(
        bool((cats == c).sum() - (c == cats[i]) > 0) and float(d[cats == c].min()) > FAR_FACTOR * lim
        for c, lim in limits.get(str(cats[i]), {}).items()
    )


def main(argv: list[str] | None = None) -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default=",".join([*PAPER, *SCENARIOS]))
    ap.add_argument("--seeds", type=int, default=3)
    args = ap.parse_args(argv)
    print("| scenario | truths judged | doubted (48 scenes) | doubted (12 scenes) |")
    print("|---|---:|---:|---:|")
    for name in args.scenarios.split(","):
        sc = ss.scenarios.get(name)
        missing = set(getattr(sc, "missing", ()))
        judged, counts = 0, {48: 0, 12: 0}
        for seed in range(args.seeds):
            train, test = sc.split(seed)
            limits = {n: apart_limits(train[:n], 1.0) for n in counts}
            for s in test:
                for i, o in enumerate(s.objects):
                    if missing and o.category not in missing:
                        continue
                    judged += 1
                    for n in counts:
                        counts[n] += doubted(s, i, limits[n])
        room = " (room)" if name in ROOMS else ""
        print(f"| {name}{room} | {judged} | {counts[48]} | {counts[12]} |", flush=True)


if __name__ == "__main__":
    main()
