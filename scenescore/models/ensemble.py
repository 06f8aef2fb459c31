"""An ensemble of energies: several networks of one shape, trained with different seeds, whose mean
energy places and whose disagreement says how far to trust a placement.

One network's minimum depends on its seed and on float rounding: in the zoo a seed's model put a book at
the row's far end or a nightstand on the wrong side of a bed where the others did not. A pose that every
member scores low is one the data supports; where the members disagree, their mean is flatter and the
members' own energy shares (:func:`member_shares`) say which of them doubts the pose.

:class:`EnsembleNet` has :class:`~scenescore.models.network.EnergyNet`'s interface (``forward``,
``node_embedding``, ``cfg``), so a :class:`~scenescore.models.model.ScoreModel` holds either and every
cost, solver and placement runs on both. The members' node embeddings are concatenated along the last
dimension (one tensor, which placement's batching indexes and repeats like a single network's).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import cast

import torch
from torch import Tensor, nn

from ..errors import ConfigError
from .architecture import EnergyConfig
from .network import EnergyNet

__all__ = ["EnsembleNet", "MAX_MEMBERS", "member_seed", "members_of"]

MAX_MEMBERS = 16
#: member ``m`` of the ensemble of seed ``s`` trains with seed ``s + m * SEED_STRIDE``: member 0 is the
#: single model of seed ``s``, and the ensembles of seeds 0, 1, 2 share no member
SEED_STRIDE = 1000


def member_seed(seed: int, member: int) -> int:
    """The training seed of member ``member`` of the ensemble of ``seed``."""
    return int(seed) + int(member) * SEED_STRIDE


class EnsembleNet(nn.Module):
    """The mean energy of ``members`` networks of one :class:`EnergyConfig` -> ``(B,)``."""

    def __init__(self, nets: Sequence[EnergyNet]):
        super().__init__()
        if not 2 <= len(nets) <= MAX_MEMBERS:
            raise ConfigError(f"EnsembleNet: expected 2 to {MAX_MEMBERS} members, got {len(nets)}")
        if any(not isinstance(n, EnergyNet) or n.cfg != nets[0].cfg for n in nets):
            raise ConfigError("EnsembleNet: the members must be energy networks of one EnergyConfig")
        self.members = nn.ModuleList(nets)
        self.cfg: EnergyConfig = nets[0].cfg

    @classmethod
    def fresh(cls, cfg: EnergyConfig, members: int) -> EnsembleNet:
        """``members`` newly initialised networks of ``cfg``."""
        if isinstance(members, bool) or not isinstance(members, int) or not 2 <= members <= MAX_MEMBERS:
            raise ConfigError(
                f"EnsembleNet: members: expected an integer 2 to {MAX_MEMBERS}, got {members!r}"
            )
        return cls([EnergyNet(cfg) for _ in range(members)])

    @property
    def size(self) -> int:
        return len(self.members)

    @property
    def nets(self) -> list[EnergyNet]:
        return cast(list[EnergyNet], list(self.members))

    def node_embedding(self, feats: Tensor, sizes: Tensor) -> Tensor:
        """The members' node embeddings side by side: ``(B, N, members * (embed_dim + 2))``."""
        return torch.cat([m.node_embedding(feats, sizes) for m in self.nets], dim=-1)

    def member_energies(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None = None,
        nodes: Tensor | None = None,
        round: Tensor | None = None,
        weight_grads: bool = True,
    ) -> Tensor:
        """Each member's energy: ``(members, B)`` (arguments as :meth:`EnergyNet.forward`)."""
        parts = [None] * self.size if nodes is None else nodes.chunk(self.size, dim=-1)
        return torch.stack(
            [
                m(poses, feats, sizes, mask, nodes=part, round=round, weight_grads=weight_grads)
                for m, part in zip(self.nets, parts, strict=True)
            ]
        )

    def forward(
        self,
        poses: Tensor,
        feats: Tensor | None,
        sizes: Tensor | None,
        mask: Tensor | None = None,
        nodes: Tensor | None = None,
        round: Tensor | None = None,
        weight_grads: bool = True,
    ) -> Tensor:
        """The members' mean energy per scene ``(B,)``."""
        return self.member_energies(poses, feats, sizes, mask, nodes, round, weight_grads).mean(dim=0)


def members_of(net: EnergyNet | EnsembleNet) -> list[EnergyNet]:
    """The networks of ``net``: its members (an :class:`EnsembleNet`), else ``[net]``."""
    return net.nets if isinstance(net, EnsembleNet) else [net]
