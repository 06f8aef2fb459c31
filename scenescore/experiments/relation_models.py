"""The relation models: one energy per relation, trained on its own examples and accepted by its edge.

A relation model learns from :data:`EXAMPLES` example scenes of its relation (``relation-<name>``: 2 or
3 objects each, the seed's training stream), with :data:`PERTURBED` counter-examples per example that
move one of its objects a little besides the Langevin ones; a relation that reads the subject's heading
(``facing``) is trained with round objects' headings visible (``round_invariant=False``), since a disk
can face something too.

A training run can end with a flat edge: the energy barely rises when the subject leaves the relation's
region (``aligned_y`` most often; docs/studies.md, "Composing relations").
In a sum of many energies such a relation is the first to give way, and sampling many particles and
keeping the best cannot tell. So each model is judged on :data:`VALIDATION` further examples of its
training stream, never trained on (:func:`edge`: the subject moved :data:`EDGE_MOVE` in
:data:`DIRECTIONS` directions; of the moves the relation's checker rejects, the share the energy ranks
above the example). A model that ranks fewer than :data:`SHARP` of them worse is trained again with the
seed of the next ensemble member (:func:`~scenescore.models.ensemble.member_seed`), at most
:data:`RESTARTS` times; the first sharp one is kept, else the sharpest.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Any

import numpy as np
import torch

from ..costs import Relation
from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..models import ScoreModel
from ..models.ensemble import member_seed
from ..problem.problem import Problem
from ..scenarios import get
from ..scenarios.relations import RELATIONS
from ..scene.scene import Scene, SceneError

__all__ = [
    "EXAMPLES",
    "PERTURBED",
    "VALIDATION",
    "EDGE_MOVE",
    "DIRECTIONS",
    "SHARP",
    "RESTARTS",
    "Edge",
    "train_config",
    "relation_training",
    "validation_examples",
    "edge",
    "train_relation",
    "train_relations",
]

PERTURBED = 8  # counter-examples per example that move one object of it a little (sharper edges)
EXAMPLES = 2048  # example scenes each relation model learns from
VALIDATION = 100  # further examples of the training stream each model's edge is judged on
EDGE_MOVE = 0.015  # metres the subject moves off a validation example to test the edge
DIRECTIONS = 16  # directions of each move, evenly spaced
SHARP = 0.85  # the share of the checker-rejected moves a kept model must rank worse than the example
RESTARTS = 3  # trainings with the next member seeds at most, when the edge is flat


@dataclass(frozen=True)
class Edge:
    """A model's edge at one move length: ``broken`` moves the checker rejects, the share ``worse`` of them
    the energy ranks above the example, and their mean energy ``rise`` over it (NaN when none broke)."""

    move: float
    broken: int
    worse: float
    rise: float


def train_config(iterations: int | None = None, quick: bool = False) -> TrainConfig:
    """The relation models' (and the whole-scene energy's) training settings: the trainer's defaults in
    one network (``ONE_NETWORK``), ``iterations`` (default 600; 100 with ``quick``) and
    :data:`PERTURBED` counter-examples per example that move one of its objects a little, which sharpen
    the energy at the edge of a relation's region."""
    return TrainConfig(iterations=iterations or (100 if quick else 600), perturbed=PERTURBED, **ONE_NETWORK)


def relation_training(
    relation: str, seed: int, config: TrainConfig, examples: int = EXAMPLES
) -> tuple[list[Scene], TrainConfig]:
    """What the model of ``relation`` (``left_of``, ...) learns from: ``examples`` scenes of its scenario's
    training stream for ``seed`` (``relation-<name>``), and ``config`` with round objects' headings
    visible where the relation reads the subject's heading. The experiment's models and the shipped
    ones (``scripts/pretrain.py``) train on these."""
    if relation not in RELATIONS:
        raise SceneError(f"no relation {relation!r}; relations: {', '.join(RELATIONS)}")
    scenes = get(f"relation-{relation}", n_train=examples).split(seed)[0]
    return scenes, replace(config, round_invariant=False) if RELATIONS[relation].reads_heading else config


def validation_examples(relation: str, seed: int, examples: int, count: int = VALIDATION) -> list[Scene]:
    """The ``count`` examples of ``relation``'s training stream for ``seed`` that follow the ``examples``
    a model trains on: the same generator and stream (:func:`relation_training`'s), never trained on."""
    return relation_training(relation, seed, TrainConfig(**ONE_NETWORK), examples + count)[0][examples:]


def edge(model: ScoreModel, relation: str, examples: Sequence[Scene], moves: Sequence[float]) -> list[Edge]:
    """Per move length of ``moves`` (metres): each example with its subject moved that far in
    :data:`DIRECTIONS` directions, judged by the relation's checker and ranked by ``model``'s energy."""
    scenario = get(f"relation-{relation}")
    angles = np.arange(DIRECTIONS) * (2 * math.pi / DIRECTIONS)
    dist = np.repeat(np.asarray(moves, dtype=float), DIRECTIONS)  # each length, its directions in turn
    shift = dist[:, None] * np.tile(np.column_stack([np.cos(angles), np.sin(angles)]), (len(moves), 1))
    rises: dict[float, list[float]] = {float(d): [] for d in moves}
    for ex in examples:
        scene = Scene([ex[n] for n in scenario.roles], ex.bounds)  # the term adds the axes marker itself
        prob = Problem(scene, Relation(model, objects=[scenario.roles]))
        poses = np.repeat(np.array([o.pose for o in scene.objects], dtype=float)[None], len(dist) + 1, 0)
        poses[1:, 0, :2] += shift  # row 0: the example; then the subject moved
        with torch.no_grad():
            e = prob.evaluate(torch.as_tensor(poses)).cpu().numpy()
        for d, p, ek in zip(dist, poses[1:], e[1:]):
            if not scenario.check(scene.with_poses(p)):
                rises[float(d)].append(float(ek - e[0]))
    return [
        Edge(
            d,
            len(r),
            float(np.mean(np.array(r) > 0)) if r else math.nan,
            float(np.mean(r)) if r else math.nan,
        )
        for d, r in rises.items()
    ]


def train_relation(
    relation: str,
    seed: int,
    config: TrainConfig,
    device: Any = None,
    cache: Any = None,
    progress: bool = False,
    examples: int = EXAMPLES,
    log: Callable[[str], None] | None = None,
    restarts: int = RESTARTS,
) -> ScoreModel:
    """``relation``'s model for ``seed``: trained on :func:`relation_training`'s scenes and settings, and
    trained again with the next member seeds (at most ``restarts`` times) while its :func:`edge` on
    :func:`validation_examples` ranks fewer than :data:`SHARP` of the broken moves worse; the first sharp
    model, else the sharpest. ``cache``: a model cache folder (:mod:`scenescore.learn.cache`); ``log``: told
    of each flat model trained again."""
    stream, cfg = relation_training(relation, seed, config, examples + VALIDATION)
    scenes, held = stream[:examples], stream[examples:]  # held: validation_examples(relation, seed, examples)
    best: tuple[float, ScoreModel] | None = None
    for m in range(restarts + 1):
        model = fit(
            scenes, cfg, seed=member_seed(seed, m), progress=progress, device=device, run=Run(cache=cache)
        )
        worse = edge(model, relation, held, [EDGE_MOVE])[0].worse
        worse = 1.0 if math.isnan(worse) else worse
        if best is None or worse > best[0]:
            best = (worse, model)
        if worse >= SHARP:
            break
        if log is not None and m < restarts:
            log(
                f"{relation} (trained with seed {member_seed(seed, m)}): its edge is flat ({worse:.2f} of "
                f"the moves {EDGE_MOVE * 100:g} cm off the relation ranked worse, below {SHARP}); training "
                f"again with seed {member_seed(seed, m + 1)}"
            )
    assert best is not None
    return best[1]


def train_relations(
    relations: Sequence[str],
    seed: int,
    config: TrainConfig,
    device: Any = None,
    cache: Any = None,
    progress: bool = False,
    examples: int = EXAMPLES,
    log: Callable[[str], None] | None = None,
    restarts: int = RESTARTS,
) -> dict[str, ScoreModel]:
    """One model per relation (:func:`train_relation`)."""
    run = (device, cache, progress, examples, log, restarts)
    return {r: train_relation(r, seed, config, *run) for r in relations}
