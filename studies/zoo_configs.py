"""Training settings compared on the zoo: the robustness table for each, worst scenario first.

    python studies/zoo_configs.py --scenarios zoo-bedroom,zoo-banquet --seeds 3 \\
        --configs '[{}, {"edge_encoder": null}]' [--place '{"proposals": 0.0}'] [--jobs 2] [--out DIR] \\
        [--train-scenes 12] [--cache DIR]

Each config is a JSON object of ``TrainConfig`` fields over the zoo experiment's one network (``{}``:
``TrainConfig(**ONE_NETWORK)``; ``{"members": 3}``: the default ensemble). For every config the
zoo experiment's protocol runs as ``scenescore experiment zoo`` does (48 training and 16 test scenes,
one object placed back per test scene, placement as ``place`` does), and one table row per scenario
gives the mean, median and worst position error, the catastrophic count (more than 25 cm and 10 oracle
means off), the ratio to the oracle, the misses split into the search's and the energy's, and the trust
check's flags: the share of all placements flagged, of the good ones (within 3 oracle means), and how
many of the catastrophic ones were flagged. A last line per config counts the scenarios within 3x the
oracle and the catastrophic placements in all, and one more pools the trust check over the scenarios:
the catastrophic placements flagged (and how many by the ``rival`` flag) and the good ones flagged. ``--cache DIR`` keeps the trained models there for
every config and later runs: an ensemble's first member is the single model of its seed, so
``--configs '[{"members": 3}, {}]'`` trains the single models once; a snapshot ensemble's member 0 is
the single model too, and ``--singles-from '{"members": 3, "ensemble": "snapshots"}'`` takes the single
models from those in the cache instead of training them again. ``--train-scenes 12``: the zoo's
small-data variant.
``--place`` changes placement's options for every config (a JSON object of ``LangevinOptions`` fields
over ``scenescore.planning.placement.PLACE``; the candidates still cover the bounds). ``--out DIR`` keeps every
case's record as ``DIR/config-K.json``; ``--records DIR/config-K.json`` prints that pooled trust line
from such a file again, without running anything, and how many catastrophic and good placements each
kind of flag fired on, and for an ensemble the counts with the ``members`` flag needing 2 or more members
to doubt, or only where they split (some but not all doubt); ``--records OUT/cases.json`` does the same
for a ``scenescore experiment zoo --out OUT`` run.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import sys
import time
from collections import Counter
from collections.abc import Callable, Mapping
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import torch

from scenescore.experiments.execution import Execution
from scenescore.experiments.zoo import run, training_split
from scenescore.experiments.zoo_verdicts import Cases, catastrophic, good, trust_line
from scenescore.learn import ONE_NETWORK, VALIDATION_FRACTION, TrainConfig
from scenescore.learn.cache import cached_path
from scenescore.models import ScoreModel, load
from scenescore.models.ensemble import members_of
from scenescore.models.trust import RELATION, reference
from scenescore.planning.placement import PLACE
from scenescore.scenarios.zoo import ROOMS, ZOO
from scenescore.scene.outputs import atomic_write_text


def _execution(args: argparse.Namespace) -> Execution:
    """How each configuration's run runs: no bars, each pair's line on stderr as it ends (the table is
    stdout's), ``--jobs`` workers, ``--cache`` the model cache."""
    return Execution(
        progress=False,
        log=lambda line: print(line, file=sys.stderr, flush=True),
        jobs=args.jobs,
        cache=args.cache,
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument(
        "--scenarios",
        default=",".join(s for s in ZOO if s not in ROOMS),
        help="comma-separated zoo scenarios (default all but the rooms, which run only when named)",
    )
    ap.add_argument("--seeds", type=int, default=3, help="seeds 0 .. N-1 (default 3)")
    ap.add_argument("--configs", default="[{}]", help="JSON list of TrainConfig overrides (default [{}])")
    ap.add_argument("--jobs", type=int, default=2, help="worker processes (default 2)")
    ap.add_argument("--energy-only", action="store_true", help="place by the learned energy alone")
    ap.add_argument("--place", default=None, help="JSON object of LangevinOptions fields over PLACE")
    ap.add_argument(
        "--val",
        type=float,
        default=0.0,
        help=f"fraction of the training scenes held out for validation (default 0; train's is {VALIDATION_FRACTION:g})",
    )
    ap.add_argument("--out", type=Path, default=None, help="keep each config's per-case records here")
    ap.add_argument("--cache", type=Path, default=None, help="a model cache folder shared by the configs")
    ap.add_argument("--train-scenes", type=int, default=None, help="train on the first N training scenes")
    ap.add_argument(
        "--singles-from",
        default=None,
        help="a JSON object of TrainConfig overrides with ensemble snapshots: before each config of one "
        "network runs, the --cache gets its models from those snapshot ensembles' member 0 (the same "
        "network: the run is the same up to the first snapshot), each with its own trust reference",
    )
    ap.add_argument(
        "--records",
        type=Path,
        default=None,
        help="print the pooled trust line of an --out file (or of experiment zoo's cases.json)",
    )
    args = ap.parse_args()
    if args.records is not None:
        try:
            per_case = read_cases(args.records)
        except ValueError as e:
            sys.exit(f"--records {e}")
        print(trust_line(per_case))
        print(flag_kinds(per_case))
        if line := members_rules(per_case):
            print(line)
        return
    configs = json.loads(args.configs)
    scenarios = [s for s in args.scenarios.split(",") if s]
    place = None if args.place is None else replace(PLACE, **json.loads(args.place))
    print(f"scenarios {scenarios}, seeds 0..{args.seeds - 1}, jobs {args.jobs}")
    print(
        "| config | scenario | mean t (cm) | median | worst | catastrophic | oracle t | t / oracle "
        "| misses: search | misses: energy | flagged | flagged (good) | catastrophic flagged | seconds |\n"
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
    )
    summary = []
    snap = (
        None if args.singles_from is None else TrainConfig(**{**ONE_NETWORK, **json.loads(args.singles_from)})
    )
    for k, overrides in enumerate(configs):
        t0 = time.perf_counter()
        if snap is not None and args.cache is not None:
            singles_from_snapshots(args, scenarios, snap, overrides)
        res = run(
            args.seeds,
            scenarios,
            config=TrainConfig(**{**ONE_NETWORK, **overrides}),
            energy_only=args.energy_only,
            place=place,
            val=args.val,
            train_scenes=args.train_scenes,
            execution=_execution(args),
        )
        label = json.dumps(overrides, sort_keys=True)
        if args.out is not None:
            args.out.mkdir(parents=True, exist_ok=True)
            atomic_write_text(
                args.out / f"config-{k}.json", json.dumps({"config": overrides, "cases": res.per_case})
            )
        rows = res.rows()
        for r in rows:
            f = r.figures
            print(
                f"| `{label}` | {r.method} | {f['mean_t_cm']:.2f} | {f['median_t_cm']:.2f} | {f['max_t_cm']:.1f} "
                f"| {f['catastrophic']} | {f['oracle_t_cm']:.2f} | {f['ratio']:.2f} | {f['miss_search']} "
                f"| {f['miss_energy']} | {f['flag_rate']:.2f} | {f['flag_rate_good']:.2f} "
                f"| {_bad_flagged(res.per_case[r.method])} | {f['seconds']:.0f} |",
                flush=True,
            )
        within = sum(r.figures["ratio"] <= 3 for r in rows)
        cat = sum(r.figures["catastrophic"] for r in rows)
        summary.append(
            f"`{label}`: {within} of {len(rows)} scenarios within 3x the oracle, {cat} catastrophic "
            f"({time.perf_counter() - t0:.0f} s); {trust_line(res.per_case)}"
        )
    print()
    for line in summary:
        print(line)


def singles_from_snapshots(
    args: argparse.Namespace, scenarios: list[str], snap: TrainConfig, overrides: dict[str, Any]
) -> None:
    """Put in ``--cache`` the single model of ``overrides`` for every pair whose snapshot ensemble
    ``snap`` is there and whose single model is not: member 0 of the ensemble, with the single model's
    settings and a trust reference of its own (as ``fit`` computes it)."""
    single = TrainConfig(**{**ONE_NETWORK, **overrides})
    if single.members != 1 or snap.snapshots == 0 or replace(snap, members=1, ensemble="seeds") != single:
        return
    cpu = torch.device("cpu")
    for name in scenarios:
        for seed in range(args.seeds):
            train_s, held, _ = training_split(name, seed, args.val, args.train_scenes)
            src = cached_path(args.cache, train_s, snap, None, seed, held, cpu)
            dst = cached_path(args.cache, train_s, single, None, seed, held, cpu)
            if src is None or dst is None or not src.exists() or dst.exists():
                continue
            ens = load(src)
            model = ScoreModel(members_of(ens.net)[0], ens.encoder)
            model.info = replace(ens.info, train_config=single.to_dict(), members=None, seconds=None)
            model.info.final_loss = ens.info.members[0]["final_loss"]
            model.info.trust = reference(model, train_s, held, single.feature_noise)
            model.save(dst)
            print(
                f"{name} seed {seed}: the single model from its snapshot ensemble's member 0", file=sys.stderr
            )


def read_cases(path: str | os.PathLike) -> dict[str, list[dict[str, Any]]]:
    """The case records of a zoo run, scenario -> cases: ``studies/zoo_configs.py --out``'s
    ``config-K.json`` or ``scenescore experiment zoo --out``'s ``cases.json``. ValueError naming the file
    when it cannot be read."""
    try:
        records = json.loads(Path(path).read_text(encoding="utf-8"))
    except (OSError, ValueError) as e:
        raise ValueError(f"{path}: cannot read the case records: {e}") from None
    return records["cases"] if "config" in records else records  # else experiment zoo's


def flag_kinds(per_case: Mapping[str, Cases]) -> str:
    """How many catastrophic and how many good placements each kind of flag (``energy``, ``members``,
    ``rival``, ...) is among the flags of, pooled over the scenarios."""
    on: dict[str, Counter[str]] = {"catastrophic": Counter(), "good": Counter()}
    for cases in per_case.values():
        for c, b, g in zip(cases, catastrophic(cases), good(cases)):
            kinds = {f.split(":")[0] for f in c["flags"]}
            on["catastrophic"].update(kinds if b else ())
            on["good"].update(kinds if g else ())
    return "; ".join(
        f"flags on {k} placements: " + (", ".join(f"{f} {n}" for f, n in sorted(v.items())) or "none")
        for k, v in on.items()
    )


def _members_doubting(flags: list[str]) -> tuple[int, int] | None:
    """The ``members`` flag's ``(members doubting, members)`` from a record's flag texts; None without
    one."""
    for f in flags:
        m = re.match(r"members: (\d+) of (\d+) members", f)
        if m:
            return int(m.group(1)), int(m.group(2))
    return None


def _flagged_if(flags: list[str], keep_members: Callable[[int, int], bool]) -> bool:
    """Whether a record stays flagged when its ``members`` flag counts only where ``keep_members(doubting,
    members)`` holds: the ``relation`` line names the doubted relation of another flag, no flag itself."""
    doubt = _members_doubting(flags)
    rest = [f for f in flags if not f.startswith(("members:", RELATION))]
    return bool(rest) or (doubt is not None and keep_members(*doubt))


def members_rules(per_case: Mapping[str, Cases]) -> str:
    """The trust check's counts with the ``members`` flag needing 1, 2, ... members to doubt (the check
    needs most of them, :func:`~scenescore.models.trust.members_needed`; runs before that rule needed
    1), and only where the members split (some but not all doubt), read from the records' flag
    texts: the catastrophic placements flagged and the good ones flagged, pooled. Empty where no record
    has a ``members`` flag."""
    cases = [c for v in per_case.values() for c in v]
    doubts = [d for c in cases if (d := _members_doubting(c["flags"])) is not None]
    if not doubts:
        return ""
    size = max(m for _, m in doubts)
    rules: list[tuple[str, Callable[[int, int], bool]]] = [
        (f"members needed {k}", lambda d, m, k=k: d >= k) for k in range(1, size + 1)
    ]
    rules.append(("members split", lambda d, m: 0 < d < m))
    bad = np.concatenate([catastrophic(v) for v in per_case.values()])
    ok = np.concatenate([good(v) for v in per_case.values()])
    out = []
    for label, keep in rules:
        fl = np.array([_flagged_if(c["flags"], keep) for c in cases], dtype=bool)
        out.append(
            f"{label}: catastrophic {int((bad & fl).sum())} of {int(bad.sum())} flagged, good "
            f"{int((ok & fl).sum())} of {int(ok.sum())}"
        )
    return "; ".join(out)


def _bad_flagged(cases: list[dict]) -> str:
    """How many of the catastrophic placements the trust check flagged: ``k of n``."""
    bad = [c for c, b in zip(cases, catastrophic(cases)) if b]
    return f"{sum(c['flagged'] for c in bad)} of {len(bad)}"


if __name__ == "__main__":
    main()
