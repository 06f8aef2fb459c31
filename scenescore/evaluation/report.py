"""The leave-one-object-out report (:func:`evaluate`): the table ``scenescore train`` prints on its
held-out scenes and ``scenescore evaluate`` on any labelled set, each category's errors beside nearest
neighbour's.

The ``*_cm`` figures are 100 times the data's lengths (cm for the built-in scenarios' metres);
:meth:`EvalReport.table` prints them in the unit the data names (:mod:`scenescore.scene.units`).
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import asdict, dataclass, field
from typing import Any

import numpy as np

from ..models.info import Caveats
from ..models.trust import CAVEAT
from ..scene.scene import Scene, SceneError
from ..scene.units import ShownUnit, declared_unit
from .cases import MissingCase, case_errors, leave_one_out

__all__ = ["CategoryErrors", "EvalReport", "evaluate"]


@dataclass
class CategoryErrors:
    """Leave-one-object-out errors of one category: SceneScore's and the nearest-neighbour baseline's."""

    category: str
    placements: int
    t_cm: float
    R_deg: float | None
    baseline_t_cm: float | None = None
    baseline_R_deg: float | None = None
    baseline_missed: int = 0  # cases the baseline could not fill (no training scene had the objects)


@dataclass
class EvalReport:
    """:func:`evaluate`'s figures: per category, the means, the held-out InfoNCE loss."""

    categories: list[CategoryErrors]
    scenes: int
    placements: int
    mean_t_cm: float
    mean_R_deg: float | None
    heldout_loss: float
    chance_loss: float
    seed: int
    baseline: str | None = None  # the baseline's name, when it ran
    flagged: int = 0  # placements flagged as out of distribution
    unit: str | None = None  # the length unit the scenes name (``meta.unit``), None when they name none
    folds: int | None = None  # cross-validation's folds pooled here (None: one set of held-out scenes)
    examples: list[tuple[MissingCase, Scene]] = field(default_factory=list, repr=False)  # a few, for plots

    @property
    def cross_validation(self) -> str:
        """How the folds pooled here held scenes out, in words ("" for one set of held-out scenes)."""
        if not self.folds:
            return ""
        return "leave one scene out" if self.folds == self.scenes else f"{self.folds}-fold cross-validation"

    def table(self) -> str:
        """The report as aligned text, lengths in the unit the data names (:class:`~scenescore.scene.units.ShownUnit`)."""
        shown = ShownUnit(self.unit)
        places = shown.decimals(self.mean_t_cm)

        def f(v: float | None) -> str:
            return "-" if v is None or not math.isfinite(v) else f"{v:.2f}"

        def t(v: float | None) -> str:
            return "-" if v is None or not math.isfinite(v) else f"{shown.value(v):.{places}f}"

        t_head = f"t ({shown.label})"
        w = max(8, len(t_head))
        head = f"{'category':16s} {'n':>4s} {t_head:>{w}s} {'R (deg)':>8s}"
        if self.baseline:
            head += f"   {'NN t':>{w}s} {'NN R':>8s}"
        lines = [head]
        for c in self.categories:
            line = f"{c.category:16s} {c.placements:4d} {t(c.t_cm):>{w}s} {f(c.R_deg):>8s}"
            if self.baseline:
                line += f"   {t(c.baseline_t_cm):>{w}s} {f(c.baseline_R_deg):>8s}"
                if c.baseline_missed:
                    line += f"  ({c.baseline_missed} not filled)"
            lines.append(line)
        mean = f"{'mean':16s} {self.placements:4d} {t(self.mean_t_cm):>{w}s} {f(self.mean_R_deg):>8s}"
        lines.append(mean)
        note = shown.note()
        if note is not None:
            lines.append(note)
        lines.append(
            f"held-out InfoNCE loss {self.heldout_loss:.3f} (chance {self.chance_loss:.3f}); "
            + (f"{self.cross_validation}, " if self.folds else "")
            + f"{self.scenes} scenes, {self.placements} placements, {self.flagged} flagged out of distribution"
            + (f"; NN = {self.baseline}" if self.baseline else "")
        )
        return "\n".join(lines)

    def _above_chance(self) -> bool:
        """Whether the held-out loss is not below chance."""
        return not self.heldout_loss < self.chance_loss

    def _one_scene_out(self) -> bool:
        """Whether the folds left one scene out at a time: each fold's model saw a few scenes, whose
        own modes its counter-examples find, so its held-out loss is above chance as often for a model
        that places well as for one that does not (docs/studies.md, "Trained as a user trains")."""
        return bool(self.folds) and self.folds == self.scenes

    def _no_better(self) -> dict[str, str]:
        """Each category placed no better than the nearest-neighbour baseline, with the figures."""
        shown = ShownUnit(self.unit)
        places = shown.decimals(self.mean_t_cm)
        out = {}
        for c in self.categories:
            b = c.baseline_t_cm
            if b is not None and math.isfinite(b) and not c.t_cm < b:
                mine, theirs = shown.value(c.t_cm), shown.value(b)
                out[c.category] = (
                    f"{c.category}: held-out error {mine:.{places}f} {shown.words}, no better than nearest "
                    f"neighbour's {theirs:.{places}f} {shown.words}"
                )
        return out

    def warnings(self) -> list[str]:
        """What the figures say the model has not learned: a held-out loss not below chance (the model
        tells held-out arrangements from counter-examples no better than a constant energy), and each
        category placed no better than the nearest-neighbour baseline."""
        out = []
        if self._above_chance():
            out.append(
                f"the held-out InfoNCE loss ({self.heldout_loss:.3f}) is not below chance "
                f"({self.chance_loss:.3f}): the model does not tell held-out arrangements from "
                "counter-examples; train on more scenes or for more iterations, or check that the held-out "
                "scenes follow the same rules"
                + (
                    " (with one scene left out at a time this says little about placements, which do not "
                    "carry it: the categories' errors beside nearest neighbour's do)"
                    if self._one_scene_out()
                    else ""
                )
            )
        return out + list(self._no_better().values())

    def caveats(self) -> Caveats | None:
        """What placements from the model say in their flags (:meth:`warnings`, in short), None when the
        figures find nothing unlearned. A held-out loss not below chance is none when one scene was
        left out at a time (:meth:`_one_scene_out`)."""
        model = []
        if self._above_chance() and not self._one_scene_out():
            model.append(
                f"the model's held-out InfoNCE loss ({self.heldout_loss:.3f}) was not below chance "
                f"({self.chance_loss:.3f}): it may not have learned the data's arrangements"
            )
        cats = self._no_better()
        return Caveats(model, cats) if model or cats else None

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d.pop("examples")
        d["warnings"] = self.warnings()
        return d


def evaluate(
    model: Any,
    scenes: Sequence[Scene],
    train_scenes: Sequence[Scene] | None = None,
    objects: Sequence[str] | None = None,
    seed: int = 0,
    progress: bool = False,
    per_category: int | None = None,
) -> EvalReport:
    """Place every movable object of ``scenes`` back in turn (or only ``objects``) and tabulate the errors
    per category, beside the nearest-neighbour baseline fitted on ``train_scenes`` when given, with the
    held-out InfoNCE loss; ``per_category``: at most that many placements of each category
    (:func:`~scenescore.evaluation.cases.leave_one_out`). Deterministic in ``seed``: ``scenescore train`` and ``scenescore evaluate``
    print the same figures for the same scenes. Lengths are printed in the unit the scenes name
    (:func:`~scenescore.scene.units.declared_unit`); flags of the model's own caveats (``info.caveats``) do not
    count as out of distribution."""
    from ..learn import heldout_loss
    from ..planning.placement import SceneScorePlacer
    from .baselines import NearestNeighbour

    unit = declared_unit([*scenes, *(train_scenes or [])])
    cases = leave_one_out(scenes, objects, per_category)
    if not cases:
        raise SceneError("evaluate: no object to place (every object is fixed, unknown or not named)")
    # the report counts flagged placements: naming the relation each one doubts (an explanation over
    # the whole scene per flagged placement) would change no figure of it
    placer = SceneScorePlacer(progress=progress, relations=False)
    placer.model = model
    pred = placer.predict([c.scene for c in cases], seed=seed)
    base = None
    if train_scenes:
        # the baseline never remembers a scene it is asked about (so --train-data may hold them too)
        asked = {json.dumps(s.to_dict(), sort_keys=True) for s in scenes}
        memory = [s for s in train_scenes if json.dumps(s.to_dict(), sort_keys=True) not in asked]
        base = NearestNeighbour().fit(memory).predict([c.scene for c in cases])
    cats: dict[str, list[int]] = {}
    for k, c in enumerate(cases):
        cats.setdefault(c.category, []).append(k)
    rows = []

    def errs(k: int, p: Scene) -> tuple[float, float | None]:
        c, pose = cases[k], p[cases[k].name].pose
        if pose is None:
            return math.nan, None
        return case_errors(c, pose, c.scene[c.name].round)

    for cat, ks in cats.items():
        ours = [errs(k, pred[k]) for k in ks]
        row = CategoryErrors(cat, len(ks), float(np.mean([t for t, _ in ours])), _mean([r for _, r in ours]))
        if base is not None:
            theirs = [errs(k, base[k]) for k in ks]
            filled = [(t, r) for t, r in theirs if math.isfinite(t)]
            row.baseline_t_cm = float(np.mean([t for t, _ in filled])) if filled else None
            row.baseline_R_deg = _mean([r for _, r in filled])
            row.baseline_missed = len(theirs) - len(filled)
        rows.append(row)
    loss, chance = heldout_loss(model, scenes, seed=seed)
    flagged = sum(_out_of_distribution(p, c.name) for c, p in zip(cases, pred))
    return EvalReport(
        categories=rows,
        scenes=len(scenes),
        placements=len(cases),
        mean_t_cm=float(np.mean([r.t_cm for r in rows])),
        mean_R_deg=_mean([r.R_deg for r in rows]),
        heldout_loss=loss,
        chance_loss=chance,
        seed=seed,
        baseline="Nearest-Nbr" if base is not None else None,
        flagged=flagged,
        unit=unit,
        examples=[(cases[k], pred[k]) for k in range(0, len(cases), max(1, len(cases) // 3))][:3],
    )


def _out_of_distribution(placed: Scene, name: str) -> bool:
    """Whether the placement of ``name`` in ``placed`` is flagged for a reason other than a caveat of the
    model's (those hold for every placement the caveat names, wherever it lands)."""
    flags = placed.meta.get("placement", {}).get(name, {}).get("flags", [])
    return any(not f.startswith(CAVEAT) for f in flags)


def _mean(values: Sequence[float | None]) -> float | None:
    v = [x for x in values if x is not None]
    return float(np.mean(v)) if v else None
