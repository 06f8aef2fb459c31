"""Robustness across the zoo: train at the CLI's defaults on each scenario, place a missing object back.

For every zoo scenario and seed: 48 training and 16 test scenes (all 48 trained on, and the trust
reference; ``val`` holds some out as ``scenescore train --val`` does); in each test scene one object of a
``missing`` category (chosen by the seed) loses its pose and is placed back with the learned energy.
In the rooms (:data:`~scenescore.scenarios.zoo.ROOMS`, run only when named) ``missing_count`` (three)
interchangeable chairs lose theirs at once, are placed back together, and are scored one record each
against the truths they match by assignment (the oracle's poses likewise).
Reported per scenario: its scale, object counts, SceneScore's mean and median position error ``t``
(cm) and orientation error ``R`` (deg, none for symmetric categories), the count of catastrophic
placements (more than 25 cm *and* more than 10 oracle means off), placements pinned at a bound, the
oracle's errors, and how often the out-of-distribution flag fires (on all placements and on good
ones, within 3 oracle means). Worst case first: the table is sorted by mean ``t`` over the oracle's.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from functools import partial
from typing import Any, cast

import numpy as np
from tqdm.auto import tqdm

from ..evaluation.cases import MissingCase
from ..learn import ONE_NETWORK, Run, TrainConfig, fit, split_validation
from ..learn.config import shared_compile
from ..models import ScoreModel
from ..models.layout import BOUND_TOL
from ..models.trust import energy_per_object
from ..planning.placement import covering, place_many
from ..runtime.devices import resolve_device
from ..scenarios import get
from ..scenarios.zoo import ROOMS, ZOO
from ..scenarios.zoo.common import Pose
from ..scene.scene import Scene, SceneError
from ..solvers.langevin import LangevinOptions
from .execution import Execution
from .report import Row, format_table
from .tasks import Codec, Task, run_tasks
from .zoo_verdicts import (
    CATASTROPHIC_CM,
    CATASTROPHIC_ORACLE,
    GOOD_ORACLE,
    case_records,
    catastrophic,
    good,
    trust_line,
)

__all__ = [
    "training_split",
    "zoo_cases",
    "place_back",
    "run",
    "run_one",
    "ZooResult",
    "format_zoo",
    "CATASTROPHIC_CM",
    "CATASTROPHIC_ORACLE",
    "catastrophic",
    "good",
    "GOOD_ORACLE",
]


def zoo_cases(scenario: Any, test: list[Scene], seed: int) -> list[MissingCase]:
    """One case per test scene: ``scenario.missing_count`` objects of a ``missing`` category, chosen by
    ``seed``, poses removed (one: the case's ``name``; more: the first as ``name``, the rest as its
    ``others``, in the scene's order)."""
    rng = np.random.default_rng(10_000 + seed)
    k = scenario.missing_count
    cases = []
    for s in test:
        names = [o.name for o in s.objects if o.category in scenario.missing and o.pose is not None]
        if not names:
            raise SceneError(f"{scenario.name}: a test scene has no object of {scenario.missing}")
        if len(names) < k:
            raise SceneError(
                f"{scenario.name}: a test scene has {len(names)} objects of {scenario.missing}, "
                f"fewer than the {k} to remove"
            )
        if k == 1:  # the one-object draw
            chosen = [names[int(rng.integers(len(names)))]]
        else:
            chosen = [names[int(i)] for i in sorted(rng.choice(len(names), size=k, replace=False))]
        masked = s
        for n in chosen:
            masked = masked.without(n)
        poses = [s[n].pose for n in chosen]
        assert all(p is not None for p in poses)
        others = tuple((n, s[n].category, cast(Pose, p)) for n, p in zip(chosen[1:], poses[1:]))
        cases.append(MissingCase(masked, chosen[0], s[chosen[0]].category, cast(Pose, poses[0]), others))
    return cases


@dataclass
class ZooResult:
    """Per scenario and seed: every case's errors and flags."""

    per_case: dict[str, list[dict[str, Any]]] = field(default_factory=dict)  # scenario -> cases (all seeds)
    info: dict[str, dict[str, Any]] = field(default_factory=dict)  # scenario -> scale and counts
    seconds: dict[str, float] = field(default_factory=dict)
    worst: dict[str, tuple[MissingCase, Scene, float]] = field(
        default_factory=dict
    )  # scenario -> worst placement

    def worst_examples(self) -> list[tuple[MissingCase, Scene]]:
        """Each scenario's worst placement ``(case, placed scene)``, worst first."""
        return [(c, p) for c, p, _ in sorted(self.worst.values(), key=lambda w: -w[2])]

    def rows(self) -> list[Row]:
        out = []
        for name, cases in self.per_case.items():
            t = np.array([c["t_cm"] for c in cases])
            o = np.array([c["oracle_t_cm"] for c in cases])
            r = np.array([c["R_deg"] for c in cases if c["R_deg"] is not None])
            ro = np.array([c["oracle_R_deg"] for c in cases if c["oracle_R_deg"] is not None])
            om = float(o.mean())
            cat = int(np.sum(catastrophic(cases)))
            ok = good(cases)
            flags = np.array([c["flagged"] for c in cases])
            # a miss (beyond 3 oracle means) is the search's when the truth has the lower energy
            search = np.array([c["energy_truth"] < c["energy"] for c in cases])
            figs = {
                **self.info[name],
                "mean_t_cm": float(t.mean()),
                "median_t_cm": float(np.median(t)),
                "max_t_cm": float(t.max()),
                "mean_R_deg": float(r.mean()) if r.size else math.nan,
                "median_R_deg": float(np.median(r)) if r.size else math.nan,
                "catastrophic": cat,
                "at_bound": int(sum(c["at_bound"] for c in cases)),
                "cases": len(cases),
                "oracle_t_cm": om,
                "oracle_R_deg": float(ro.mean()) if ro.size else math.nan,
                "ratio": float(t.mean() / max(om, 1e-9)),
                "miss_search": int(np.sum(~ok & search)),
                "miss_energy": int(np.sum(~ok & ~search)),
                "flag_rate": float(flags.mean()),
                "flag_rate_good": float(flags[ok].mean()) if ok.any() else 0.0,
                "seconds": self.seconds.get(name, 0.0),
            }
            out.append(Row(name, figs))
        return sorted(out, key=lambda r: -r.figures["ratio"])


def place_back(
    model: ScoreModel,
    cases: Sequence[MissingCase],
    seed: int,
    options: LangevinOptions | None = None,
    energy_only: bool = False,
    done: Callable[[int], Any] | None = None,
) -> list[Scene]:
    """Each case's scene with its object placed back by :func:`place_many`, 8 scenes a batch, batch
    ``k`` (its first case's index) seeded ``seed + k``: the zoo's placements. ``done(count)`` after
    each batch."""
    placed: list[Scene] = []
    for k in range(0, len(cases), 8):
        batch = cases[k : k + 8]
        placed += place_many(model, [c.scene for c in batch], options, seed + k, energy_only)
        if done is not None:
            done(len(batch))
    return placed


def training_split(
    name: str, seed: int, val: float = 0.0, train_scenes: int | None = None
) -> tuple[list[Scene], list[Scene], list[Scene]]:
    """Scenario ``name``'s scenes for ``seed`` as :func:`run_one` uses them: ``(trained on, held out for
    validation, test)``, the training scenes cut to the first ``train_scenes`` before ``val`` of them
    is held out."""
    train_s, test_s = get(name).split(seed)
    if train_scenes is not None:
        if not 2 <= train_scenes <= len(train_s):
            raise SceneError(f"zoo: train_scenes must be 2 to {len(train_s)}, got {train_scenes}")
        train_s = train_s[:train_scenes]
    train_s, held = split_validation(train_s, val, seed=seed)
    return train_s, held, test_s


def run_one(
    name: str,
    seed: int,
    config: TrainConfig | None = None,
    progress: bool = False,
    energy_only: bool = False,
    device: Any = None,
    place: LangevinOptions | None = None,
    val: float = 0.0,
    cache: Any = None,
    train_scenes: int | None = None,
) -> dict[str, Any]:
    """One scenario and seed: train, place every test case back as ``place`` does (``energy_only``: by
    the learned energy alone, the paper's protocol; ``place``: placement options instead of
    :data:`~scenescore.planning.placement.PLACE`, their candidates covering the bounds as PLACE's do), on
    ``device``; ``val``: the fraction of the training scenes held out for validation, as ``scenescore
    train --val`` (default none: the training scenes are the trust reference, and every one of them is
    trained on, which a table top's worst placements need); ``cache``: a model cache folder (:mod:`scenescore.learn.cache`); ``train_scenes``: train on
    the first that many of the split's training scenes (the small-data variant; the test scenes are the
    same); ``{"cases", "worst", "seconds"}``."""
    t0 = time.perf_counter()
    sc = get(name)
    train_s, held, test_s = training_split(name, seed, val, train_scenes)
    model = fit(
        train_s,
        config or TrainConfig(**ONE_NETWORK),
        seed=seed,
        progress=progress,
        device=device,
        validation=held,
        run=Run(cache=cache),
    )
    cases = zoo_cases(sc, test_s, seed)
    tol = BOUND_TOL * model.config.length_scale  # "at a bound": as the trust check judges it
    opts = None if place is None else covering(place, model, [c.scene for c in cases])
    with tqdm(total=len(cases), desc=f"{name}: place", unit="case", disable=not progress) as bar:
        placed = place_back(model, cases, seed, opts, energy_only, bar.update)
    # the energy at each placement and at its truth: a placement with the higher of the two is a
    # failure of the search; with the lower, the learned energy prefers the wrong pose
    truths = [p.with_poses([q.truth for q in c.singles()], c.names) for c, p in zip(cases, placed)]
    energies = energy_per_object(model, placed + truths)
    records: list[dict[str, Any]] = []
    worst: tuple[MissingCase, Scene, float] | None = None
    for k, (c, p) in enumerate(zip(cases, placed)):
        got, w = case_records(sc, c, p, energies[k], energies[len(cases) + k], tol, seed)
        records += got
        if worst is None or w[2] > worst[2]:
            worst = w
    return {"cases": records, "worst": worst, "seconds": time.perf_counter() - t0}


def _pair(
    task: Task,
    log: Callable[[str], None],
    configs: dict[tuple[str, int], TrainConfig],
    progress: bool,
    energy_only: bool,
    device: Any,
    place: LangevinOptions | None,
    val: float,
    cache: Any,
    train_scenes: int | None = None,
) -> dict[str, Any]:
    """:func:`run_one` on one (scenario, seed) pair with its training settings of ``configs``, its line
    logged when it is done."""
    name, seed = task.scenario, task.seed
    one = run_one(
        name, seed, configs[(name, seed)], progress, energy_only, device, place, val, cache, train_scenes
    )
    got = one["cases"]
    log(
        f"{name} seed {seed}: mean t {np.mean([c['t_cm'] for c in got]):.2f} cm, "
        f"oracle {np.mean([c['oracle_t_cm'] for c in got]):.2f} cm, "
        f"max {max(c['t_cm'] for c in got):.1f} cm ({one['seconds']:.0f} s)"
    )
    return one


def run(
    seeds: int = 3,
    scenarios: list[str] | None = None,
    config: TrainConfig | None = None,
    energy_only: bool = False,
    place: LangevinOptions | None = None,
    val: float = 0.0,
    train_scenes: int | None = None,
    *,
    execution: Execution | None = None,
) -> ZooResult:
    """The zoo table over ``seeds`` seeds for ``scenarios`` (default every zoo scenario but the rooms,
    whose training takes far longer; ``config``: the training settings; default the CLI's; ``place``:
    placement options; ``val``: the validation fraction held out of the training scenes;
    ``train_scenes``: train on that many of the 48 training scenes (12: the small-data variant);
    :func:`run_one`). ``execution``: where and how (default :class:`Execution`'s): the models train and
    place on its ``device``, with its model ``cache``; its ``sweep`` keeps each pair's record, to
    resume from (:mod:`scenescore.experiments.tasks`).

    ``execution.jobs > 1`` runs the (scenario, seed) pairs in that many worker processes of one thread
    each, largest scenarios first; each pair's figures do not depend on ``jobs``.
    """
    ex = execution or Execution()
    chosen = scenarios or [s for s in ZOO if s not in ROOMS]
    unknown = [s for s in chosen if s not in ZOO]
    if unknown:
        raise SceneError(f"unknown zoo scenario(s) {unknown}; choose from {list(ZOO)}")
    settings = {
        "training": config,
        "energy_only": energy_only,
        "device": str(ex.device),
        "place": place,
        "val": val,
        "train_scenes": train_scenes,
        "trainings": seeds,  # compiled together where that pays
    }  # every setting a pair's record depends on beyond its scenario and seed
    tasks = [
        Task.of("zoo", scenario=name, seed=seed, config=settings) for name in chosen for seed in range(seeds)
    ]
    # each scenario's seeds' networks compile together where that pays, settled before any pair starts
    kind, base = resolve_device(ex.device).type, config or TrainConfig(**ONE_NETWORK)
    configs = {
        (t.scenario, t.seed): shared_compile(
            base, training_split(t.scenario, t.seed, val, train_scenes)[0], seeds, kind
        )
        for t in tasks
    }
    pair = partial(
        _pair,
        configs=configs,
        progress=ex.progress and ex.jobs == 1,
        energy_only=energy_only,
        device=ex.device,
        place=place,
        val=val,
        cache=ex.cache,
        train_scenes=train_scenes,
    )
    bar = "zoo" if ex.progress else None
    # the largest graphs first in worker processes, so the long pairs do not start last
    records = run_tasks(
        pair, tasks, ex.jobs, ex.log, bar, ex.sweep, PAIR_RECORD, length=lambda t: get(t.scenario).counts[1]
    )
    done = {(t.scenario, t.seed): r for t, r in zip(tasks, records)}
    res = ZooResult()
    for name in chosen:
        res.per_case[name] = []
        for seed in range(seeds):
            one = done[(name, seed)]
            res.per_case[name] += one["cases"]
            res.seconds[name] = res.seconds.get(name, 0.0) + one["seconds"]
            w = one["worst"]
            if w is not None and (name not in res.worst or w[2] > res.worst[name][2]):
                res.worst[name] = w
        res.info[name] = _info(get(name))
    return res


def _info(sc: Any) -> dict[str, str]:
    """What the zoo table says of a scenario beside its errors: its bounds, its objects' sizes (over 16
    scenes generated with seed 99) and how many objects a scene holds."""
    scenes = sc.generate(16, 99)
    sizes = np.array([o.size for s in scenes for o in s.objects])
    (x0, y0), (x1, y1) = sc.bounds
    lo, hi = sc.counts
    return {
        "bounds_m": f"{x1 - x0:g} x {y1 - y0:g}",
        "sizes_cm": f"{100 * sizes.min():.1f}-{100 * sizes.max():.0f}",
        "objects": f"{lo}-{hi}",
    }


def _encode_pair(one: dict[str, Any]) -> dict[str, Any]:
    """A pair's record (:func:`run_one`) as JSON: its worst placement's case and scene as theirs."""
    w = one["worst"]
    worst = None if w is None else {"case": w[0].to_dict(), "placed": w[1].to_dict(), "t_cm": float(w[2])}
    return {"cases": one["cases"], "worst": worst, "seconds": one["seconds"]}


def _decode_pair(d: dict[str, Any]) -> dict[str, Any]:
    w = d["worst"]
    worst = None
    if w is not None:
        worst = (MissingCase.from_dict(w["case"]), Scene.from_dict(w["placed"]), float(w["t_cm"]))
    return {"cases": list(d["cases"]), "worst": worst, "seconds": float(d["seconds"])}


PAIR_RECORD = Codec(_encode_pair, _decode_pair)  # a (scenario, seed) pair's record in a sweep's folder


def format_zoo(res: ZooResult) -> str:
    """The zoo table as markdown, worst scenario first."""
    cols = [
        ("bounds_m", "bounds (m)"),
        ("sizes_cm", "sizes (cm)"),
        ("objects", "objects"),
        ("mean_t_cm", "mean t (cm)"),
        ("median_t_cm", "median t"),
        ("max_t_cm", "worst t"),
        ("mean_R_deg", "mean R (deg)"),
        ("median_R_deg", "median R"),
        ("catastrophic", "catastrophic"),
        ("at_bound", "at a bound"),
        ("oracle_t_cm", "oracle t"),
        ("oracle_R_deg", "oracle R"),
        ("ratio", "t / oracle"),
        ("miss_search", "misses: search"),
        ("miss_energy", "misses: energy"),
        ("flag_rate", "flagged"),
        ("flag_rate_good", "flagged (good)"),
        ("seconds", "seconds"),
    ]
    n = sum(r.figures["cases"] for r in res.rows())
    return (
        format_table(res.rows(), cols)
        + f"\n\n{n} placements. Catastrophic: more than {CATASTROPHIC_CM:g} cm and more than "
        f"{CATASTROPHIC_ORACLE:g} oracle means off. Good: within 3 oracle means; a miss "
        "is not good: the search's when the truth has the lower learned energy, the energy's when the placement "
        "has. Sorted worst first (t / oracle).\n\nTrust check, " + trust_line(res.per_case) + "."
    )
