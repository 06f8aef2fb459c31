"""A user-written guide: solvers ask any cost term that is a Guide, through the general hook only."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
import torch
from torch import Tensor

import scenescore as ss
from scenescore.costs import Guide, PoseTarget
from scenescore.costs.guide import doubts, guides, propose, verdicts


@dataclass
class Opinion:
    confidence: float
    flags: list[str] = field(default_factory=list)

    def to_dict(self) -> dict[str, Any]:
        return {"confidence": self.confidence, "flags": list(self.flags)}


class LeftPreferred(PoseTarget, Guide):
    """A target that doubts ``obj`` right of x = 0, proposes it at x = -0.5, and judges it by side."""

    doubt_note = "put the object right of x = 0"

    def index(self) -> int:
        return self.binding.scene.index(self.obj)

    def propose(self, x: Tensor, generator: torch.Generator) -> Tensor | None:
        out = x.clone()
        out[:, self.index(), 0] = -0.5
        return out

    def doubts(self, poses: Tensor) -> Tensor | None:
        return poses[:, self.index(), 0] > 0

    def verdicts(self, poses: np.ndarray) -> dict[str, Opinion]:
        right = float(poses[self.index(), 0]) > 0
        return {self.obj: Opinion(0.0 if right else 1.0, ["right of x = 0"] if right else [])}


def _problem(guided: bool = True) -> ss.Problem:
    scene = ss.Scene(
        [
            ss.SceneObject("a_0", "a", (0.1, 0.1), (0.0, 0.5, 0.0)),
            ss.SceneObject("b_0", "b", (0.1, 0.1), None),
        ],
        ((-1.0, -1.0), (1.0, 1.0)),
    )
    target = LeftPreferred("b_0", (0.8, -0.8)) if guided else PoseTarget("b_0", (0.8, -0.8))
    return ss.Problem(scene, target + 0.0 * ss.costs.Bounds())


def test_only_guiding_terms_are_asked():
    p, plain = _problem(), _problem(guided=False)
    assert [type(g).__name__ for g in guides(p.cost)] == ["LeftPreferred"]
    assert guides(plain.cost) == [] and doubts(plain.cost, plain.initial(4, torch.Generator())) is None
    assert propose(plain.cost, plain.initial(4, torch.Generator()), torch.Generator()) is None
    assert verdicts(plain.cost, plain.scene.poses()) == {}


def test_proposals_come_from_the_guide_and_the_rest_stay_uniform():
    p = _problem()
    gen = lambda: torch.Generator().manual_seed(0)  # noqa: E731
    x, uniform = p.initial(8, gen(), proposals=0.5), p.initial(8, gen())
    assert torch.all(x[:4, 1, 0] == -0.5) and torch.equal(x[4:], uniform[4:])


def test_trusted_first_ranks_the_doubted_particles_last_and_the_verdict_reaches_the_result():
    p = _problem()
    opts = {"particles": 16, "steps": 10, "proposals": 0.5}
    plain = ss.solve(p, "langevin", seed=0, options={"langevin": opts})
    first = ss.solve(p, "langevin", seed=0, options={"langevin": {**opts, "trusted_first": True}})
    assert plain.poses[1, 0] > 0 and plain.confidence["b_0"].flags == ["right of x = 0"]
    assert first.poses[1, 0] <= 0 and first.confidence["b_0"].confidence == 1.0
    doubted = p.doubted(torch.as_tensor(first.samples))
    assert f"{int(doubted.sum())} of 16 particles put the object right of x = 0" in first.message
    assert first.to_dict()["confidence"]["b_0"] == {"confidence": 1.0, "flags": []}
