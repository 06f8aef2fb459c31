"""The zoo's records of placements and its verdicts on them: catastrophic, good, and how the trust check did.

A placement is catastrophic when it is more than :data:`CATASTROPHIC_CM` and more than
:data:`CATASTROPHIC_ORACLE` oracle means off, good within :data:`GOOD_ORACLE` oracle means (the oracle's
mean error over the scenario's placements). The trust check should flag every catastrophic placement and
few good ones: :func:`trust_line` counts both, pooled over the scenarios. Each case record is a dict with ``t_cm``, ``oracle_t_cm``, ``flagged`` and
``flags``, made by :func:`case_records` (:func:`scenescore.experiments.zoo.run`).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any, cast

import numpy as np

from ..evaluation.cases import MissingCase, assignment, case_errors
from ..models.layout import touching_bound
from ..scenarios.zoo.common import Pose
from ..scene.scene import Scene, SceneError

__all__ = [
    "CATASTROPHIC_CM",
    "CATASTROPHIC_ORACLE",
    "GOOD_ORACLE",
    "catastrophic",
    "good",
    "trust_line",
    "case_records",
]

Cases = Sequence[dict[str, Any]]

CATASTROPHIC_CM = 25.0  # a placement is catastrophic when it is this far off ...
CATASTROPHIC_ORACLE = 10.0  # ... and this many oracle means
GOOD_ORACLE = 3.0  # a placement is good within this many oracle means


def catastrophic(cases: Cases) -> np.ndarray:
    """Which of one scenario's case records are catastrophic: more than :data:`CATASTROPHIC_CM` and
    :data:`CATASTROPHIC_ORACLE` oracle means (the scenario's mean oracle error) off."""
    t = np.array([c["t_cm"] for c in cases])
    om = float(np.array([c["oracle_t_cm"] for c in cases]).mean())
    return (t > CATASTROPHIC_CM) & (t > CATASTROPHIC_ORACLE * om)


def good(cases: Cases) -> np.ndarray:
    """Which of one scenario's case records are good: within :data:`GOOD_ORACLE` oracle means (the
    scenario's mean oracle error)."""
    t = np.array([c["t_cm"] for c in cases])
    om = float(np.array([c["oracle_t_cm"] for c in cases]).mean())
    return t <= GOOD_ORACLE * max(om, 1e-9)


def trust_line(per_case: Mapping[str, Cases]) -> str:
    """The trust check pooled over every scenario's case records: the catastrophic placements flagged,
    those the ``rival`` flag is among the flags of, and the good ones flagged."""
    bad = flagged = rival = n_good = good_flagged = 0
    for cases in per_case.values():
        for c, b, g in zip(cases, catastrophic(cases), good(cases)):
            bad += int(b)
            flagged += int(b and c["flagged"])
            rival += int(b and any(f.startswith("rival:") for f in c["flags"]))
            n_good += int(g)
            good_flagged += int(g and c["flagged"])
    share = good_flagged / n_good if n_good else 0.0
    return (
        f"flagged: {flagged} of {bad} catastrophic ({rival} by rival), "
        f"{good_flagged} of {n_good} good ({100 * share:.1f}%)"
    )


def case_records(
    sc: Any, c: MissingCase, p: Scene, e_placed: float, e_truth: float, tol: float, seed: int
) -> tuple[list[dict[str, Any]], tuple[MissingCase, Scene, float]]:
    """One record per object the case removed, and its worst ``(case, placed scene, t)``. The placed
    poses and the oracle's are each matched to the truths by :func:`assignment` (the identity for one
    object); a record's ``placed`` names the object whose placement was matched to its truth, when
    the case removed several. ``e_placed``, ``e_truth``: the energy per object at the placement and
    at the truth (every removed object at its true pose)."""
    parts = c.singles()
    cats = [q.category for q in parts]
    unplaced = [q.name for q in parts if p[q.name].pose is None]
    if unplaced:
        raise SceneError(f"zoo: placement left {unplaced} without a pose")
    poses = [cast(Pose, p[q.name].pose) for q in parts]
    match = assignment(poses, [q.truth for q in parts], cats)
    oracle = sc.oracle_many(c.scene, c.names)
    by_oracle = assignment(oracle, [q.truth for q in parts], cats)
    records: list[dict[str, Any]] = []
    worst: tuple[MissingCase, Scene, float] | None = None
    for i, q in enumerate(parts):
        src, pose = parts[match[i]].name, poses[match[i]]
        sym = q.category in sc.symmetric
        t, r = case_errors(q, pose, sym)
        ot, orr = case_errors(q, oracle[by_oracle[i]], sym)
        if worst is None or t > worst[2]:  # drawn as the placed object against the truth it matched
            worst = (q if src == q.name else MissingCase(c.scene, src, q.category, q.truth), p, t)
        flags = list(p.meta.get("placement", {}).get(src, {}).get("flags", []))
        rec = {
            "seed": seed,
            "object": q.name,
            "t_cm": t,
            "R_deg": r,
            "oracle_t_cm": ot,
            "oracle_R_deg": orr,
            "at_bound": touching_bound(c.scene[src], pose, c.scene.bounds, tol) is not None,
            "flagged": bool(flags),
            "flags": flags,
            "energy": e_placed,
            "energy_truth": e_truth,
            "pose": list(pose),
            "truth": list(q.truth),
        }
        if c.others:
            rec["placed"] = src
        records.append(rec)
    assert worst is not None
    return records, worst
