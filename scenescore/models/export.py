"""ONNX export of a trained energy, for planners outside Python (a robot's C++ stack, onnxruntime).

The exported graph is the network after its pose-independent part: the energy of ``B`` arrangements of
one scene's ``N`` objects given the scene's node embeddings, computed once per scene.

``energy.onnx`` (from :func:`export_onnx`):

* ``poses (B, N, 3)`` float32: ``x, y`` in metres and ``theta`` in radians of every object the network
  sees, in the order of ``nodes``; for a model with walls (metadata ``walls`` is ``"true"``) the scene's
  own objects followed by the bounds' four sides, whose poses are :attr:`OnnxScene.extra_poses`;
* ``nodes (N, D)`` float32: the node embeddings, :func:`node_embeddings`, or ``embedding.onnx`` run on the
  encoder's features (metadata ``embed_dim`` is ``D``; an ensemble's members' side by side, metadata
  ``members`` saying how many);
* ``round (N,)`` bool: the round objects, whose headings the energy ignores; only a graph whose metadata
  has ``round_invariant`` ``"true"`` (every model trained since it exists) takes it;
* output ``energy (B,)`` float32, low for arrangements like the training examples (an ensemble's: its
  members' mean).

``B`` and ``N`` are dynamic. ``embedding.onnx`` (from :func:`export_embedding_onnx`) maps ``feats (N, F)``
(the encoder's vectors, :func:`scenescore.encoders.encode_scene`; walls are objects of category ``"wall"``)
and ``sizes (N, 2)`` (footprints in metres) to ``nodes (N, D)``. The graphs' ``metadata_props`` hold the
length scale, the input and output names, the encoder and the flags above. In Python,
``scene_inputs(model, scene).feeds(poses)`` builds the whole input of ``energy.onnx``.
"""

from __future__ import annotations

import copy
import json
import os
import tempfile
import warnings
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, cast

import numpy as np
import torch
from torch import Tensor, nn

from ..scene.outputs import atomic_write_bytes
from ..scene.scene import Scene, SceneError
from .ensemble import EnsembleNet, members_of
from .model import ScoreModel
from .network import WALLS, EnergyNet

__all__ = [
    "ENERGY_INPUTS",
    "EMBEDDING_INPUTS",
    "EXPORT_EXTRA",
    "OnnxScene",
    "export_embedding_onnx",
    "energy_inputs",
    "export_onnx",
    "node_embeddings",
    "onnx_metadata",
    "require",
    "scene_inputs",
]

ENERGY_INPUTS = ("poses", "nodes", "round")  # the last only for a round-invariant network
EMBEDDING_INPUTS = ("feats", "sizes")
DEFAULT_OPSET = 17
EXPORT_EXTRA = "export needs the 'export' extra: pip install -e '.[export]' (onnx, onnxruntime)"


def require(module: str) -> Any:
    """Import ``module`` (``onnx``, ``onnxruntime``) or raise :class:`SceneError` naming the extra."""
    import importlib

    try:
        return importlib.import_module(module)
    except ImportError as e:
        raise SceneError(f"{EXPORT_EXTRA} ({e})") from None


def _member_energy(net: EnergyNet, poses: Tensor, nodes: Tensor, round: Tensor | None) -> Tensor:
    """:meth:`EnergyNet.forward` for one scene's precomputed nodes, without padding: every object is real,
    and a round-invariant network always takes the round path (the same numbers when none is round)."""
    cfg = net.cfg
    b, n = poses.shape[0], poses.shape[1]
    v = nodes.unsqueeze(0).expand(b, n, nodes.shape[-1])
    eye = torch.eye(n, dtype=poses.dtype, device=poses.device)
    pair = (1 - eye).unsqueeze(0).expand(b, n, n)  # no self-edges
    rnd = round.unsqueeze(0).expand(b, n) if cfg.round_invariant and round is not None else None
    if cfg.absolute:
        th = poses[..., 2:3]
        heading = torch.cat([torch.cos(th), torch.sin(th)], dim=-1)
        if rnd is not None:
            heading = heading * (~rnd).unsqueeze(-1).to(heading.dtype)
        v = torch.cat([v, poses[..., :2] / cfg.length_scale, heading], dim=-1)
        e = None
    else:
        walls = None
        if net.reads_walls:  # the walls are the last nodes (see OnnxScene)
            walls = (torch.arange(n, device=poses.device) >= n - WALLS).unsqueeze(0).expand(b, n)
        e = net.edges(poses, rnd, walls)
    for layer in net.layers:
        v = layer(v, e, pair)
    return net.head(v.sum(dim=1)).squeeze(-1)


class _Energy(nn.Module):
    """The members' mean energy (one member: its energy), each member reading its own slice of the
    nodes, as :meth:`EnsembleNet.forward` does."""

    def __init__(self, nets: list[EnergyNet]):
        super().__init__()
        self.members = nn.ModuleList(nets)

    def forward(self, poses: Tensor, nodes: Tensor, round: Tensor | None = None) -> Tensor:
        nets = cast(list[EnergyNet], list(self.members))
        if len(nets) == 1:
            return _member_energy(nets[0], poses, nodes, round)
        parts = nodes.chunk(len(nets), dim=-1)
        energies = [_member_energy(m, poses, x, round) for m, x in zip(nets, parts, strict=True)]
        return torch.stack(energies).mean(dim=0)


class _Embedding(nn.Module):
    """The network's node embeddings (an ensemble's: its members' side by side)."""

    def __init__(self, net: EnergyNet | EnsembleNet):
        super().__init__()
        self.net = net

    def forward(self, feats: Tensor, sizes: Tensor) -> Tensor:
        return self.net.node_embedding(feats, sizes)


@dataclass
class OnnxScene:
    """What ``energy.onnx`` needs of one scene besides its poses, computed once per scene."""

    nodes: np.ndarray  # (M, D) float32: the scene's N objects, then the walls (M = N + W)
    round: np.ndarray  # (M,) bool
    extra_poses: np.ndarray  # (W, 3) float32: poses of the objects the model adds (its walls), or (0, 3)
    inputs: tuple[str, ...] = ENERGY_INPUTS  # the graph's inputs (:func:`energy_inputs`)

    def feeds(self, poses: np.ndarray | Tensor) -> dict[str, np.ndarray]:
        """The inputs of ``energy.onnx`` for ``poses (B, N, 3)`` (or ``(N, 3)``) of the scene's own
        objects: the walls' poses appended when the model has walls."""
        p = np.asarray(poses.detach().cpu() if isinstance(poses, Tensor) else poses, dtype=np.float32)
        if p.ndim == 2:
            p = p[None]
        n = len(self.nodes) - len(self.extra_poses)
        if p.ndim != 3 or p.shape[1:] != (n, 3):
            raise SceneError(f"poses: expected shape (B, {n}, 3) for this scene, got {tuple(p.shape)}")
        if len(self.extra_poses):
            walls = np.broadcast_to(self.extra_poses, (p.shape[0], *self.extra_poses.shape))
            p = np.concatenate([p, walls], axis=1)
        feeds = {"poses": np.ascontiguousarray(p), "nodes": self.nodes, "round": self.round}
        return {k: feeds[k] for k in self.inputs}


def scene_inputs(model: ScoreModel, scene: Scene) -> OnnxScene:
    """Node embeddings, round flags and added objects' poses of ``scene`` for ``energy.onnx``."""
    st = model.tensors([scene])
    with torch.no_grad():
        nodes = model.net.node_embedding(st.feats, st.sizes)[0]
    return OnnxScene(
        nodes=nodes.to(torch.float32).cpu().numpy(),
        round=st.round[0].cpu().numpy(),
        extra_poses=st.poses[0, len(scene) :].to(torch.float32).cpu().numpy(),
        inputs=energy_inputs(model),
    )


def energy_inputs(model: ScoreModel) -> tuple[str, ...]:
    """The inputs of ``model``'s ``energy.onnx``: ``round`` only for a round-invariant network."""
    return ENERGY_INPUTS if model.config.round_invariant else ENERGY_INPUTS[:2]


def node_embeddings(model: ScoreModel, scene: Scene) -> np.ndarray:
    """The ``nodes (M, D)`` input of ``energy.onnx`` for ``scene`` (its objects, then any walls)."""
    return scene_inputs(model, scene).nodes


def onnx_metadata(model: ScoreModel, inputs: tuple[str, ...], outputs: tuple[str, ...]) -> dict[str, str]:
    """The ``metadata_props`` an exported graph carries."""
    cfg = model.config
    return {
        "format": "scenescore-energy" if outputs == ("energy",) else "scenescore-embedding",
        "length_scale": repr(float(cfg.length_scale)),
        "inputs": json.dumps(list(inputs)),
        "outputs": json.dumps(list(outputs)),
        "walls": str(bool(cfg.walls)).lower(),
        "round_invariant": str(bool(cfg.round_invariant)).lower(),
        "embed_dim": str(_node_dim(model)),
        "members": str(model.members),
        "feat_dim": str(cfg.feat_dim),
        "encoder": json.dumps({"name": model.encoder.name, "config": model.encoder.config()}),
        "energy_config": json.dumps(cfg.to_dict()),
    }


def _node_dim(model: ScoreModel) -> int:
    """The width ``D`` of the ``nodes`` input: each member's embedding and footprint, side by side."""
    return model.members * (model.config.embed_dim + 2)


@contextmanager
def _quiet() -> Iterator[None]:
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation and tracer notes
        yield


def _to_proto(
    module: nn.Module,
    args: tuple[Tensor, ...],
    inputs: tuple[str, ...],
    outputs: tuple[str, ...],
    dynamic_axes: dict[str, dict[int, str]],
    opset: int,
    dynamo: bool | None,
) -> Any:
    """``module`` as an ONNX ``ModelProto``: the TorchScript exporter unless ``dynamo`` (or where it is
    gone), which turns ``dynamic_axes`` into ``torch.export`` dims."""
    onnx = require("onnx")
    if not dynamo:
        try:
            with _quiet(), torch.no_grad(), tempfile.TemporaryDirectory() as tmp:
                torch.onnx.export(
                    module,
                    args,
                    Path(tmp) / "graph.onnx",
                    dynamo=False,
                    input_names=list(inputs),
                    output_names=list(outputs),
                    dynamic_axes=dynamic_axes,
                    opset_version=opset,
                )
                return onnx.load(str(Path(tmp) / "graph.onnx"))
        except (TypeError, NotImplementedError, RuntimeError, ImportError):
            if dynamo is False:
                raise
    require("onnxscript")
    dims = {d: torch.export.Dim(d) for axes in dynamic_axes.values() for d in axes.values()}
    shapes = {name: {axis: dims[d] for axis, d in dynamic_axes.get(name, {}).items()} for name in inputs}
    with _quiet(), torch.no_grad():
        prog = torch.onnx.export(
            module,
            args,
            dynamo=True,
            input_names=list(inputs),
            output_names=list(outputs),
            dynamic_shapes=shapes,
            opset_version=max(opset, 18),
            verbose=False,
        )
    assert prog is not None  # it returns the program when given no file
    return prog.model_proto


def _write(proto: Any, path: str | os.PathLike, meta: dict[str, str]) -> Path:
    onnx = require("onnx")
    onnx.helper.set_metadata_props(proto, {**{p.key: p.value for p in proto.metadata_props}, **meta})
    onnx.checker.check_model(proto)
    path = Path(path)
    atomic_write_bytes(path, proto.SerializeToString())
    return path


def _float_net(model: ScoreModel) -> EnergyNet | EnsembleNet:
    """The model's network (or ensemble) as a float32 copy on the CPU, which exports it."""
    return copy.deepcopy(model.net).to("cpu", torch.float32).eval()


def export_onnx(
    model: ScoreModel, path: str | os.PathLike, opset: int = DEFAULT_OPSET, dynamo: bool | None = None
) -> Path:
    """Write ``model``'s energy as ONNX to ``path`` atomically (see the module's docstring for the inputs);
    ``dynamo``: None takes the TorchScript exporter where this torch still has it (fast, with
    ``dynamic_axes``) and ``torch.export`` otherwise; True or False forces one."""
    require("onnx")
    if model.config.local:
        raise SceneError(
            "export: this model reads a local graph (each object's nearest neighbours, for rooms), which "
            "the ONNX graph does not carry yet; export a model trained with graph: dense"
        )
    net = _float_net(model)
    inputs = energy_inputs(model)
    n = 3
    args = (torch.zeros(2, n, 3), torch.zeros(n, _node_dim(model)), torch.zeros(n, dtype=torch.bool))
    axes = {"poses": {0: "batch", 1: "objects"}, "nodes": {0: "objects"}, "round": {0: "objects"}}
    axes = {**{k: v for k, v in axes.items() if k in inputs}, "energy": {0: "batch"}}
    proto = _to_proto(_Energy(members_of(net)), args[: len(inputs)], inputs, ("energy",), axes, opset, dynamo)
    return _write(proto, path, onnx_metadata(model, inputs, ("energy",)))


def export_embedding_onnx(
    model: ScoreModel, path: str | os.PathLike, opset: int = DEFAULT_OPSET, dynamo: bool | None = None
) -> Path:
    """Write the node-embedding step as ONNX to ``path`` atomically: ``feats (N, F)``, ``sizes (N, 2)``
    -> ``nodes (N, D)``, the ``nodes`` input of :func:`export_onnx`'s graph."""
    require("onnx")
    args = (torch.zeros(3, model.config.feat_dim), torch.zeros(3, 2))
    axes = {"feats": {0: "objects"}, "sizes": {0: "objects"}, "nodes": {0: "objects"}}
    proto = _to_proto(_Embedding(_float_net(model)), args, EMBEDDING_INPUTS, ("nodes",), axes, opset, dynamo)
    return _write(proto, path, onnx_metadata(model, EMBEDDING_INPUTS, ("nodes",)))
