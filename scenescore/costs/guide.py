"""Guides: cost terms that also have an opinion on candidate poses, beyond their value.

A term that subclasses :class:`Guide` beside :class:`~scenescore.costs.base.Cost` may *propose*
candidate poses (solvers screen them beside uniform draws), *doubt* pose sets (solvers that are asked
to rank the doubted ones after the others do so before they rank by cost), and give each moving
object a *verdict* (a confidence and the reasons to doubt it, reported with every result), and name
the *rivals* of an answer among the other answers a sampling solver found (:class:`Alternatives`:
another place, far off, that costs nearly as little). Each method's default says nothing, so a guide
overrides only what it knows.

Solvers and problems ask a whole cost through the functions of this module (:func:`propose`,
:func:`doubts`, :func:`verdicts`, :func:`doubt_note`), which ask the sum's guiding terms in order;
they need not know what a guide bases its opinion on. The learned energy
(:class:`~scenescore.costs.energy.LearnedEnergy`) is a guide by its model's trust reference: the
poses its training data has.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any, Protocol

import numpy as np
import torch
from torch import Tensor

from .base import Sum

__all__ = ["Guide", "Verdict", "Alternatives", "guides", "propose", "doubts", "verdicts", "doubt_note"]


class Verdict(Protocol):
    """A guide's verdict on one moving object: a confidence in [0, 1] and the reasons to doubt the
    object's pose (none: nothing to doubt)."""

    confidence: float
    flags: list[str]

    def to_dict(self) -> dict[str, Any]:
        """``{"confidence": ..., "flags": [...]}`` for a result's JSON."""
        ...


@dataclass(frozen=True)
class Alternatives:
    """The other answers a sampling solver found: pose sets ``poses (B, N, 3)`` that satisfy the
    constraints and that no guide doubts, and their ``margins (B,)``: each one's cost minus the
    answer's (the objective's units)."""

    poses: np.ndarray
    margins: np.ndarray


class Guide:
    """A cost term's opinion on candidate poses; mixed into a :class:`~scenescore.costs.base.Cost`."""

    #: what a doubted row does, completing "<k> of <B> particles ..." in a solver's message
    doubt_note: str = "are doubted by a term of the cost"

    def propose(self, x: Tensor, generator: torch.Generator) -> Tensor | None:
        """Candidate poses: ``x (B, N, 3)`` with some moving objects put where this term expects them,
        drawn by ``generator``; None: no proposal."""
        return None

    def doubts(self, poses: Tensor) -> Tensor | None:
        """The rows of ``poses (B, N, 3)`` this term doubts, ``(B,)`` bool; None: no opinion."""
        return None

    def verdicts(self, poses: np.ndarray) -> Mapping[str, Verdict]:
        """A verdict on each moving object this term judges at one pose set ``(N, 3)``, by name."""
        return {}

    def rivals(self, poses: np.ndarray, alternatives: Alternatives) -> Mapping[str, str]:
        """Why to doubt moving objects of the answer ``poses (N, 3)`` given the ``alternatives``: a
        reason by object name (an object this term gives a verdict on); {}: none."""
        return {}

    def doubted(self, poses: np.ndarray, flagged: Mapping[str, Verdict]) -> Mapping[str, str]:
        """For the flagged moving objects at ``poses (N, 3)`` (``flagged``: their verdicts, by name): the
        reason this term holds each one where it is, said as the flag to add (``relation: ...``); {}:
        nothing to say."""
        return {}


def guides(cost: Sum) -> list[Guide]:
    """The terms of ``cost`` that are guides, in the sum's order."""
    return [c for _, c in cost if isinstance(c, Guide)]


def propose(cost: Sum, x: Tensor, generator: torch.Generator) -> Tensor | None:
    """Candidates for ``x (B, N, 3)``: each guide in turn proposes from the one before's proposal (the
    first from ``x``); None when no guide proposes."""
    out = None
    for g in guides(cost):
        y = g.propose(x if out is None else out, generator)
        out = y if y is not None else out
    return out


def doubts(cost: Sum, poses: Tensor) -> Tensor | None:
    """The rows ``(B,)`` that any guide of ``cost`` doubts; None when no guide has an opinion."""
    flags = [d for g in guides(cost) if (d := g.doubts(poses)) is not None]
    if not flags:
        return None
    return torch.stack(flags, dim=-1).any(-1)


def verdicts(cost: Sum, poses: np.ndarray, alternatives: Alternatives | None = None) -> dict[str, Verdict]:
    """Every guide's verdicts at one pose set ``(N, 3)``, by object name (a later guide's verdict on
    an object replaces an earlier one's); with ``alternatives``, each guide's rivals added to the flags
    of the objects it gives verdicts on; a flagged object's flags end with the relation its guide
    doubts (:meth:`Guide.doubted`)."""
    out: dict[str, Verdict] = {}
    for g in guides(cost):
        mine = dict(g.verdicts(poses))
        if alternatives is not None and len(alternatives.margins) and mine:
            for name, reason in g.rivals(poses, alternatives).items():
                if name in mine:
                    mine[name].flags.append(reason)
        flagged = {name: v for name, v in mine.items() if v.flags}
        for name, reason in (g.doubted(poses, flagged) if flagged else {}).items():
            mine[name].flags.append(reason)
        out.update(mine)
    return out


def doubt_note(cost: Sum) -> str:
    """What a row that ``cost``'s guides doubt does, for a solver's message (see :attr:`Guide.doubt_note`)."""
    notes = list(dict.fromkeys(g.doubt_note for g in guides(cost)))
    return " or ".join(notes) if notes else Guide.doubt_note
