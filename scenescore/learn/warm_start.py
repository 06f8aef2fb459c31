"""Training that starts from another model's weights (``fit(..., run=Run(init=model))``, ``scenescore train
--init``): a prior trained on other arrangements, fine-tuned on a handful of the user's own.

The network reads lengths in its data's length scale and a footprint encoder's sizes in it too, so a
network's weights mean the same on data of any unit: the new model takes the data's own length scale,
walls and graph (:func:`~scenescore.learn.config.derive`), and only its weights start where the other
model's stand. The architecture (feature width, widths, layers, message, edge encoder) and the
encoder must match; a mismatch is refused naming the setting. :func:`at_unit_scale` puts scenes of
several datasets on one scale, so that one prior can be trained on them all.
"""

from __future__ import annotations

import hashlib
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass

import torch
from torch import Tensor

from ..encoders import Encoder
from ..errors import ConfigError
from ..models import ScoreModel
from ..models.architecture import EnergyConfig
from ..models.ensemble import members_of
from ..scene.scene import Scene
from .data import data_scale

__all__ = ["Start", "at_unit_scale", "ARCHITECTURE"]

#: the EnergyConfig fields that decide the network's weights' shapes and meaning; the others (length
#: scale, walls, graph, ranges) the new model takes from its own data
ARCHITECTURE = (
    "feat_dim",
    "embed_dim",
    "hidden",
    "edge_hidden",
    "layers",
    "message",
    "activation",
    "absolute",
    "edge_encoder",
)


@dataclass(frozen=True, eq=False)  # compared by identity: its weights are tensors
class Start:
    """The weights a training starts from (tensors on the CPU, by parameter name: no code), the config
    of the network they are of, its encoder's name, and how messages name where they came from."""

    weights: Mapping[str, Tensor]
    config: EnergyConfig
    encoder: str
    source: str

    @classmethod
    def of(cls, model: ScoreModel, source: str = "the initial model") -> Start:
        """Start from ``model``: its network's weights (an ensemble's member 0, the single model of its
        seed), copied to the CPU."""
        net = members_of(model.net)[0]
        weights = {k: v.detach().to("cpu", copy=True) for k, v in net.state_dict().items()}
        return cls(weights, net.cfg, model.encoder.name, source)

    def check(self, own: EnergyConfig, encoder: Encoder) -> None:
        """Refuse starting a network of ``own`` that encodes with ``encoder`` from these weights unless
        the two share their architecture and encoder, naming the first setting that differs."""
        if self.encoder != encoder.name:
            raise ConfigError(
                f"init: {self.source} encodes objects with the {self.encoder!r} encoder, this training "
                f"with {encoder.name!r}; train with the same encoder to start from it"
            )
        theirs, ours = asdict(self.config), asdict(own)
        for key in ARCHITECTURE:
            if theirs[key] != ours[key]:
                if key == "feat_dim":
                    raise ConfigError(
                        f"init: {self.source} reads features of width {theirs[key]}, this training's "
                        f"encoder gives {ours[key]}; train with the encoder it was trained with"
                    )
                where = "" if key == "edge_encoder" else "network."
                raise ConfigError(
                    f"init: {self.source}'s network has {key} = {theirs[key]!r}, this training's "
                    f"{ours[key]!r}; train with --set {where}{key}={theirs[key]} to start from it"
                )

    def digest(self) -> str:
        """A short hash of the weights: what names a training started from them in the model cache and
        in its resumable state."""
        h = hashlib.sha256()
        for name in sorted(self.weights):
            t = self.weights[name].detach().to("cpu", torch.float64).contiguous()
            h.update(name.encode())
            h.update(str(tuple(t.shape)).encode())
            h.update(t.numpy().tobytes())
        return h.hexdigest()[:24]


def at_unit_scale(scenes: Sequence[Scene]) -> list[Scene]:
    """``scenes`` with every length divided by their length scale (:func:`~scenescore.learn.data.data_scale`):
    one dataset's arrangements at the scale another's are put at, so that arrangements of circuit
    boards and of halls can train one prior."""
    length, _ = data_scale(scenes)
    return [s.scaled(1.0 / length) for s in scenes]
