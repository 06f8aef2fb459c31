"""Learning the energy from example arrangements.

- ``config.py``: :class:`TrainConfig` (with the network's :class:`NetworkConfig`) and :func:`derive`, the
  one place where the settings the data decides are worked out;
- ``data.py``: the checks on the example scenes, their scale, the held-out split;
- ``negatives.py``: the counter-examples (persistent Langevin chains, perturbed, re-anchored);
- ``losses.py``: InfoNCE and the regularisers, the held-out loss;
- ``size_groups.py``: a batch's energies in groups of similar object counts;
- ``loop.py``: :func:`train`, the training alone; ``members.py``: an ensemble's members, trained one
  after another or side by side in worker processes; ``cache.py``: the model cache it may use;
  ``training_state.py``: the state it writes every so often, that a killed run resumes from;
- ``logs.py``: TensorBoard logs;
- ``workflow.py``: :func:`~scenescore.workflow.train.train_model` (``ss.train``), what
  ``scenescore train`` does: hold scenes out, train, evaluate, calibrate tidying, report, save (not
  imported here: it sits above the evaluation and the tidy planner, which import this package).
"""

from .config import LOCAL_FROM, LR_DENSE, LR_LOCAL, RAW_EDGES, Derived, NetworkConfig, TrainConfig, derive
from .data import (
    VALIDATION_FRACTION,
    check_training_data,
    data_scale,
    local_radius,
    split_validation,
    stands_against_walls,
)
from .logs import log_validation, require_tensorboard, summary_writer
from .loop import train
from .losses import heldout_loss, infonce_loss
from .negatives import ChainBuffer, perturbed_negatives, reanchored_negatives
from .training_state import SAVE_EVERY, StateError

__all__ = [
    "TrainConfig",
    "NetworkConfig",
    "RAW_EDGES",
    "Derived",
    "derive",
    "train",
    "infonce_loss",
    "heldout_loss",
    "perturbed_negatives",
    "reanchored_negatives",
    "ChainBuffer",
    "data_scale",
    "local_radius",
    "LOCAL_FROM",
    "LR_DENSE",
    "LR_LOCAL",
    "stands_against_walls",
    "check_training_data",
    "split_validation",
    "VALIDATION_FRACTION",
    "require_tensorboard",
    "summary_writer",
    "log_validation",
    "StateError",
    "SAVE_EVERY",
]
