"""How a training runs, apart from its data, its settings and its seed (:class:`Run`): where it logs,
where it keeps the model and its state, where it starts from, and how many worker processes an
ensemble's members train in."""

from __future__ import annotations

import os
from dataclasses import dataclass

from ..errors import ConfigError, check_number
from ..models import ScoreModel
from .training_state import SAVE_EVERY
from .warm_start import Start

__all__ = ["Run"]


@dataclass(frozen=True)
class Run:
    """How :func:`~scenescore.learn.fit` runs (every field has a default that asks for nothing).

    ``log_dir``: a TensorBoard log there, every iteration's loss (``train/loss``, the InfoNCE loss with
    its regularisers; ``train/infonce`` alone) and learning rate (``train/lr``).
    ``cache``: a folder where the model is kept, and loaded from instead of trained when the same
    training ran before (:mod:`scenescore.learn.cache`; not with an encoder given or a ``log_dir``).
    ``state``: a file where the run writes where it stands every ``save_every`` iterations and at its
    end (weights, optimiser, averaged weights, chains, random streams, iteration), so that a killed run
    can go on; ``resume``: go on from that file when it exists, to the model an uninterrupted run with
    this seed trains, bit for bit on the CPU (a state of other scenes, settings, encoder, seed or device
    is refused with a :class:`~scenescore.learn.training_state.StateError` naming the file). The file
    is removed once training ends, unless ``keep_state``.
    ``jobs``: with ``members`` of 2 or more, the worker processes the members train in, side by side,
    the ensemble the same whatever their number (None: one per usable core). Spawned workers import the
    calling script again, so a script that trains with ``jobs`` above 1 keeps its work under
    ``if __name__ == "__main__":``.
    ``init``: a model whose weights the run starts from instead of random ones (a prior fine-tuned on
    the data, :mod:`scenescore.learn.warm_start`; kept as its :class:`~scenescore.learn.warm_start.Start`,
    :attr:`start`): its architecture and encoder must be the training's, and the new model takes its
    own data's length scale, walls and graph. Every member of an ensemble, and every fold of a
    cross-validation, starts from it.
    """

    log_dir: str | os.PathLike | None = None
    cache: str | os.PathLike | None = None
    state: str | os.PathLike | None = None
    resume: bool = False
    save_every: int = SAVE_EVERY
    keep_state: bool = False
    jobs: int | None = 1
    init: ScoreModel | Start | None = None

    def __post_init__(self) -> None:
        if isinstance(self.init, ScoreModel):  # its weights, copied: a run holds no module
            object.__setattr__(self, "init", Start.of(self.init))
        elif self.init is not None and not isinstance(self.init, Start):
            raise ConfigError(
                f"train: init: expected a ScoreModel to start from, got {type(self.init).__name__}"
            )
        check_number("train", "save_every", self.save_every, 1, integer=True)
        if self.resume and self.state is None:
            raise ConfigError("train: resume=True needs the state file to resume from (state=...)")
        if self.jobs is not None and (
            isinstance(self.jobs, bool) or not isinstance(self.jobs, int) or self.jobs < 1
        ):
            raise ConfigError(
                f"train: jobs: expected a whole number of worker processes, 1 or more, got {self.jobs!r}"
            )

    @property
    def start(self) -> Start | None:
        """The weights the run starts from (:attr:`init`'s), None for the seed's."""
        return self.init if isinstance(self.init, Start) else None
