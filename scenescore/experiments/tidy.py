"""Tidying messy scenes: which objects to move, how far, in what order, against what it buys.

For each scenario (dining, desk, television and a few of the zoo's) and each seed (its own split of the
scenes): train the energy on its training scenes; displace ``k`` objects of each test scene (shifted by
a fraction of the bounds' half-extent in a random direction and turned, or two objects of different
kinds swapped), keeping only messy scenes that are collision-free, inside the bounds and *rejected* by
the scenario's check. Then, per method:

- ``tidy (effort W)``: :func:`scenescore.planning.tidying.tidy` at each effort weight;
- ``re-place all``: every movable object placed from scratch by the sampler, no effort term;
- ``missing placement``: the displaced objects (an oracle says which) placed by ``place``.

Figures: the fraction of results the scenario's check accepts; precision and recall of the moved set
against the displaced set; total displacement (centre and tip, metres) over the put-back
displacement (the displaced objects moved back to where they were); objects moved; plan length
(pick-and-places, buffer moves included); the fraction of results whose targets admit no plan (a
target outside the bounds, or on an object that stays) and, of the plans made, the fraction valid
when replayed.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from dataclasses import replace
from functools import partial
from typing import Any, cast

from ..costs import Displacement
from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..learn.config import shared_compile
from ..models import ScoreModel
from ..planning.placement import place_many
from ..planning.tidying import TidyError, TidyOptions, calibrate, plan_moves, tidy_many, validate_plan
from ..runtime.devices import resolve_device
from ..scenarios import get
from ..scene.scene import Scene, SceneError
from ..solvers.langevin import LangevinOptions
from .execution import Execution
from .messy import SIZES, MessyCase, accepts, displaceable, messy_cases
from .tasks import Codec, Task, run_tasks
from .tidy_results import EFFORTS, Outcome, TidyRun, format_tidy, method_name, plot_pareto

__all__ = [
    "SCENARIOS",
    "TEST_SCENES",
    "EFFORTS",
    "SIZES",
    "MessyCase",
    "TidyRun",
    "displaceable",
    "accepts",
    "messy_cases",
    "run",
    "format_tidy",
    "plot_pareto",
]

SCENARIOS: tuple[str, ...] = ("dining", "desk", "tv", "zoo-workstation", "zoo-hall")
TEST_SCENES = 3  # test scenes per scenario and seed that messy cases are made from


def _score(
    case: MessyCase, scenario: Any, after: Scene, moved: list[str], model: ScoreModel, seed: int
) -> Outcome:
    """Judge a result and plan its moves (for the methods that do not plan their own)."""
    d = Displacement(objects=case.messy.names).bind(case.messy)
    disp = float(cast(Displacement, d).moves(after.poses()).sum())
    try:
        steps = plan_moves(case.messy, after, model=model, seed=seed)
        valid, made = validate_plan(case.messy, after, steps, model=model).valid, True
    except TidyError:
        steps, valid, made = [], False, False
    buffers = sum(s.buffer for s in steps)
    return Outcome(accepts(scenario, after, case.truth), moved, disp, len(steps), valid, buffers, made)


def _moved(before: Scene, after: Scene, tol: float = 0.01) -> list[str]:
    d = cast(Displacement, Displacement(objects=before.names).bind(before)).moves(after.poses())
    return [n for n, v in zip(before.names, d) if v > tol]


def run(
    scenarios: tuple[str, ...] = SCENARIOS,
    efforts: tuple[float, ...] = EFFORTS,
    test_scenes: int = TEST_SCENES,
    seeds: Sequence[int] = (0,),
    config: TrainConfig | None = None,
    sizes: tuple[float, ...] = SIZES,
    options: TidyOptions | None = None,
    place_options: LangevinOptions | None = None,
    *,
    execution: Execution | None = None,
) -> TidyRun:
    """Train per scenario and seed of ``seeds`` (each seed its own split, model and displacements), make
    the messy cases, run every method on them (``options``: tidy's, ``place_options``: the baselines'
    placement; defaults: the library's); the cases of every seed are pooled. ``execution``: where and
    how (default ``Execution(progress=False)``): the models train on its ``device``; ``jobs > 1`` runs
    the scenario and seed pairs in that many worker processes of one thread each (the figures do not
    depend on it; each method's seconds are then summed over the workers); its ``sweep`` keeps each
    pair's record, to resume from (:mod:`scenescore.experiments.tasks`)."""
    ex = execution or Execution(progress=False)
    seeds = list(seeds)
    if not seeds or any(isinstance(s, bool) or not isinstance(s, int) or s < 0 for s in seeds):
        raise SceneError(f"tidy experiment: seeds must be one or more whole numbers >= 0, got {seeds!r}")
    for name in scenarios:
        get(name)  # an unknown name fails here, before any worker starts
    # each scenario's seeds' networks compile together where that pays, settled before any pair starts
    kind, base = resolve_device(ex.device).type, config or TrainConfig(**ONE_NETWORK)
    configs = {
        (name, s): shared_compile(base, get(name).split(s)[0], len(seeds), kind)
        for name in scenarios
        for s in seeds
    }
    one = partial(
        _scenario,
        efforts=tuple(efforts),
        test_scenes=test_scenes,
        configs=configs,
        sizes=tuple(sizes),
        options=options,
        place_options=place_options,
        # what a worker needs of the execution: the log is its own, the tasks' records are kept here
        execution=Execution(progress=ex.progress and ex.jobs == 1, device=ex.device, cache=ex.cache),
    )
    settings = {
        "efforts": list(efforts),
        "test_scenes": test_scenes,
        "training": config,
        "trainings": len(seeds),  # compiled together where that pays
        "sizes": list(sizes),
        "options": options,
        "place_options": place_options,
        "device": str(ex.device),
    }  # every setting a pair's record depends on beyond its scenario and seed
    units = [Task.of("tidy", scenario=name, seed=s, config=settings) for name in scenarios for s in seeds]
    codec = Codec(TidyRun.to_dict, TidyRun.from_dict)
    bar = "tidy" if ex.progress else None
    parts = run_tasks(one, units, ex.jobs, ex.log, bar, ex.sweep, codec)
    res = TidyRun(efforts=tuple(efforts))
    for part in parts:  # in the order asked, whatever order the workers finished in
        res.cases += part.cases
        for m, got in part.outcomes.items():
            res.outcomes.setdefault(m, []).extend(got)
            res.seconds[m] = res.seconds.get(m, 0.0) + part.seconds[m]
    return res


def _scenario(
    unit: Task,
    log: Callable[[str], None],
    efforts: tuple[float, ...],
    test_scenes: int,
    configs: dict[tuple[str, int], TrainConfig],
    sizes: tuple[float, ...],
    options: TidyOptions | None,
    place_options: LangevinOptions | None,
    execution: Execution,
) -> TidyRun:
    """:func:`run_scenario` as a task of :func:`run` with its training settings of ``configs``, its lines
    to the task's ``log``."""
    ex = replace(execution, log=log)
    config = configs[(unit.scenario, unit.seed)]
    return run_scenario(unit, efforts, test_scenes, config, sizes, options, place_options, execution=ex)


def calibration_scenes(train: list[Scene], test: list[Scene], test_scenes: int) -> list[Scene]:
    """The scenes a scenario's move gain is calibrated on: up to 8 test scenes after the first
    ``test_scenes`` (no messy case is made from them), or the first 8 training scenes where fewer than 4
    are left."""
    held = test[test_scenes : test_scenes + 8]
    return held if len(held) >= 4 else train[:8]


def run_scenario(
    unit: Task | tuple[str, int],
    efforts: tuple[float, ...],
    test_scenes: int,
    config: TrainConfig | None,
    sizes: tuple[float, ...],
    options: TidyOptions | None,
    place_options: LangevinOptions | None,
    *,
    execution: Execution | None = None,
) -> TidyRun:
    """One scenario and seed ``unit`` of :func:`run`: its cases and every method's outcomes and seconds.
    ``execution``: where and how (default ``Execution(progress=False)``; its ``jobs`` and ``sweep`` are
    :func:`run`'s, unused here)."""
    ex = execution or Execution(progress=False)
    name, seed = (unit.scenario, unit.seed) if isinstance(unit, Task) else unit
    res = TidyRun(efforts=tuple(efforts))
    methods = [method_name(e) for e in efforts] + ["re-place all", "missing placement"]
    for m in methods:
        res.outcomes[m] = []
        res.seconds[m] = 0.0
    sc = get(name)
    t0 = time.perf_counter()
    train_s, test_s = sc.split(seed)
    model = fit(
        train_s,
        config or TrainConfig(**ONE_NETWORK),
        seed=seed,
        progress=ex.progress,
        device=ex.device,
        run=Run(cache=ex.cache),
    )
    gain = calibrate(model, calibration_scenes(train_s, test_s, test_scenes), seed=seed)
    cases = messy_cases(sc, test_s[:test_scenes], seed, sizes=sizes)
    if not cases:
        raise SceneError(f"tidy experiment: no messy case could be made for {name!r}")
    took = time.perf_counter() - t0
    ex.log(f"{name} seed {seed}: trained in {took:.0f} s; move gain {gain:.3f}; {len(cases)} messy cases")
    res.cases += cases
    messy = [c.messy for c in cases]
    for e in efforts:
        t = time.perf_counter()
        results = tidy_many(model, messy, effort=e, seed=seed, options=options)
        res.seconds[method_name(e)] += time.perf_counter() - t
        for c, r in zip(cases, results):
            out = Outcome(
                accepts(sc, r.after, c.truth),
                list(r.moved),
                r.total_displacement,
                len(r.steps),
                r.check.valid,
                r.buffers,
                r.plan_made,
            )
            res.outcomes[method_name(e)].append(out)
        ex.log(f"{name} seed {seed}: {method_name(e)} {time.perf_counter() - t:.0f} s")
    _baselines(res, name, sc, cases, model, place_options, seed, ex.log)
    return res


def _baselines(
    res: TidyRun,
    name: str,
    sc: Any,
    cases: list[MessyCase],
    model: ScoreModel,
    place_options: LangevinOptions | None,
    seed: int,
    log: Callable[[str], None],
) -> None:
    """The two baselines on ``cases`` (of scenario ``sc``, called ``name``), their outcomes and seconds
    added to ``res``: every movable object placed from scratch (``re-place all``), and the displaced
    ones alone (``missing placement``)."""
    t = time.perf_counter()
    blank = [c.messy.copy() for c in cases]
    for s in blank:
        for o in s.objects:
            if not o.fixed:
                o.pose = None
    placed = place_many(model, blank, place_options, seed=seed)
    res.seconds["re-place all"] += time.perf_counter() - t
    res.outcomes["re-place all"] += [
        _score(c, sc, p, _moved(c.messy, p), model, seed) for c, p in zip(cases, placed)
    ]
    t = time.perf_counter()
    holes = []
    for c in cases:
        s = c.messy.copy()
        for n in c.displaced:
            s.objects[s.index(n)].pose = None
        holes.append(s)
    filled = place_many(model, holes, place_options, seed=seed)
    res.seconds["missing placement"] += time.perf_counter() - t
    res.outcomes["missing placement"] += [
        _score(c, sc, p, _moved(c.messy, p), model, seed) for c, p in zip(cases, filled)
    ]
    log(f"{name} seed {seed}: baselines {time.perf_counter() - t:.0f} s")
