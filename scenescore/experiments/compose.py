"""Experiment 3 (the paper's Fig. 4): composing the learned energy with constraints.

A television and two speakers; at test time 0, 1, 2, ... fixed clutter boxes on the floor. For
every clutter level each method draws ``samples`` arrangements (spread over ``scenes`` cluttered
test scenes); a sample counts when :meth:`TVScenario.correct` holds (aligned and symmetric within the
thresholds, no collision by the exact check, inside the room).

- NeatNet: whole arrangements from its VAE's prior; the constraints reject (correct = not rejected).
- SceneScore: Langevin on energy + 10 * hinge collision + 10 * bounds; every particle is a sample. The
  energy sees the television and speakers only (the clutter is a class it never saw, and enters
  through the collision cost). The particles are a population resampled three times by cost
  (population annealing): independent chains from uniform starts mostly stall in high-energy basins,
  resampled ones mostly end aligned, at the price of fewer distinct samples, so
  the table also counts the distinct correct samples (poses rounded to 1 cm). The energy is trained
  with every counter-example chain moving every object, as the sampler does here (with the default
  mix of one-object and subset chains, one seed of three learned a basin lower than the data's and
  its population collapsed into it).
- SceneScore (langevin>alm): every Langevin sample refined at once by the batched augmented
  Lagrangian (``alm``, :data:`REFINE`): each sample descends the energy under the constraints for one
  outer iteration and on until it is feasible and the objective nearly flat (``tol_grad`` 1 per metre,
  not the default's 0.01: polished to the minimum, the samples of one basin merge into one
  arrangement); the same ``samples`` budget, real counts; its time is the Langevin time plus the
  refinement's.
- SceneScore (langevin>osqp), (langevin>casadi): per-solve refinements (one solve per sample), so only the
  first ``refine`` Langevin samples of each scene are refined, one solve each. They are not rows of
  the main table: a separate one gives their correct and distinct counts among the samples they
  refined (real counts of that smaller number, never scaled up).
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np
import torch

from ..evaluation.baselines import NeatNet, NeatNetConfig
from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..scenarios.tv import TVScenario
from ..scene.scene import Scene, SceneError
from ..solvers import get, solve
from .execution import Execution
from .report import Row, format_table
from .tasks import Task, run_tasks

if TYPE_CHECKING:
    from ..models import ScoreModel
    from ..problem.problem import Problem

__all__ = [
    "ComposeResult",
    "run",
    "format_compose",
    "plot_compose",
    "METHODS",
    "train_energy",
    "train_config",
    "tv_problem",
    "langevin_options",
    "BATCHED",
    "CHAINS",
    "REFINE",
]

BATCHED = "SceneScore (langevin>alm)"
METHODS = ["NeatNet", "SceneScore", BATCHED, "SceneScore (langevin>osqp)", "SceneScore (langevin>casadi)"]
#: the batched row's ``alm`` options: descend until feasible and nearly flat (a repair, ``polish: false``,
#: leaves misaligned samples misaligned; the default ``tol_grad`` 0.01 merges the samples of a basin)
REFINE: dict[str, Any] = {"tol_grad": 1.0}
#: per-solve refinements: they refine ``refine`` samples per level, reported in a table of their own
CHAINS = {"SceneScore (langevin>osqp)": "osqp", "SceneScore (langevin>casadi)": "casadi"}


@dataclass
class ComposeResult:
    """Correct samples per method, seed and clutter level; seconds per method (summed over seeds). The
    per-solve chains (:data:`CHAINS`) count among the ``refine`` samples they refined per level."""

    levels: list[int]
    samples: int
    refine: int
    refine_options: dict[str, Any] = field(default_factory=lambda: dict(REFINE))  # the batched row's alm
    correct: dict[str, list[list[float]]] = field(default_factory=dict)  # method -> seed -> level
    distinct: dict[str, list[list[float]]] = field(default_factory=dict)  # distinct correct samples
    seconds: dict[str, float] = field(default_factory=dict)

    def rows(self) -> list[Row]:
        rows = []
        for m, runs in self.correct.items():
            a = np.asarray(runs, dtype=float)
            fig: dict[str, float] = {}
            d = np.asarray(self.distinct[m], dtype=float)
            for k, n in enumerate(self.levels):
                fig[f"correct_at_{n}_objects"] = float(a[:, k].mean())
                if len(a) > 1:  # no spread from one seed
                    fig[f"correct_at_{n}_objects_std"] = float(a[:, k].std())
                fig[f"distinct_at_{n}_objects"] = float(d[:, k].mean())
            fig["seconds"] = self.seconds.get(m, 0.0)
            fig["samples"] = float(self.samples if m not in CHAINS else self.refine)
            rows.append(Row(m, fig))
        return rows


def train_energy(
    scenes: list[Scene],
    seed: int,
    quick: bool = False,
    progress: bool = False,
    device: Any = None,
    cache: Any = None,
) -> ScoreModel:
    """The experiment's energy, trained on ``scenes`` (on ``device``): every counter-example chain moves
    every object, as the sampler does here; the library's default network (its edge encoder and noise
    on every node input: without the encoder the samples spread beyond the alignment tolerance;
    docs/studies.md, "Behind the defaults"). ``cache``: a model cache folder
    (:mod:`scenescore.learn.cache`)."""
    return fit(scenes, train_config(quick), seed=seed, progress=progress, device=device, run=Run(cache=cache))


def train_config(quick: bool = False) -> TrainConfig:
    """The training settings of :func:`train_energy`."""
    return TrainConfig(
        iterations=100 if quick else 600, full_fraction=1.0, single_fraction=0.0, **ONE_NETWORK
    )


def tv_problem(scene: Scene, model: ScoreModel) -> Problem:
    """A cluttered test scene's problem: energy (television and speakers only) + 10 * hinge collision
    + 10 * bounds, the television and speakers moving."""
    from .. import costs
    from ..problem.problem import Problem

    cost = (
        costs.LearnedEnergy(model, objects=[o.name for o in scene.objects if not o.fixed])
        + 10.0 * costs.HingeCollision(margin=0.0)
        + 10.0 * costs.Bounds()
    )
    return Problem(scene, cost, movable=scene.unknown)


def langevin_options(particles: int) -> dict[str, float]:
    """The ``langevin`` stage's options: ``particles`` per scene, a population resampled three times, the
    sampler's own 100 steps (fewer leave a population in a wrong basin; docs/studies.md, "Behind the
    defaults")."""
    return {"particles": particles, "steps": 100, "resample": 3, "temperature": 1.0}


def correct_samples(scenario: TVScenario, scene, poses: np.ndarray) -> tuple[int, int]:
    """Correct samples among ``poses (S, N, 3)``, and how many of them are distinct at 1 cm."""
    poses = np.asarray(poses)
    ok = poses[scenario.correct_many(scene, poses)]
    if not len(ok):
        return 0, 0
    return len(ok), len(np.unique(np.round(ok[..., :2], 2).reshape(len(ok), -1), axis=0))


def run(
    seeds: int = 1,
    methods: list[str] | None = None,
    quick: bool = False,
    levels: list[int] | None = None,
    samples: int | None = None,
    scenes: int | None = None,
    refine: int | None = None,
    refine_options: dict[str, Any] | None = None,
    *,
    execution: Execution | None = None,
) -> ComposeResult:
    """Fig. 4 over ``seeds`` seeds: correct samples of ``samples`` per method at each clutter level.
    ``refine_options``: the :data:`BATCHED` row's ``alm`` options (default :data:`REFINE`).
    ``execution``: where and how (default :class:`Execution`'s): SceneScore's model and problems on its
    ``device`` (NeatNet on the CPU); ``jobs > 1`` runs the seeds in that many worker processes of one
    thread each (the counts do not depend on it; seconds are summed over the workers); its ``sweep``
    keeps each seed's record, to resume from (:mod:`scenescore.experiments.tasks`)."""
    ex = execution or Execution()
    chosen = methods or METHODS
    unknown = [m for m in chosen if m not in METHODS]
    if unknown:
        raise SceneError(f"unknown method(s) {unknown}; choose from {METHODS}")
    levels = levels if levels is not None else ([0, 1] if quick else [0, 1, 2, 3, 4, 5])
    n_scenes = scenes or (1 if quick else 5)
    samples = samples or (16 if quick else 5000)
    per_scene = max(1, samples // n_scenes)
    samples = per_scene * n_scenes
    k_refine = refine if refine is not None else (1 if quick else 4)
    res = ComposeResult(
        levels, samples, k_refine * n_scenes, dict(REFINE if refine_options is None else refine_options)
    )
    one = partial(
        _seed,
        chosen=list(chosen),
        levels=list(levels),
        n_scenes=n_scenes,
        per_scene=per_scene,
        k_refine=k_refine,
        quick=quick,
        progress=ex.progress,
        bars=ex.progress and ex.jobs == 1,
        device=ex.device,
        refine_options=res.refine_options,
        cache=ex.cache,
    )
    config = {
        "methods": list(chosen),
        "levels": list(levels),
        "scenes": n_scenes,
        "per_scene": per_scene,
        "refine": k_refine,
        "quick": quick,
        "device": str(ex.device),
        "refine_options": res.refine_options,
    }  # every setting a seed's record depends on
    tasks = [Task.of("compose", seed=seed, config=config) for seed in range(seeds)]
    bar = "Fig. 4 seeds" if ex.progress else None
    for counts, uniq, seconds in run_tasks(one, tasks, ex.jobs, ex.log, bar, ex.sweep):
        for m in chosen:
            res.correct.setdefault(m, []).append(counts[m])
            res.distinct.setdefault(m, []).append(uniq[m])
            res.seconds[m] = res.seconds.get(m, 0.0) + seconds.get(m, 0.0)
    return res


def _seed(
    task: Task,
    log: Callable[[str], None],
    chosen: list[str],
    levels: list[int],
    n_scenes: int,
    per_scene: int,
    k_refine: int,
    quick: bool,
    progress: bool,
    bars: bool,
    device: Any,
    refine_options: dict[str, Any],
    cache: Any = None,
) -> tuple[dict[str, list[float]], dict[str, list[float]], dict[str, float]]:
    """One seed of :func:`run`: per method, correct and distinct correct samples per clutter level, and
    seconds (``progress``: a log line per level; ``bars``: training's progress bar)."""
    seed = task.seed
    scenario = TVScenario()
    train_s, test_s = scenario.split(seed)
    methods = _Methods.trained(chosen, train_s, seed, quick, bars, device, cache)
    methods.per_scene, methods.k_refine, methods.refine_options = per_scene, k_refine, refine_options
    counts: dict[str, list[float]] = {m: [] for m in chosen}
    uniq: dict[str, list[float]] = {m: [] for m in chosen}
    for n in levels:
        got = dict.fromkeys(chosen, 0.0)
        dis = dict.fromkeys(chosen, 0.0)
        for k in range(n_scenes):
            scene = scenario.clutter(test_s[k % len(test_s)], n, seed=1000 * seed + 10 * n + k)
            for m, (c, d) in methods.score(scenario, scene, k).items():
                got[m] += c
                dis[m] += d
        for m in chosen:
            counts[m].append(got[m])
            uniq[m].append(dis[m])
        if progress:
            log(f"seed {seed} clutter {n}: " + ", ".join(f"{m} {counts[m][-1]:.0f}" for m in chosen))
    return counts, uniq, methods.seconds


@dataclass
class _Methods:
    """The methods of one seed, trained, and the seconds each has taken so far (training included)."""

    chosen: list[str]
    model: ScoreModel | None
    neatnet: Any
    seconds: dict[str, float]
    per_scene: int = 0
    k_refine: int = 0
    refine_options: dict[str, Any] = field(default_factory=dict)

    @classmethod
    def trained(
        cls,
        chosen: list[str],
        train_s: list[Scene],
        seed: int,
        quick: bool,
        bars: bool,
        device: Any,
        cache: Any,
    ) -> _Methods:
        """Train the energy (once, for every SceneScore method) and NeatNet, as ``chosen`` needs them."""
        seconds: dict[str, float] = {}
        ss_methods = [m for m in chosen if m != "NeatNet"]
        model = None
        if ss_methods:
            t0 = time.perf_counter()
            model = train_energy(train_s, seed, quick, bars, device, cache)
            dt = time.perf_counter() - t0
            for m in ss_methods:
                seconds[m] = seconds.get(m, 0.0) + dt
        nn = None
        if "NeatNet" in chosen:
            t0 = time.perf_counter()
            nn = NeatNet(config=NeatNetConfig(iterations=200 if quick else 1500)).fit(train_s, seed)
            seconds["NeatNet"] = seconds.get("NeatNet", 0.0) + time.perf_counter() - t0
        return cls(chosen, model, nn, seconds)

    def score(self, scenario: TVScenario, scene: Scene, k: int) -> dict[str, tuple[float, float]]:
        """Correct and distinct correct samples of each method on test scene ``k`` (its seeds are ``k``)."""
        chosen, seconds = self.chosen, self.seconds
        out: dict[str, tuple[float, float]] = {}
        if self.neatnet is not None:
            t0 = time.perf_counter()
            out["NeatNet"] = correct_samples(
                scenario, scene, self.neatnet.sample(scene, self.per_scene, seed=k)
            )
            seconds["NeatNet"] += time.perf_counter() - t0
        if self.model is None:
            return out
        prob = tv_problem(scene, self.model)
        t0 = time.perf_counter()
        r = solve(prob, "langevin", seed=k, options={"langevin": langevin_options(self.per_scene)})
        t_lan = time.perf_counter() - t0
        for m in chosen:
            if m != "NeatNet":
                seconds[m] += t_lan
        assert r.samples is not None
        if "SceneScore" in chosen:
            out["SceneScore"] = correct_samples(scenario, scene, r.samples)
        if BATCHED in chosen:
            t0 = time.perf_counter()
            rr = get("alm", **self.refine_options).solve(prob, init=torch.as_tensor(r.samples))
            seconds[BATCHED] += time.perf_counter() - t0
            assert rr.samples is not None
            out[BATCHED] = correct_samples(scenario, scene, rr.samples)
        for m, stage in CHAINS.items():
            if m in chosen:
                out[m] = self._refined_one_by_one(m, stage, prob, r.samples, scenario, scene)
        return out

    def _refined_one_by_one(
        self, m: str, stage: str, prob: Problem, samples: np.ndarray, scenario: TVScenario, scene: Scene
    ) -> tuple[float, float]:
        """Method ``m``: the first ``k_refine`` samples refined one at a time by the solver ``stage``."""
        solver = get(stage)
        t0 = time.perf_counter()
        refined = [
            solver.solve(prob, init=torch.as_tensor(samples[j]), seed=j).poses
            for j in range(min(self.k_refine, len(samples)))
        ]
        self.seconds[m] += time.perf_counter() - t0
        return correct_samples(scenario, scene, np.asarray(refined))


def format_compose(res: ComposeResult) -> str:
    """Fig. 4 as markdown: correct and distinct correct samples per clutter level and seconds per method,
    all of the same ``samples`` budget; then the per-solve refinements in a table of their own."""
    rows = [r for r in res.rows() if r.method not in CHAINS]
    per_solve = [r for r in res.rows() if r.method in CHAINS]
    cols = [(f"correct_at_{n}_objects", f"{n} clutter ({n + 3} objects)") for n in res.levels]
    cols.append(("seconds", "seconds"))
    dcols = [(f"distinct_at_{n}_objects", f"{n} clutter") for n in res.levels]
    out = (
        format_table(rows, cols, digits=0)
        + f"\n\nCorrect of {res.samples} samples per clutter level, every method on the same budget; "
        f"{BATCHED} refines all {res.samples} Langevin samples at once (alm options "
        f"{json.dumps(res.refine_options)}{_refine_words(res.refine_options)}).\n\n"
        "Distinct correct samples (positions rounded to 1 cm; SceneScore's population resampling copies "
        "particles):\n\n" + format_table(rows, dcols, digits=0)
    )
    if per_solve:
        both = [c for pair in zip(cols, dcols) for c in pair]
        both = [(k, h if k.startswith("correct") else "distinct") for k, h in both] + [("seconds", "seconds")]
        out += (
            f"\n\nPer-solve refinement, {res.refine} samples per clutter level: these chains refine one "
            f"sample per solve, so each refines the first {res.refine} Langevin samples of a level (not "
            f"{res.samples}); counts are among those {res.refine}; seconds include training and the "
            "Langevin stage.\n\n" + format_table(per_solve, both, digits=0)
        )
    return out


def _refine_words(opts: dict[str, Any]) -> str:
    """What the batched row's ``alm`` options make of it, in words."""
    if opts.get("polish") is False:
        return ": a repair, each sample stops once feasible"
    if opts == REFINE:
        return ": each sample descends until feasible and the objective nearly flat"
    return ""


def plot_compose(res: ComposeResult, path: str | Path) -> None:
    """The paper's Fig. 4: correct samples against the number of objects, one line per method of the
    main table (the per-solve chains refine fewer samples and have a table of their own)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..viz.plot import save_figure

    fig, ax = plt.subplots(figsize=(5, 3.5))
    x = [n + 3 for n in res.levels]
    for r in res.rows():
        if r.method in CHAINS:  # counts of fewer samples: not on this axis
            continue
        y = [r.figures[f"correct_at_{n}_objects"] for n in res.levels]
        ax.plot(x, y, marker="o", linestyle="--" if r.method == BATCHED else "-", label=r.method)
    ax.set_xlabel("number of objects (television, 2 speakers, clutter)")
    ax.set_ylabel(f"correct samples (of {res.samples})")
    ax.set_xticks(x)
    ax.legend(fontsize=7)
    ax.grid(alpha=0.3)
    save_figure(fig, path)
