"""Energy models: the SceneScore network, batching, trained models, checkpoints, the models the package
ships (:func:`pretrained`) and the CasADi export."""

from .architecture import EnergyConfig
from .batching import SceneTensors, batch_scenes
from .bundled import pretrained, pretrained_index, pretrained_names
from .checkpoint import FORMAT_VERSION, CheckpointError
from .info import Caveats, ModelInfo, TidyCalibration
from .model import ScoreModel, load
from .network import EnergyNet, edge_features

__all__ = [
    "EnergyConfig",
    "EnergyNet",
    "edge_features",
    "CheckpointError",
    "FORMAT_VERSION",
    "ModelInfo",
    "Caveats",
    "TidyCalibration",
    "ScoreModel",
    "SceneTensors",
    "batch_scenes",
    "load",
    "pretrained",
    "pretrained_names",
    "pretrained_index",
]
