"""Energy models: the SceneScore network, batching, trained models, checkpoints and the CasADi export."""

from .batching import SceneTensors, batch_scenes
from .checkpoint import FORMAT_VERSION, CheckpointError
from .info import ModelInfo, TidyCalibration
from .model import ScoreModel, load
from .network import EnergyConfig, EnergyNet, edge_features

__all__ = [
    "EnergyConfig",
    "EnergyNet",
    "edge_features",
    "CheckpointError",
    "FORMAT_VERSION",
    "ModelInfo",
    "TidyCalibration",
    "ScoreModel",
    "SceneTensors",
    "batch_scenes",
    "load",
]
