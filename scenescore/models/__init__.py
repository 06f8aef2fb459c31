"""Energy models: the SceneScore network, trained models and their checkpoints."""

from .energy import EnergyConfig, EnergyNet, edge_features
from .score import FORMAT_VERSION, CheckpointError, SceneTensors, ScoreModel, batch_scenes, load

__all__ = [
    "EnergyConfig",
    "EnergyNet",
    "edge_features",
    "CheckpointError",
    "FORMAT_VERSION",
    "ScoreModel",
    "SceneTensors",
    "batch_scenes",
    "load",
]
