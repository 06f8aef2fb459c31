"""The trust check's share flags judged again at other margins, from a zoo run's records and models.

    python studies/trust_margins.py --records DIR/config-0.json --cache DIR [--train-scenes 12] \\
        [--config '{"members": 3}'] [--margins 0.5,1,2,4] [--member-margin 0.5] [--run-margins 1,0.5]

The ``energy`` flag fires when a placed object's share of the energy lies beyond its category's largest
in the reference scenes plus ``margin`` times their interquartile range (the check's margin is
``SHARE_MARGIN``); an ensemble's ``members`` flag when some member's share lies beyond that member's own
such limit (at ``--member-margin``, by default the check's ``MEMBER_MARGIN``). A
zoo run's records (``studies/zoo_configs.py --out``, or ``scenescore experiment zoo --out``'s
``cases.json``) keep each placement's pose and its flags' texts, not the shares; this script reads the
run's models back from its model cache (it trains none: the same code, settings and cache as the run),
computes each placed object's shares, and prints for each margin, and for the ``members`` flag needing
1, 2 or all members, how many catastrophic and how many good placements the whole check flags (the
other flags as the run recorded them). At the margins the run was made with (``--run-margins SHARE,
MEMBER``, by default the check's own) and the members its flag needed (``--run-needed``, by default
the check's: most of them; runs before that rule needed 1) it reproduces the run's flags: the script
says so, or names the placements where it does not. Last it lists the catastrophic placements the
check leaves unflagged at its own margins, each with how much more the truth costs than the placement,
by the mean energy and by each member: where every member prefers the placement, nothing the model
knows tells it from a good one.
"""

from __future__ import annotations

import argparse
import json
import sys
from dataclasses import replace
from pathlib import Path

import torch
from zoo_configs import read_cases  # a sibling study: studies/ is the script's own folder

from scenescore.experiments.zoo import zoo_cases
from scenescore.experiments.zoo_verdicts import catastrophic, good
from scenescore.learn import Run, TrainConfig, fit, split_validation
from scenescore.learn.cache import cached_path
from scenescore.models.ensemble import member_seed
from scenescore.models.shares import shares_by_energy
from scenescore.models.trust import MEMBER_MARGIN, RELATION, SHARE_MARGIN, limit_beyond, members_needed
from scenescore.scenarios import get

SHARE_FLAGS = ("energy:", "members:")


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--records", type=Path, required=True, help="a zoo run's case records")
    ap.add_argument("--cache", type=Path, required=True, help="the run's model cache")
    ap.add_argument("--config", default="{}", help="the run's TrainConfig overrides (JSON)")
    ap.add_argument("--train-scenes", type=int, default=None, help="the run's --train-scenes")
    ap.add_argument("--margins", default="0.5,1,2,4", help="interquartile ranges beyond the largest")
    ap.add_argument("--member-margin", type=float, default=MEMBER_MARGIN, help="the members flag's margin")
    ap.add_argument(
        "--run-margins",
        default=f"{SHARE_MARGIN:g},{MEMBER_MARGIN:g}",
        help="the share and member margins of the code that made the run (default the check's own)",
    )
    ap.add_argument(
        "--run-needed",
        type=int,
        default=None,
        help="how many members the members flag needed in the code that made the run (default the "
        "check's own: most of them)",
    )
    args = ap.parse_args()
    try:
        per_case = read_cases(args.records)
    except ValueError as e:
        sys.exit(f"--records {e}")
    cfg = TrainConfig(**json.loads(args.config))
    if args.run_needed is None:
        args.run_needed = members_needed(cfg.members)
    margins = [float(m) for m in args.margins.split(",")]
    shares = {name: _shares(name, cases, cfg, args) for name, cases in per_case.items()}
    print("| energy margin (IQR) | members needed | catastrophic flagged | good flagged |")
    print("|---:|---:|---:|---:|")
    for m in margins:
        for need in range(1, cfg.members + 1) if cfg.members > 1 else [0]:
            bad = flagged_bad = n_good = flagged_good = 0
            for name, cases in per_case.items():
                for c, s, b, g in zip(cases, shares[name], catastrophic(cases), good(cases)):
                    fl = flagged(c, s, m, need, args.member_margin)
                    bad, flagged_bad = bad + int(b), flagged_bad + int(b and fl)
                    n_good, flagged_good = n_good + int(g), flagged_good + int(g and fl)
            share = 100 * flagged_good / max(n_good, 1)
            print(
                f"| {m:g} | {need or '-'} | {flagged_bad} of {bad} | {flagged_good} of {n_good} ({share:.1f}%) |"
            )
    share_m, member_m = (float(v) for v in args.run_margins.split(","))
    odd = [
        f"{name} #{k}"
        for name, cases in per_case.items()
        for k, (c, s) in enumerate(zip(cases, shares[name]))
        if flagged(c, s, share_m, args.run_needed if cfg.members > 1 else 0, member_m) != c["flagged"]
    ]
    verdict = "yes" if not odd else "no, at " + ", ".join(odd)
    print(f"\nmargins {share_m:g} and {member_m:g} reproduce the run's flags: {verdict}")
    misses(per_case, shares, cfg)


def misses(per_case: dict[str, list[dict]], shares: dict[str, list[dict]], cfg: TrainConfig) -> None:
    """The catastrophic placements the check leaves unflagged at its own margins, each with how much more
    the truth costs than the placement (the object's share at its truth minus at the placement: the
    scene's energy difference, the rest of the scene the same), by the mean energy and by each member."""
    need = members_needed(cfg.members) if cfg.members > 1 else 0
    rows = [
        (name, c, s)
        for name, cases in per_case.items()
        for c, s, b in zip(cases, shares[name], catastrophic(cases))
        if b and not flagged(c, s, SHARE_MARGIN, need)
    ]
    print(f"\ncatastrophic placements the check leaves unflagged: {len(rows)}")
    if not rows:
        return
    members = "" if cfg.members == 1 else " | by each member"
    print(f"| scenario | seed | object | t (cm) | truth minus placement, mean energy{members} |")
    print("|---|---:|---|---:|---:|" + ("---|" if members else ""))
    for name, c, s in rows:
        d = s["truth_minus_answer"]
        each = "" if cfg.members == 1 else " | " + ", ".join(f"{v:.2f}" for v in d[1:])
        print(f"| {name} | {c['seed']} | {c['object']} | {c['t_cm']:.1f} | {d[0]:.2f}{each} |")


def _shares(name: str, cases: list[dict], cfg: TrainConfig, args: argparse.Namespace) -> list[dict]:
    """Each record's placed object's shares and the reference shares they are judged against: by the
    mean energy, then by each member."""
    sc = get(name)
    single = replace(cfg, members=1)  # each member is cached as the single model of its seed
    out: list[dict] = []
    for seed in sorted({c["seed"] for c in cases}):
        train_s, test_s = sc.split(seed)
        if args.train_scenes is not None:
            train_s = train_s[: args.train_scenes]
        train_s, held = split_validation(train_s, 0.0, seed=seed)
        for m in range(cfg.members):  # the models are read back, never trained here
            path = cached_path(
                args.cache, train_s, single, None, member_seed(seed, m), held, torch.device("cpu")
            )
            if path is None or not path.exists():
                sys.exit(
                    f"{name} seed {seed}: member {m} is not in {args.cache}; run this with the run's code"
                )
        model = fit(train_s, cfg, seed=seed, progress=False, run=Run(cache=args.cache))
        ref = model.info.trust
        mine = [(c, b) for c, b in zip(cases, catastrophic(cases)) if c["seed"] == seed]
        for case, (rec, bad) in zip(zoo_cases(sc, test_s, seed), mine, strict=True):
            placed = case.scene.with_poses([rec["pose"]], [case.name])
            rows = shares_by_energy(model, placed, [case.name], members=True)[:, 0]
            cat = case.category
            refs = [ref.category_shares(cat)] + [ref.category_shares(cat, k) for k in range(len(rows) - 1)]
            got = {"shares": rows.tolist(), "refs": refs}
            if bad:  # how much more the truth costs than the placement, by the mean energy and each member
                truth = case.scene.with_poses([rec["truth"]], [case.name])
                at_truth = shares_by_energy(model, truth, [case.name], members=True)[:, 0]
                got["truth_minus_answer"] = (at_truth - rows).tolist()
            out.append(got)
    return out


def flagged(case: dict, s: dict, margin: float, need: int, member_margin: float = MEMBER_MARGIN) -> bool:
    """Whether the check flags ``case`` with the energy flag at ``margin`` (``members`` when ``need``
    members or more put the share beyond their limit at ``member_margin``; 0: no members flag), its
    other flags as recorded."""
    others = any(not f.startswith((*SHARE_FLAGS, RELATION)) for f in case["flags"])
    share, ref = s["shares"][0], s["refs"][0]
    beyond = [v > limit_beyond(r, member_margin) for v, r in zip(s["shares"][1:], s["refs"][1:])]
    return others or share > limit_beyond(ref, margin) or (need > 0 and sum(beyond) >= need)


if __name__ == "__main__":
    main()
