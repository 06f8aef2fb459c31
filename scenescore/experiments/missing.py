"""Experiment 1 (the paper's Table 1): placing a missing bowl, fork or knife on the dining table.

For every test scene and every place setting, one of bowl, fork, knife is removed (its pose set to
``null``) and each method predicts it. Errors: position ``t`` in cm and orientation ``R`` in degrees
(none for the rotationally symmetric bowl). Rows are averaged over test cases, then mean +- std
over seeds.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping
from dataclasses import replace
from functools import partial
from typing import Any

from ..encoders import Encoder
from ..evaluation.cases import MissingCase, OraclePlacer, make_cases, score_cases
from ..learn import ONE_NETWORK, RAW_EDGES, TrainConfig
from ..learn.config import shared_compile
from ..planning.placement import Placer, SceneScorePlacer
from ..runtime.devices import resolve_device
from ..scenarios import DiningScenario
from ..scene.scene import Scene, SceneError
from .execution import Execution, network_trainings
from .report import SeedResults, format_table
from .tasks import Task, describe, run_tasks

__all__ = ["PAPER", "fit_predict", "run", "train_config", "METHODS", "EXTRA_METHODS"]

# The paper's Table 1 (mean over bowl, fork, knife): position cm, orientation deg
PAPER: dict[str, dict[str, float]] = {
    "SceneScore": {"mean_t_cm": 4.4, "mean_R_deg": 9.7},
    "Nearest-Nbr": {"mean_t_cm": 7.9, "mean_R_deg": 16.9},
    "SceneScore-Abs": {"mean_t_cm": 6.5, "mean_R_deg": 14.8},
    "NeatNet": {"mean_t_cm": 21.7, "mean_R_deg": 146.6},
}


def train_config(quick: bool = False, seeds: int = 1, device: Any = None) -> TrainConfig:
    """SceneScore's training in Table 1: one network (150 iterations with ``quick``), compiled where the
    ``seeds`` trainings of each row's network pay for one compile together
    (:func:`~scenescore.learn.config.shared_compile`)."""
    tc = TrainConfig(iterations=150, **ONE_NETWORK) if quick else TrainConfig(**ONE_NETWORK)
    return shared_compile(tc, DiningScenario().split(0)[0], seeds, resolve_device(device).type)


def _methods(
    scenario: DiningScenario,
    quick: bool,
    tc: TrainConfig,
    encoder: Encoder | None,
    device: Any = None,
    cache: Any = None,
) -> dict[str, Callable[[], Placer]]:
    from ..evaluation.baselines import NearestNeighbour, NeatNet, NeatNetConfig

    def scenescore(name: str, train: Mapping[str, Any] | None = None, **network: Any) -> SceneScorePlacer:
        net = replace(tc.network, **network)
        cfg = TrainConfig(**{**tc.to_dict(), **(train or {}), "network": net})
        return SceneScorePlacer(name, cfg, encoder=encoder, device=device, cache=cache)

    return {
        "NeatNet": lambda: NeatNet(config=NeatNetConfig(iterations=200 if quick else 1500)),
        "Nearest-Nbr": NearestNeighbour,
        "SceneScore-Abs": lambda: scenescore("SceneScore-Abs", absolute=True),
        "SceneScore (LeakyReLU)": lambda: scenescore("SceneScore (LeakyReLU)", activation="leaky_relu"),
        "SceneScore": lambda: scenescore("SceneScore"),
        "SceneScore (raw edges)": lambda: scenescore("SceneScore (raw edges)", RAW_EDGES),
        "Oracle": lambda: OraclePlacer(scenario),
    }


METHODS = ["NeatNet", "Nearest-Nbr", "SceneScore-Abs", "SceneScore (LeakyReLU)", "SceneScore", "Oracle"]
# rows run only when named in ``methods`` (``--methods``): the network without its edge encoder, trained
# with the feature noise it had as the default (see TrainConfig.edge_encoder)
EXTRA_METHODS = ["SceneScore (raw edges)"]


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
    scenes_fn: Callable[[list[Scene], list[Scene]], tuple[list[Scene], list[Scene]]] | None = None,
    encoder: Encoder | None = None,
    *,
    execution: Execution | None = None,
) -> MissingResult:
    """Run Table 1 over ``seeds`` seeds; ``scenes_fn`` may turn ground-truth scenes into other graphs.
    ``execution``: where and how (default :class:`Execution`'s); its ``device`` is where SceneScore's
    models train and place (the baselines stay on the CPU); ``jobs > 1`` runs each method on each seed
    in one of that many worker processes of one thread each (the figures do not depend on it); with
    ``scenes_fn`` (a function of this process) they run here, in turn; its ``sweep`` keeps each method
    and seed's record, to resume from (:mod:`scenescore.experiments.tasks`)."""
    ex = execution or Execution()
    tc = train_config(quick, seeds, ex.device)
    table = _methods(DiningScenario(), quick, tc, encoder, ex.device)
    chosen = methods or METHODS
    unknown = [m for m in chosen if m not in table]
    if unknown:
        raise SceneError(f"unknown method(s) {unknown}; choose from {list(table)}")
    one = partial(
        _one,
        quick=quick,
        tc=tc,
        progress=ex.progress and (ex.jobs == 1 or scenes_fn is not None),
        scenes_fn=scenes_fn,
        encoder=encoder,
        device=ex.device,
        cache=ex.cache,
        graphs={},
    )
    # every setting a record depends on beyond its method and seed
    config = {
        "quick": quick,
        "compile": tc.compile,
        "graphs": describe(scenes_fn),
        "encoder": describe(encoder),
        "device": str(ex.device),
    }
    tasks = [Task.of("missing", method=m, seed=seed, config=config) for seed in range(seeds) for m in chosen]
    res = MissingResult()
    jobs = 1 if scenes_fn is not None else ex.jobs
    bar = "Table 1" if ex.progress else None
    for task, (figs, dt) in zip(
        tasks, run_tasks(one, tasks, jobs, ex.log, bar, ex.sweep, length=network_trainings)
    ):
        res.per_seed.setdefault(task.method, []).append(figs)
        res.seconds[task.method] = res.seconds.get(task.method, 0.0) + dt
    return res


def _one(
    task: Task,
    log: Callable[[str], None],
    quick: bool,
    tc: TrainConfig,
    progress: bool,
    scenes_fn: Callable[[list[Scene], list[Scene]], tuple[list[Scene], list[Scene]]] | None,
    encoder: Encoder | None,
    device: Any,
    cache: Any,
    graphs: dict[int, tuple[list[Scene], list[Scene]]],
) -> tuple[dict[str, float], float]:
    """One method on one seed of :func:`run`: its figures and seconds (``graphs``: each seed's scenes
    from ``scenes_fn``, made once for every method)."""
    seed, m = task.seed, task.method
    scenario = DiningScenario()
    train_s, test_s = scenario.split(seed)
    truth_cases = make_cases(test_s, scenario.missing)
    if scenes_fn is not None:
        if seed not in graphs:
            graphs[seed] = scenes_fn(train_s, test_s)
        train_s, test_s = graphs[seed]
    cases = make_cases(test_s, scenario.missing)
    # the truth is always the simulator's pose, whatever graph the method sees
    for c, t in zip(cases, truth_cases):
        c.truth = t.truth
    pred, dt = fit_predict(
        _methods(scenario, quick, tc, encoder, device, cache)[m], train_s, cases, seed, progress
    )
    figs = score_cases(cases, pred, scenario.symmetric)
    log(
        f"seed {seed} {m:24s} mean t {figs['mean_t_cm']:.2f} cm  R {figs['mean_R_deg']:.1f} deg  ({dt:.0f} s)"
    )
    return figs, dt


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
