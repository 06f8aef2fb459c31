"""An arrangement prior: one energy trained on the bundled table tops together, to start a training on a
handful of a user's own scenes from (``scenescore train --init``, :mod:`scenescore.learn.warm_start`).

Each dataset is put at unit length scale (:func:`~scenescore.learn.warm_start.at_unit_scale`) before
they are pooled, so that circuit boards and banquet halls teach the network relations in one scale:
beside, in a row, evenly spaced, around, on either side. The rooms (local graphs) are not in it. An
experiment that tests the prior on a zoo scenario trains one without that scenario (``without``).
"""

from __future__ import annotations

from collections.abc import Iterable

from ..errors import ConfigError
from ..learn import ONE_NETWORK, Run, TrainConfig, fit
from ..learn.warm_start import at_unit_scale
from ..models import ScoreModel
from ..scenarios import get
from ..scenarios.zoo import ROOMS, ZOO
from ..scene.scene import Scene

__all__ = ["PRIOR_DATASETS", "prior_scenes", "train_prior"]

#: the datasets a prior is trained on: every zoo table top and three of the paper's scenarios (the
#: ordering row's cutlery is Table 2's test of unseen objects, left out of it)
PRIOR_DATASETS: tuple[str, ...] = (*(n for n in ZOO if n not in ROOMS), "dining", "desk", "tv")


def prior_scenes(without: Iterable[str] = (), seed: int = 0) -> list[Scene]:
    """The training scenes (``split(seed)``'s) of every :data:`PRIOR_DATASETS` dataset but ``without``,
    each dataset at unit length scale, pooled in that order."""
    left = set(without)
    unknown = left - set(PRIOR_DATASETS)
    if unknown:
        raise ConfigError(
            f"prior: without: not a dataset of the prior: {', '.join(sorted(unknown))} (its datasets: "
            f"{', '.join(PRIOR_DATASETS)})"
        )
    return [s for n in PRIOR_DATASETS if n not in left for s in at_unit_scale(get(n).split(seed)[0])]


def train_prior(
    without: Iterable[str] = (),
    seed: int = 0,
    progress: bool = True,
    run: Run | None = None,
    config: TrainConfig | None = None,
) -> ScoreModel:
    """The prior of :func:`prior_scenes` (``without`` those datasets), trained with ``config`` (default
    the defaults in one network, ``ONE_NETWORK``) and ``seed``."""
    cfg = config or TrainConfig(**ONE_NETWORK)
    return fit(prior_scenes(without, seed), cfg, seed=seed, progress=progress, run=run)
