"""Learning the energy from example arrangements: :func:`fit`, the training alone.

- ``config.py``: :class:`TrainConfig` (with the network's :class:`NetworkConfig`) and :func:`derive`, the
  one place where the settings the data decides are worked out;
- ``data.py``: the checks on the example scenes, their scale, the held-out split;
- ``negatives.py``: the counter-examples (persistent Langevin chains, perturbed, re-anchored);
- ``losses.py``: InfoNCE and the regularisers, the held-out loss;
- ``size_groups.py``: a batch's energies in groups of similar object counts;
- ``loop.py``: :func:`fit`; ``run.py``: :class:`Run`, how it runs (its log, cache and resumable state);
  ``members.py``: an ensemble's members, trained one after another or side by side in worker
  processes; ``cache.py``: the model cache; ``training_state.py``: the state a run writes every so
  often, that a killed run resumes from; ``logs.py``: TensorBoard logs.

What ``scenescore train`` does around the training (hold scenes out, evaluate, calibrate tidying,
save) is :func:`scenescore.train`, in :mod:`scenescore.workflow`.
"""

from .config import ONE_NETWORK, RAW_EDGES, NetworkConfig, TrainConfig, derive
from .data import VALIDATION_FRACTION, check_training_data, split_validation
from .loop import fit
from .losses import heldout_loss
from .run import Run
from .training_state import StateError

__all__ = [
    "ONE_NETWORK",
    "RAW_EDGES",
    "NetworkConfig",
    "Run",
    "StateError",
    "TrainConfig",
    "VALIDATION_FRACTION",
    "check_training_data",
    "derive",
    "fit",
    "heldout_loss",
    "split_validation",
]
