"""Experiment 1 (the paper's Table 1): placing a missing bowl, fork or knife on the dining table.

For every test scene and every place setting, one of bowl, fork, knife is removed (its pose set to
``null``) and each method predicts it. Errors: position ``t`` in cm and orientation ``R`` in degrees
(none for the rotationally symmetric bowl). Rows are averaged over test cases, then mean +- std
over seeds.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from ..encoders import Encoder
from ..placement import Placer, SceneScorePlacer
from ..scenarios import DiningScenario
from ..scene import Scene, SceneError
from ..training import TrainConfig
from .report import SeedResults, format_table

__all__ = ["PAPER", "MissingCase", "make_cases", "score_cases", "fit_predict", "run", "METHODS"]

# The paper's Table 1 (mean over bowl, fork, knife): position cm, orientation deg
PAPER: dict[str, dict[str, float]] = {
    "SceneScore": {"mean_t_cm": 4.4, "mean_R_deg": 9.7},
    "Nearest-Nbr": {"mean_t_cm": 7.9, "mean_R_deg": 16.9},
    "SceneScore-Abs": {"mean_t_cm": 6.5, "mean_R_deg": 14.8},
    "NeatNet": {"mean_t_cm": 21.7, "mean_R_deg": 146.6},
}


@dataclass
class MissingCase:
    """One test case: a scene with ``name``'s pose removed, and the true pose."""

    scene: Scene
    name: str
    category: str
    truth: tuple[float, float, float]


def make_cases(test: list[Scene], categories: tuple[str, ...]) -> list[MissingCase]:
    """Every (scene, object of a listed category) pair, that object's pose removed."""
    cases = []
    for s in test:
        for o in s.objects:
            if o.category in categories and o.pose is not None:
                cases.append(MissingCase(s.without(o.name), o.name, o.category, o.pose))
    return cases


def angle_error_deg(a: float, b: float) -> float:
    d = (a - b + math.pi) % (2 * math.pi) - math.pi
    return abs(math.degrees(d))


def score_cases(
    cases: list[MissingCase], predicted: list[Scene], symmetric: tuple[str, ...]
) -> dict[str, float]:
    """Per-category and mean errors: ``<cat>_t_cm``, ``<cat>_R_deg``, ``mean_t_cm``, ``mean_R_deg``."""
    t: dict[str, list[float]] = {}
    r: dict[str, list[float]] = {}
    for case, pred in zip(cases, predicted):
        pose = pred[case.name].pose
        if pose is None:
            raise RuntimeError(f"method left {case.name!r} without a pose")
        t.setdefault(case.category, []).append(
            100 * math.hypot(pose[0] - case.truth[0], pose[1] - case.truth[1])
        )
        if case.category not in symmetric:
            r.setdefault(case.category, []).append(angle_error_deg(pose[2], case.truth[2]))
    out: dict[str, float] = {}
    for cat in t:
        out[f"{cat}_t_cm"] = float(np.mean(t[cat]))
        if cat in r:
            out[f"{cat}_R_deg"] = float(np.mean(r[cat]))
    out["mean_t_cm"] = float(np.mean([out[f"{c}_t_cm"] for c in t]))
    out["mean_R_deg"] = float(np.mean([out[f"{c}_R_deg"] for c in r])) if r else float("nan")
    return out


@dataclass
class OraclePlacer:
    """The process's own best guess for a missing object: the floor no method can beat."""

    scenario: Any
    name: str = "Oracle"

    def fit(self, scenes: list[Scene], seed: int = 0) -> OraclePlacer:
        return self

    def predict(self, scenes: list[Scene], seed: int = 0) -> list[Scene]:
        out = []
        for s in scenes:
            names = s.unknown
            out.append(s.with_poses([self.scenario.oracle(s, n) for n in names], names))
        return out


def _methods(
    scenario: DiningScenario, quick: bool, encoder: Encoder | None
) -> dict[str, Callable[[], Placer]]:
    from ..baselines import NearestNeighbour, NeatNet, NeatNetConfig

    tc = TrainConfig(iterations=150) if quick else TrainConfig()

    def scenescore(name: str, **model: Any) -> SceneScorePlacer:
        cfg = TrainConfig(**{**tc.to_dict(), "model": {**tc.model, **model}})
        return SceneScorePlacer(name, cfg, encoder=encoder)

    return {
        "NeatNet": lambda: NeatNet(config=NeatNetConfig(iterations=200 if quick else 1500)),
        "Nearest-Nbr": NearestNeighbour,
        "SceneScore-Abs": lambda: scenescore("SceneScore-Abs", absolute=True),
        "SceneScore (LeakyReLU)": lambda: scenescore("SceneScore (LeakyReLU)", activation="leaky_relu"),
        "SceneScore": lambda: scenescore("SceneScore"),
        "Oracle": lambda: OraclePlacer(scenario),
    }


METHODS = ["NeatNet", "Nearest-Nbr", "SceneScore-Abs", "SceneScore (LeakyReLU)", "SceneScore", "Oracle"]


class MissingResult(SeedResults):
    """Per-method, per-seed figures of Table 1 and the aggregated rows."""

    paper = PAPER
    spread = ("mean_t_cm", "mean_R_deg")


def fit_predict(
    factory: Callable[[], Placer], train: list[Scene], cases: list[MissingCase], seed: int, progress: bool
) -> tuple[list[Scene], float]:
    """Build a method, fit it on ``train``, fill the cases' missing poses; returns them and the seconds taken."""
    t0 = time.perf_counter()
    method = factory()
    if isinstance(method, SceneScorePlacer):
        method.progress = progress
    method.fit(train, seed=seed)
    pred = method.predict([c.scene for c in cases], seed=seed)
    return pred, time.perf_counter() - t0


def run(
    seeds: int = 3,
    methods: list[str] | None = None,
    quick: bool = False,
    progress: bool = True,
    scenes_fn: Callable[[list[Scene], list[Scene]], tuple[list[Scene], list[Scene]]] | None = None,
    log: Callable[[str], None] = print,
    encoder: Encoder | None = None,
) -> MissingResult:
    """Run Table 1 over ``seeds`` seeds; ``scenes_fn`` may turn ground-truth scenes into other graphs."""
    scenario = DiningScenario()
    table = _methods(scenario, quick, encoder)
    chosen = methods or METHODS
    unknown = [m for m in chosen if m not in table]
    if unknown:
        raise SceneError(f"unknown method(s) {unknown}; choose from {list(table)}")
    res = MissingResult()
    for seed in range(seeds):
        train_s, test_s = scenario.split(seed)
        truth_cases = make_cases(test_s, scenario.missing)
        if scenes_fn is not None:
            train_s, test_s = scenes_fn(train_s, test_s)
        cases = make_cases(test_s, scenario.missing)
        # the truth is always the simulator's pose, whatever graph the method sees
        for c, tc in zip(cases, truth_cases):
            c.truth = tc.truth
        for m in chosen:
            pred, dt = fit_predict(table[m], train_s, cases, seed, progress)
            figs = score_cases(cases, pred, scenario.symmetric)
            res.per_seed.setdefault(m, []).append(figs)
            res.seconds[m] = res.seconds.get(m, 0.0) + dt
            log(
                f"seed {seed} {m:24s} mean t {figs['mean_t_cm']:.2f} cm  R {figs['mean_R_deg']:.1f} deg  ({dt:.0f} s)"
            )
    return res


def table_columns() -> list[tuple[str, str]]:
    """Columns of Table 1: (key, header)."""
    return [
        ("bowl_t_cm", "bowl t"),
        ("fork_t_cm", "fork t"),
        ("fork_R_deg", "fork R"),
        ("knife_t_cm", "knife t"),
        ("knife_R_deg", "knife R"),
        ("mean_t_cm", "mean t (cm)"),
        ("mean_R_deg", "mean R (deg)"),
    ]


def format_missing(res: MissingResult) -> str:
    """Table 1 as markdown, the paper's figures beside ours."""
    return format_table(
        res.rows(), table_columns(), std={"mean_t_cm": "mean_t_cm_std", "mean_R_deg": "mean_R_deg_std"}
    )
