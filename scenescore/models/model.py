"""A trained SceneScore model: the energy network with the encoder it was trained with."""

from __future__ import annotations

import os
from collections.abc import Callable, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from pathlib import Path
from typing import Any

import torch
from torch import Tensor, nn

from ..encoders import Encoder, make_encoder
from ..runtime import check_memory, resolve_device
from ..scene.scene import Scene
from .architecture import EnergyConfig, parameter_count
from .batching import SceneTensors, batch_scenes
from .checkpoint import CheckpointError, read_checkpoint, write_checkpoint
from .compiled import compiling
from .ensemble import MAX_MEMBERS, EnsembleNet, members_of
from .info import ModelInfo
from .moving import Mover, moving_one
from .network import EnergyNet, round_flags
from .trust import TrustReference

__all__ = ["ScoreModel", "load", "with_walls"]


class ScoreModel(nn.Module):
    """The energy network and its encoder: ``E(poses | scene)``, low for arrangements like the examples.

    The model's device (``model.to(device)``, or ``load(path, device=...)``) is where its scenes are
    encoded to and where the problems built on it run (see :mod:`scenescore.runtime.devices`)."""

    def __init__(self, net: EnergyNet | EnsembleNet, encoder: Encoder, info: ModelInfo | None = None):
        super().__init__()
        self.net = net
        self.encoder = encoder
        self.info = info if info is not None else ModelInfo()  # what training recorded (the checkpoint's)

    @classmethod
    def create(cls, encoder: Encoder, **config: Any) -> ScoreModel:
        """A freshly initialised model for ``encoder`` (``config``: :class:`EnergyConfig` fields)."""
        return cls(EnergyNet(EnergyConfig(feat_dim=encoder.dim, **config)), encoder)

    @property
    def trust(self) -> TrustReference | None:
        """What placements are judged against (stored by training), or None for older checkpoints."""
        return self.info.trust

    @property
    def config(self) -> EnergyConfig:
        return self.net.cfg

    @property
    def members(self) -> int:
        """The networks whose mean energy this model is: 1, or an ensemble's size."""
        return len(members_of(self.net))

    def member_energies(self, poses: Tensor, st: SceneTensors) -> Tensor:
        """Each member's energy of ``poses (B, N, 3)`` for scenes ``st`` (as :meth:`energy`): ``(members, B)``."""
        if isinstance(self.net, EnsembleNet):
            feats, sizes, mask, rnd = _broadcast(st, poses.shape[0])
            return self.net.member_energies(
                poses, feats, sizes, mask, round=round_flags(self.config, rnd), weight_grads=False
            )
        return self.energy(poses, st, weight_grads=False)[None]

    @contextmanager
    def compiled_chains(self) -> Iterator[None]:
        """Within the block the chains that sample this model (placement's Langevin) take their pose
        gradient through its networks' compiled pass (:mod:`~scenescore.models.compiled`), where they
        trained compiled (``info.compiled``) on a CPU; elsewhere, and for every pass with the weights'
        gradient, eager. For many placements after trainings of the same network shape
        (:func:`~scenescore.learn.config.compiled_placements`): the placements' graphs' first compile
        costs more than one placement saves, so :func:`place` stays eager. The compiled pass differs
        from the eager one by float rounding, which can change which particle a placement keeps."""
        with ExitStack() as stack:
            if self.info.compiled and self.device.type == "cpu":
                for net in members_of(self.net):
                    stack.enter_context(compiling(net, "cpu", loss=False))
            yield

    def tensors(self, scenes: Sequence[Scene]) -> SceneTensors:
        """Encode scenes with this model's encoder, on the model's device."""
        return batch_scenes(
            scenes, self.encoder, dtype=self.dtype, walls=self.config.walls, device=self.device
        )

    @property
    def dtype(self) -> torch.dtype:
        return next(self.net.parameters()).dtype

    @property
    def device(self) -> torch.device:
        """Where the weights are (``cpu`` unless moved)."""
        return next(self.net.parameters()).device

    def energy(self, poses: Tensor, st: SceneTensors, weight_grads: bool = True) -> Tensor:
        """Energy of ``poses (B, N, 3)`` for scenes ``st`` (batch B, or 1 broadcast over B) -> ``(B,)``;
        ``weight_grads=False``: a gradient for the poses alone (sampling; see :meth:`EnergyNet.forward`)."""
        return self.energy_for(st, weight_grads)(poses)

    def energy_for(self, st: SceneTensors, weight_grads: bool = True) -> Callable[[Tensor], Tensor]:
        """:meth:`energy` for the scenes ``st``, their round objects read once (the device waited on
        here, not at every call: a chain calls it at every step)."""
        rnd = round_flags(self.config, st.round)

        def fn(poses: Tensor) -> Tensor:
            feats, sizes, mask, _ = _broadcast(st, poses.shape[0])
            return self.net(poses, feats, sizes, mask, round=rnd, weight_grads=weight_grads)

        return fn

    def energy_fn(self, scene: Scene) -> Callable[[Tensor], Tensor]:
        """``poses (B, N, 3) -> (B,)`` conditioned on one scene's objects (node embeddings computed once).
        For sampling and scoring: a batch evaluated in chunks gives no gradient to the weights (train
        through :meth:`energy`)."""
        st = self.tensors([scene])
        return self.energy_fn_for(st)

    def energy_fn_for(self, st: SceneTensors) -> Callable[[Tensor], Tensor]:
        """As :meth:`energy_fn`, for an already encoded single scene."""
        nodes = self.net.node_embedding(st.feats, st.sizes)  # (1, N, D)
        rnd = round_flags(self.config, st.round)

        def fn(poses: Tensor) -> Tensor:
            b = poses.shape[0]
            mask = st.mask.expand(b, -1)
            return self.net(
                with_walls(poses, st), None, None, mask, nodes=nodes, round=rnd, weight_grads=False
            )

        return fn

    def moving_one(self, st: SceneTensors, o: int) -> Mover | None:
        """The energy of an encoded single scene's pose sets in which only object ``o`` moves, the nodes
        it cannot reach computed once (:func:`~scenescore.models.moving.moving_one`, each member's for an
        ensemble); None where that does not apply (a dense graph, walls, a small scene, a GPU)."""
        with torch.no_grad():
            nodes = self.net.node_embedding(st.feats, st.sizes)
        rnd = round_flags(self.config, st.round)
        nets = members_of(self.net)
        return moving_one(nets, st.poses[0], nodes[0], st.mask[0], None if rnd is None else rnd[0], o)

    def save(self, path: str | os.PathLike) -> None:
        """Write a safetensors checkpoint atomically (weights, network config, encoder, info)."""
        write_checkpoint(
            path,
            self.net.state_dict(),
            self.net.cfg.to_dict(),
            {"name": self.encoder.name, "config": self.encoder.config()},
            self.info.to_dict(),
        )


def _broadcast(st: SceneTensors, b: int) -> tuple[Tensor, Tensor, Tensor, Tensor]:
    """``st``'s features, sizes, mask and round flags, one scene's expanded over a batch of ``b``."""
    feats, sizes, mask, rnd = st.feats, st.sizes, st.mask, st.round
    if feats.shape[0] == 1 and b != 1:
        feats, sizes, mask, rnd = (t.expand(b, *t.shape[1:]) for t in (feats, sizes, mask, rnd))
    return feats, sizes, mask, rnd


def with_walls(poses: Tensor, st: SceneTensors) -> Tensor:
    """``poses (B, N, 3)`` of a scene's own objects, followed by the poses of the objects ``st`` adds to
    it (the walls of a model that sees them): ``(B, N + W, 3)``."""
    n, total = poses.shape[1], st.poses.shape[1]
    if n == total:
        return poses
    extra = st.poses[:, n:].to(poses.dtype)
    return torch.cat([poses, extra.expand(poses.shape[0], -1, -1)], dim=1)


def load(
    path: str | os.PathLike, encoder: Encoder | None = None, device: str | torch.device | None = None
) -> ScoreModel:
    """Load a checkpoint written by :meth:`ScoreModel.save` (no pickle); ``encoder`` overrides the stored
    one. ``device`` (default the CPU): where the weights go and the model runs; ``"cuda"``
    without CUDA on this machine is a :class:`~scenescore.errors.ConfigError`."""
    path = Path(path)
    dev = resolve_device(device)
    ck = read_checkpoint(path)  # on the CPU, checked there, then moved (a map_location)
    try:
        cfg = EnergyConfig(**ck.energy_config)
    except (TypeError, ValueError) as e:
        raise CheckpointError(f"{path}: checkpoint metadata is damaged: energy_config: {e}") from None
    members = _members(path, ck.info)
    count = members * parameter_count(
        cfg
    )  # the stored weights and the network's copy, before either is built
    check_memory(
        2 * 4 * count,
        f"{path}: the network it declares ({cfg.describe()}: {count:,} weights)",
        "the widths it was trained with (hidden, edge_hidden, layers)",
    )
    with torch.device("meta"):  # the shapes and kinds the config declares, without allocating them
        reference = _network(cfg, members).state_dict()
    expected = {k: tuple(v.shape) for k, v in reference.items()}
    stored = {k: tuple(v.shape) for k, v in ck.tensors.items()}
    if expected != stored:
        diff = sorted(set(expected) ^ set(stored)) or [k for k in expected if expected[k] != stored[k]]
        raise CheckpointError(
            f"{path}: the weights do not match the stored energy_config (first difference: {diff[0]!r})"
        )
    for k, t in ck.tensors.items():
        # an integer or boolean tensor would be cast into the float weights without a word (quantised
        # or damaged weights read as if they were the trained ones)
        if reference[k].is_floating_point() and not t.is_floating_point():
            kind = str(t.dtype).removeprefix("torch.")
            raise CheckpointError(f"{path}: weight {k!r} is {kind}, expected a floating-point tensor")
        if t.is_floating_point() and not bool(torch.isfinite(t).all()):
            raise CheckpointError(f"{path}: weight {k!r} holds NaN or infinite values; the file is damaged")
    if encoder is None:
        config = ck.encoder.get("config")
        if config is not None and not isinstance(config, dict):
            raise CheckpointError(f"{path}: checkpoint metadata: encoder config: expected a mapping")
        try:
            encoder = make_encoder(ck.encoder["name"], config)
        except TypeError as e:
            raise CheckpointError(
                f"{path}: checkpoint metadata: encoder {ck.encoder['name']!r}: {e}"
            ) from None
        except ValueError as e:  # SceneError: an unknown encoder, or options it refuses
            raise CheckpointError(f"{path}: checkpoint metadata: {e}") from None
    if encoder.dim != cfg.feat_dim:
        raise CheckpointError(
            f"{path}: encoder {encoder.name!r} makes {encoder.dim}-vectors, the model expects {cfg.feat_dim}"
        )
    net = _network(cfg, members)
    try:
        net.load_state_dict(ck.tensors)
    except RuntimeError as e:
        raise CheckpointError(f"{path}: weights do not match the stored config: {e}") from None
    net.to(dev).eval()
    try:
        info = ModelInfo.from_dict(ck.info)
    except ValueError as e:  # a damaged trust reference, named
        raise CheckpointError(f"{path}: checkpoint metadata is damaged: {e}") from None
    return ScoreModel(net, encoder, info)


def _network(cfg: EnergyConfig, members: int) -> EnergyNet | EnsembleNet:
    return EnergyNet(cfg) if members == 1 else EnsembleNet.fresh(cfg, members)


def _members(path: Path, info: dict[str, Any]) -> int:
    """The networks a checkpoint holds: an ensemble's ``info.members`` records, else 1."""
    records = info.get("members")
    if records is None:
        return 1
    if not (
        isinstance(records, list)
        and 2 <= len(records) <= MAX_MEMBERS
        and all(isinstance(r, dict) for r in records)
    ):
        raise CheckpointError(
            f"{path}: checkpoint metadata is damaged: info.members: expected a list of 2 to "
            f"{MAX_MEMBERS} member records, got {records!r:.80}"
        )
    return len(records)
