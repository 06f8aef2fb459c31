"""A trained SceneScore model: the energy network with the encoder it was trained with, and checkpoints.

Checkpoints are safetensors files: the weights, plus metadata holding the format name and version,
the network's config and the encoder's name and config. Loading never unpickles code, and writing
goes through a temporary file and a rename.
"""

from __future__ import annotations

import json
import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import torch
from safetensors import safe_open
from safetensors.torch import save as st_save
from torch import Tensor, nn

from ..encoders import Encoder, encode_scene, make_encoder
from ..scene import Scene, SceneError, atomic_write_bytes
from .energy import EnergyConfig, EnergyNet

__all__ = [
    "FORMAT",
    "FORMAT_VERSION",
    "SceneTensors",
    "batch_scenes",
    "ScoreModel",
    "load",
    "CheckpointError",
]

FORMAT = "scenescore-energy"
FORMAT_VERSION = 1


class CheckpointError(ValueError):
    """A checkpoint that cannot be loaded; the message names the file and what is wrong."""


@dataclass
class SceneTensors:
    """Scenes as padded tensors; ``mask`` marks real objects, ``known`` known poses, ``fixed`` fixed ones."""

    poses: Tensor  # (B, N, 3), unknown poses are 0
    feats: Tensor  # (B, N, F)
    sizes: Tensor  # (B, N, 2)
    mask: Tensor  # (B, N) bool
    known: Tensor  # (B, N) bool
    fixed: Tensor  # (B, N) bool
    lo: Tensor  # (B, 2) lower bounds
    hi: Tensor  # (B, 2) upper bounds

    def __len__(self) -> int:
        return self.poses.shape[0]

    def index(self, idx: Tensor | Sequence[int]) -> SceneTensors:
        """Rows ``idx`` (an index tensor or list)."""
        idx = torch.as_tensor(idx, dtype=torch.long)
        return SceneTensors(*(getattr(self, f)[idx] for f in self.__dataclass_fields__))

    def repeat(self, k: int) -> SceneTensors:
        """Each scene ``k`` times in a row: ``(B * k, ...)``."""
        return SceneTensors(
            *(getattr(self, f).repeat_interleave(k, dim=0) for f in self.__dataclass_fields__)
        )


def batch_scenes(
    scenes: Sequence[Scene], encoder: Encoder, dtype: torch.dtype = torch.float32
) -> SceneTensors:
    """Encode and pad scenes of possibly different sizes into one batch."""
    if not scenes:
        raise SceneError("batch_scenes: no scenes given")
    b, n = len(scenes), max(len(s) for s in scenes)
    out = SceneTensors(
        poses=torch.zeros(b, n, 3, dtype=dtype),
        feats=torch.zeros(b, n, encoder.dim, dtype=dtype),
        sizes=torch.zeros(b, n, 2, dtype=dtype),
        mask=torch.zeros(b, n, dtype=torch.bool),
        known=torch.zeros(b, n, dtype=torch.bool),
        fixed=torch.zeros(b, n, dtype=torch.bool),
        lo=torch.zeros(b, 2, dtype=dtype),
        hi=torch.zeros(b, 2, dtype=dtype),
    )
    for k, s in enumerate(scenes):
        m = len(s)
        out.poses[k, :m] = torch.as_tensor(s.poses(), dtype=dtype)
        out.feats[k, :m] = torch.as_tensor(encode_scene(s, encoder), dtype=dtype)
        out.sizes[k, :m] = torch.as_tensor(s.sizes(), dtype=dtype)
        out.mask[k, :m] = True
        out.known[k, :m] = torch.tensor([o.pose is not None for o in s.objects])
        out.fixed[k, :m] = torch.tensor([o.fixed for o in s.objects])
        out.lo[k] = torch.tensor(s.bounds[0], dtype=dtype)
        out.hi[k] = torch.tensor(s.bounds[1], dtype=dtype)
    return out


class ScoreModel(nn.Module):
    """The energy network and its encoder: ``E(poses | scene)``, low for arrangements like the examples."""

    def __init__(self, net: EnergyNet, encoder: Encoder, info: dict[str, Any] | None = None):
        super().__init__()
        self.net = net
        self.encoder = encoder
        self.info: dict[str, Any] = dict(info or {})

    @classmethod
    def create(cls, encoder: Encoder, **config: Any) -> ScoreModel:
        """A freshly initialised model for ``encoder`` (``config``: :class:`EnergyConfig` fields)."""
        return cls(EnergyNet(EnergyConfig(feat_dim=encoder.dim, **config)), encoder)

    @property
    def config(self) -> EnergyConfig:
        return self.net.cfg

    def tensors(self, scenes: Sequence[Scene]) -> SceneTensors:
        """Encode scenes with this model's encoder."""
        return batch_scenes(scenes, self.encoder, dtype=self.dtype)

    @property
    def dtype(self) -> torch.dtype:
        return next(self.net.parameters()).dtype

    def energy(self, poses: Tensor, st: SceneTensors) -> Tensor:
        """Energy of ``poses (B, N, 3)`` for scenes ``st`` (batch B, or 1 broadcast over B) -> ``(B,)``."""
        b = poses.shape[0]
        feats, sizes, mask = st.feats, st.sizes, st.mask
        if feats.shape[0] == 1 and b != 1:
            feats, sizes, mask = (t.expand(b, *t.shape[1:]) for t in (feats, sizes, mask))
        return self.net(poses, feats, sizes, mask)

    def energy_fn(self, scene: Scene) -> Callable[[Tensor], Tensor]:
        """``poses (B, N, 3) -> (B,)`` conditioned on one scene's objects (node embeddings computed once)."""
        st = self.tensors([scene])
        return self.energy_fn_for(st)

    def energy_fn_for(self, st: SceneTensors) -> Callable[[Tensor], Tensor]:
        """As :meth:`energy_fn`, for an already encoded single scene."""
        nodes = self.net.node_embedding(st.feats, st.sizes)  # (1, N, D)

        def fn(poses: Tensor) -> Tensor:
            b = poses.shape[0]
            mask = st.mask.expand(b, -1)
            return self.net(poses, None, None, mask, nodes=nodes)  # type: ignore[arg-type]

        return fn

    # -- checkpoints ----------------------------------------------------------------------------
    def save(self, path: str | os.PathLike) -> None:
        """Write a safetensors checkpoint atomically."""
        meta = {
            "format": FORMAT,
            "format_version": str(FORMAT_VERSION),
            "energy_config": json.dumps(self.net.cfg.to_dict()),
            "encoder": json.dumps({"name": self.encoder.name, "config": self.encoder.config()}),
            "info": json.dumps(self.info),
        }
        tensors = {k: v.detach().contiguous().cpu() for k, v in self.net.state_dict().items()}
        atomic_write_bytes(path, st_save(tensors, metadata=meta))


def load(path: str | os.PathLike, encoder: Encoder | None = None) -> ScoreModel:
    """Load a checkpoint written by :meth:`ScoreModel.save` (no pickle); ``encoder`` overrides the stored one."""
    path = Path(path)
    if not path.exists():
        raise CheckpointError(f"{path}: no such checkpoint file")
    try:
        with safe_open(str(path), framework="pt") as f:
            meta = f.metadata() or {}
            tensors = {k: f.get_tensor(k) for k in f.keys()}
    except Exception as e:  # safetensors raises its own error types for corrupt files
        raise CheckpointError(
            f"{path}: not a scenescore checkpoint (safetensors could not read it: {e})"
        ) from None
    if meta.get("format") != FORMAT:
        raise CheckpointError(
            f"{path}: not a scenescore checkpoint (format {meta.get('format')!r}, expected {FORMAT!r})"
        )
    version = meta.get("format_version")
    if version != str(FORMAT_VERSION):
        raise CheckpointError(
            f"{path}: checkpoint format version {version!r} is not supported by this scenescore "
            f"(it reads version {FORMAT_VERSION}); retrain with `scenescore train` or use a matching release"
        )
    try:
        cfg = EnergyConfig(**json.loads(meta["energy_config"]))
        enc_meta = json.loads(meta["encoder"])
        info = json.loads(meta.get("info", "{}"))
    except (KeyError, TypeError, json.JSONDecodeError) as e:
        raise CheckpointError(f"{path}: checkpoint metadata is damaged ({e})") from None
    if encoder is None:
        encoder = make_encoder(enc_meta["name"], enc_meta.get("config"))
    if encoder.dim != cfg.feat_dim:
        raise CheckpointError(
            f"{path}: encoder {encoder.name!r} makes {encoder.dim}-vectors, the model expects {cfg.feat_dim}"
        )
    net = EnergyNet(cfg)
    try:
        net.load_state_dict(tensors)
    except RuntimeError as e:
        raise CheckpointError(f"{path}: weights do not match the stored config: {e}") from None
    net.eval()
    return ScoreModel(net, encoder, info)
