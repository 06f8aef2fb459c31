"""The zoo with a handful of scenes, trained as ``scenescore train`` trains a user's data.

    python studies/train_as_user.py [--scenarios zoo-pcb,zoo-books] [--seeds 1] [--train-scenes 5] \\
        [--cache DIR] [--out records.json]

For every table-top scenario and seed: the first K training scenes of the zoo's split trained through
the training workflow (``ss.train``, the function the command calls, at its defaults: with under
:data:`~scenescore.workflow.crossval.CROSS_VALIDATE_BELOW` scenes the model is trained on all of them
and cross-validated, the folds' figures kept as the model's caveats, the categories the examples leave
free said), then the zoo's 16 test cases placed as ``scenescore place`` places them with that model.
What the user is told is set beside what happened: the held-out loss against chance, the
cross-validation's error for the missing category against the test's, whether train called the
category free or unlearned, and, of the catastrophic placements (more than 25 cm and 10 oracle means
off), how many carry a flag, how many of those only a validation caveat, and how many of the good ones
(within 3 oracle means) are flagged, in all and by the trust check's own tests. A held-out loss's
caveat is left out of the counts: it flags every placement of a model or none. ``--from A.json B.json`` prints the table of earlier ``--out`` files, running nothing.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path
from typing import Any

import numpy as np

import scenescore as ss
from scenescore.experiments.zoo import zoo_cases
from scenescore.experiments.zoo_verdicts import case_records, catastrophic, good
from scenescore.learn import Run
from scenescore.models.layout import BOUND_TOL
from scenescore.planning.placement import PLACE, covering, placement_problem
from scenescore.scenarios import get
from scenescore.scenarios.zoo import ROOMS, ZOO
from scenescore.scene.outputs import atomic_write_text
from scenescore.solvers import solve
from scenescore.solvers.langevin import LangevinSolver


def one_pair(name: str, seed: int, k: int, cache: Path | None) -> dict[str, Any]:
    """What train said and how the test cases came out, for one scenario and seed."""
    sc = get(name)
    train_s, test_s = sc.split(seed)
    model = ss.train(train_s[:k], seed=seed, progress=False, run=Run(cache=cache))
    cases = zoo_cases(sc, test_s, seed)
    missing = cases[0].category
    opts = covering(PLACE, model, [c.scene for c in cases])
    tol = BOUND_TOL * model.config.length_scale
    caveats = model.info.caveats.reasons(missing) if model.info.caveats is not None else []
    records = []
    for i, c in enumerate(cases):
        r = solve(placement_problem(model, c.scene), LangevinSolver(opts), seed=seed + i)
        names = c.scene.unknown
        placed = c.scene.with_poses(r.poses[[c.scene.index(n) for n in names]], names)
        placed.meta = {**placed.meta, "placement": {n: r.confidence[n].to_dict() for n in names}}
        for rec in case_records(sc, c, placed, float("nan"), float("nan"), tol, seed)[0]:
            own = [f for f in rec["flags"] if f not in caveats]
            notes = placed.meta["placement"][rec.get("placed", rec["object"])].get("notes", [])
            records.append({**rec, "own_flagged": bool(own), "free_note": bool(notes)})
    val = model.info.validation or {}
    cv = next((cat for cat in val.get("categories", []) if cat["category"] == missing), None)
    spread = model.trust.spread(missing) if model.trust is not None else None
    return {
        "seed": seed,
        "category": missing,
        "cv_t_cm": None if cv is None else cv["t_cm"],
        "cv_baseline_t_cm": None if cv is None else cv["baseline_t_cm"],
        "heldout_loss": val.get("heldout_loss"),
        "chance_loss": val.get("chance_loss"),
        "free": None if spread is None else bool(spread.free),
        "records": records,
    }


LOSS_CAVEAT = "validation: the model's held-out InfoNCE loss"


def verdicts(cases: list[dict[str, Any]]) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Catastrophic and good placements, and which carry a flag other than the held-out loss's caveat
    (placements carry that one on every object, or on none) and which one of the trust check's own
    (not a validation caveat)."""
    flags = np.array([any(not f.startswith(LOSS_CAVEAT) for f in c["flags"]) for c in cases], dtype=bool)
    own = np.array([any(not f.startswith("validation:") for f in c["flags"]) for c in cases], dtype=bool)
    return catastrophic(cases), good(cases), flags, own


def loss(run: dict[str, Any]) -> str:
    """The held-out loss against chance; from the flags for records written without it."""
    if run.get("heldout_loss") is not None:
        return f"{run['heldout_loss']:.2f} ({run['chance_loss']:.2f})"
    above = any(f.startswith(LOSS_CAVEAT) for c in run["records"] for f in c["flags"])
    return "above chance" if above else "below chance"


def unlearned(run: dict[str, Any]) -> bool:
    """Whether the validation found the category placed no better than nearest neighbour: its caveat
    among the placements' flags (the held-out loss's is the model's, not the category's)."""
    return any(
        f.startswith("validation:") and not f.startswith(LOSS_CAVEAT)
        for c in run["records"]
        for f in c["flags"]
    )


def row(name: str, runs: list[dict[str, Any]]) -> str:
    cases = [c for r in runs for c in r["records"]]
    t = np.array([c["t_cm"] for c in cases])
    o = np.array([c["oracle_t_cm"] for c in cases])
    cat, ok, flags, own = verdicts(cases)
    cv = [r["cv_t_cm"] for r in runs if r["cv_t_cm"] is not None]
    said = ", ".join(
        sorted({w for r in runs for w, on in (("free", r["free"]), ("unlearned", unlearned(r))) if on})
    )
    return (
        f"| {name} | {runs[0]['category']} | {'; '.join(loss(r) for r in runs)} | "
        f"{np.mean(cv) if cv else float('nan'):.2f} | {t.mean():.2f} | {t.max():.1f} | "
        f"{t.mean() / max(o.mean(), 1e-9):.2f} | {said or '-'} | {int(cat.sum())} "
        f"({int((cat & flags).sum())}, {int((cat & flags & ~own).sum())}) | "
        f"{int((ok & flags).sum())} ({int((ok & own).sum())}) of {int(ok.sum())} |"
    )


def report(per: dict[str, list[dict[str, Any]]]) -> None:
    """The table, worst first by the test's t / oracle, and the pooled line."""

    def ratio(name: str) -> float:
        cases = [c for r in per[name] for c in r["records"]]
        return np.mean([c["t_cm"] for c in cases]) / max(np.mean([c["oracle_t_cm"] for c in cases]), 1e-9)

    print(
        "| scenario | missing | held-out loss (chance) | cross-validated t (cm) | test mean t (cm) | worst "
        "| t / oracle | train said | catastrophic (flagged, by a validation caveat alone) "
        "| good flagged (by the trust check) |"
    )
    print("|---|---|---|---:|---:|---:|---:|---|---:|---:|")
    for name in sorted(per, key=lambda n: -ratio(n)):
        print(row(name, per[name]))
    # each scenario's verdicts (against its own oracle's mean), added up
    cat, ok, flags, own = (
        np.concatenate(v)
        for v in zip(*(verdicts([c for r in runs for c in r["records"]]) for runs in per.values()))
    )
    print(
        f"\nmedian scenario t / oracle {np.median([ratio(n) for n in per]):.2f}, catastrophic "
        f"{int(cat.sum())} of {len(cat)} ({int((cat & flags).sum())} flagged, "
        f"{int((cat & flags & ~own).sum())} by a validation caveat alone), good flagged "
        f"{int((ok & flags).sum())} of {int(ok.sum())} ({(ok & flags).sum() / max(ok.sum(), 1):.1%}; by "
        f"the trust check {int((ok & own).sum())}, {(ok & own).sum() / max(ok.sum(), 1):.1%})"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenarios", default=",".join(s for s in ZOO if s not in ROOMS))
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--train-scenes", type=int, default=5)
    ap.add_argument("--cache", type=Path, default=None, help="a model cache folder")
    ap.add_argument("--out", type=Path, default=None, help="write every record here (JSON)")
    ap.add_argument(
        "--from", dest="records", type=Path, nargs="+", default=None, help="print these --out files' table"
    )
    args = ap.parse_args()
    if args.records:
        per: dict[str, list[dict[str, Any]]] = {}
        for path in args.records:
            for name, runs in json.loads(path.read_text(encoding="utf-8")).items():
                per.setdefault(name, []).extend(runs)
        report(per)
        return
    per = {}
    for name in args.scenarios.split(","):
        for seed in range(args.seeds):
            t0 = time.perf_counter()
            got = one_pair(name, seed, args.train_scenes, args.cache)
            per.setdefault(name, []).append(got)
            t = np.mean([c["t_cm"] for c in got["records"]])
            print(
                f"{name} seed {seed}: mean t {t:.2f} cm ({time.perf_counter() - t0:.0f} s)", file=sys.stderr
            )
            if args.out is not None:
                atomic_write_text(args.out, json.dumps(per) + "\n")
    report(per)


if __name__ == "__main__":
    main()
