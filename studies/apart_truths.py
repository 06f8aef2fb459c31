"""How often the trust check's ``apart`` test doubts a true arrangement: no model, geometry only.

    python studies/apart_truths.py [--scenarios dining,zoo-cafe] [--seeds 3]

For each scenario and seed, the limits (:func:`scenescore.models.layout.apart_limits`) come from the
training split (all 48 scenes, and the first 12), and every object of the scenario's ``missing``
categories in the 16 test scenes is judged at its true pose, as placement's ``outside_data`` judges a
particle: doubted when it stands farther from every object of some category than 1.5 times the
farthest any object of its category stands in the training scenes. A doubted truth would be a good
placement flagged, and a particle near the truth ranked after worse ones.
"""

from __future__ import annotations

import argparse

import scenescore as ss
from scenescore.models.layout import apart_limits
from scenescore.models.trust import FAR_FACTOR, TrustReference, apart_distances
from scenescore.scenarios.zoo import ROOMS, SCENARIOS

PAPER = ("dining", "desk", "tv")


def doubted(scene: ss.Scene, i: int, limits: dict[str, dict[str, float]]) -> bool:
    """Whether the trust check's ``apart`` test doubts object ``i`` of ``scene`` (every pose known) against
    ``limits`` in metres (:func:`~scenescore.models.trust.apart_distances`, as placement applies it)."""
    ref = TrustReference(
        energies=[0.0], length_scale=1.0, nearest={}, nearest_any=0.0, touches_bounds=[], apart=limits
    )
    return any(d[0] > FAR_FACTOR * lim for _, d, lim in apart_distances(ref, scene, i, scene.poses()[None]))


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
