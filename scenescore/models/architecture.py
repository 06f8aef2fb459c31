"""The energy network's architecture, :class:`EnergyConfig`: the widths, the graph (dense or local), the
edge encodings and the options a checkpoint stores, checked where they are made; and the number of
weights a configuration gives, counted without building the network."""

from __future__ import annotations

from dataclasses import asdict, dataclass
from typing import Literal

from ..errors import ConfigError, check_number
from .graph import WALLS

__all__ = ["Activation", "EnergyConfig", "MAX_LAYERS", "MAX_WIDTH", "parameter_count"]

Activation = Literal["silu", "softplus", "leaky_relu"]


MAX_WIDTH = 8192  # the widest layer a checkpoint may declare (the defaults are 32)
MAX_LAYERS = 64


@dataclass
class EnergyConfig:
    """Architecture of :class:`EnergyNet` (stored in checkpoints)."""

    feat_dim: int
    embed_dim: int = 32
    hidden: int = 32
    edge_hidden: int | None = None  # width inside the message MLP f (default: hidden)
    layers: int = 3
    message: Literal["mlp", "linear"] = "mlp"  # "linear": the paper's single linear layer
    activation: Activation = "silu"  # the paper's is "leaky_relu"; smooth helps second-order solvers
    absolute: bool = False  # the "Abs" ablation: absolute poses in the nodes, no edge features
    length_scale: float = 0.1  # metres that map to one unit inside the network (training derives it)
    # offsets (in length scales) beyond which edge positions saturate smoothly: u / sqrt(1 + |u|^2 / R^2);
    # None: linear (checkpoints before it). Training derives it from the data's largest offset.
    edge_range: float | None = None
    walls: bool = False  # the bounds' four sides are fixed objects in every graph (training decides)
    # round disks' headings ignored: an edge from a round object carries only the distance, and an edge
    # touching one no relative heading (False: checkpoints before it; training turns it on)
    round_invariant: bool = False
    # width of the edge encoder ``act(W e + b)`` that each message layer reads instead of the four raw
    # edge features, so a message is a two-layer function of the relative pose and can form a well at
    # one offset, not only a ramp; None: the raw features (checkpoints before it)
    edge_encoder: int | None = None
    # offsets (in length scales) beyond which the positions on an edge touching a wall saturate, each
    # axis on its own: a wall is read near it (how far, how turned, which corner) and not as a ramp across
    # the room, whose sum over four walls pulled objects off their places far from every wall; None:
    # linear (checkpoints before it). Used only with ``walls``
    wall_range: float | None = None
    # walls as lines: seen from a wall an object is only how far it stands from it (its offset along the
    # wall is dropped), and a wall seen from an object is the foot of the perpendicular from the object
    # to it, so no edge reads where along a wall something stands (False: checkpoints before it)
    wall_lines: bool = False
    # a local graph for rooms: each object reads the ``neighbours`` objects nearest to it (by the gap
    # between their footprints' circles, half the longer side each) and every wall, each message weighted
    # by ``(1 - (gap / radius)^2)^2``, which fades to zero at a gap of ``radius`` length scales, so the
    # energy stays smooth as objects come and go from each other's lists; and the energy is a sum of
    # per-object terms (see EnergyNet.readout); None: every pair, one head over the pooled sum (dense)
    neighbours: int | None = None
    radius: float | None = None

    def __post_init__(self) -> None:
        own = "EnergyConfig"
        for name in ("feat_dim", "embed_dim", "hidden", "layers"):
            check_number(own, name, getattr(self, name), 1, MAX_WIDTH, integer=True)
        if self.edge_hidden is not None:
            check_number(own, "edge_hidden", self.edge_hidden, 1, MAX_WIDTH, integer=True)
        check_number(own, "layers", self.layers, 1, MAX_LAYERS, integer=True)
        check_number(own, "length_scale", self.length_scale, 0, open_lo=True)
        if self.edge_range is not None:
            check_number(own, "edge_range", self.edge_range, 0, open_lo=True)
        if self.edge_encoder is not None:
            check_number(own, "edge_encoder", self.edge_encoder, 1, MAX_WIDTH, integer=True)
        if self.wall_range is not None:
            check_number(own, "wall_range", self.wall_range, 0, open_lo=True)
        if (self.neighbours is None) != (self.radius is None):
            raise ConfigError(f"{own}: neighbours and radius: give both (a local graph) or neither (dense)")
        if self.neighbours is not None:
            check_number(own, "neighbours", self.neighbours, 1, MAX_WIDTH, integer=True)
            check_number(own, "radius", self.radius, 0, open_lo=True)
        if self.message not in ("mlp", "linear"):
            raise ConfigError(f"{own}: message: expected 'mlp' or 'linear', got {self.message!r}")
        if self.activation not in ("silu", "softplus", "leaky_relu"):
            raise ConfigError(
                f"{own}: activation: expected 'silu', 'softplus' or 'leaky_relu', got {self.activation!r}"
            )
        for name in ("absolute", "walls", "round_invariant", "wall_lines"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{own}: {name}: expected true or false, got {getattr(self, name)!r}")

    def to_dict(self) -> dict:
        return asdict(self)

    def describe(self) -> str:
        """The widths that memory grows with, for messages."""
        inner = f", edge_hidden {self.edge_hidden}" if self.edge_hidden is not None else ""
        graph = f", {self.neighbours} neighbours" if self.neighbours is not None else ""
        return f"hidden {self.hidden}{inner}, {self.layers} layers, embed_dim {self.embed_dim}{graph}"

    @property
    def local(self) -> bool:
        """Whether the graph is local (:attr:`neighbours` within :attr:`radius`) rather than dense."""
        return self.neighbours is not None

    def reads(self, n: int) -> int:
        """The nodes each node of an ``n``-node graph reads: all of them (dense; the self-edge is
        masked, not skipped), or its neighbours and the walls (local)."""
        return n if self.neighbours is None else min(n, self.neighbours + WALLS * self.walls)


def parameter_count(cfg: EnergyConfig) -> int:
    """The number of weights :class:`EnergyNet` has for ``cfg``, counted without building it."""
    h, inner = cfg.hidden, (cfg.edge_hidden or cfg.hidden) if cfg.message == "mlp" else cfg.hidden
    total = cfg.feat_dim * h + h + h * cfg.embed_dim + cfg.embed_dim  # embed
    d_edge = 0 if cfg.absolute else 4
    if cfg.edge_encoder and not cfg.absolute:
        total += 4 * cfg.edge_encoder + cfg.edge_encoder
        d_edge = cfg.edge_encoder
    for k in range(cfg.layers):
        d_in = cfg.embed_dim + 2 + (4 if cfg.absolute else 0) if k == 0 else h
        total += 2 * d_in * inner + inner + d_edge * inner  # w_i (with bias), w_j, w_e
        if cfg.message == "mlp":
            total += inner * h + h  # out
    return total + h * h + h + h + 1  # head
