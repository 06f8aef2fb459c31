"""Training settings (:class:`TrainConfig`, the network's own in :class:`NetworkConfig`) and the one
place where the settings the data decides are worked out (:func:`derive`)."""

from __future__ import annotations

import importlib.util
import shutil
from collections.abc import Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from types import MappingProxyType
from typing import Any, Literal, get_args

from ..encoders import Encoder, FootprintEncoder
from ..errors import ConfigError, check_number
from ..models.architecture import Activation, EnergyConfig
from ..models.ensemble import MAX_MEMBERS
from ..models.graph import WALLS
from ..scene.scene import Scene
from ..solvers.kernel import TRAINING, LangevinConfig
from .data import data_scale, local_radius, stands_against_walls

__all__ = [
    "NetworkConfig",
    "TrainConfig",
    "RAW_EDGES",
    "ONE_NETWORK",
    "Derived",
    "derive",
    "LOCAL_FROM",
    "LR_DENSE",
    "LR_LOCAL",
    "Graph",
    "Compile",
    "COMPILE_FROM",
    "compiled_placements",
    "compiles",
    "shared_compile",
    "training_work",
]

Graph = Literal["auto", "dense", "local"]
Compile = Literal["auto", "on", "off"]
Ensemble = Literal["seeds", "snapshots"]
#: the training work (edge evaluations: pose sets x objects x the objects each reads, over the chains'
#: steps and the loss's passes) from which ``compile="auto"`` compiles: below it the cold compile costs
#: more than the compiled passes save (``benchmarks/bench_training.py`` measures both)
COMPILE_FROM = 1.5e8
#: ``graph="auto"`` gives data whose largest scene has more objects than this (walls included) a local
#: graph: from here a scene's cost grows with its objects, not their square, and every table top keeps
#: the dense graph (``benchmarks/bench_rooms.py`` times both)
LOCAL_FROM = 32
#: the learning rate where ``TrainConfig.lr`` is None: the dense graph's, and the local graph's, higher
#: for a room's many objects (docs/studies.md, "The zoo's rooms")
LR_DENSE = 2e-3
LR_LOCAL = 4e-3


@dataclass
class NetworkConfig:
    """The energy network's architecture (the :class:`~scenescore.models.architecture.EnergyConfig` fields
    that neither the data nor the training settings below decide); the defaults are EnergyConfig's own,
    read from it so that the two cannot drift apart (what each field means is documented there)."""

    embed_dim: int = EnergyConfig.embed_dim
    hidden: int = EnergyConfig.hidden
    edge_hidden: int | None = EnergyConfig.edge_hidden  # None: hidden
    layers: int = EnergyConfig.layers
    message: Literal["mlp", "linear"] = EnergyConfig.message
    activation: Activation = EnergyConfig.activation
    absolute: bool = EnergyConfig.absolute

    def __post_init__(self) -> None:
        EnergyConfig(feat_dim=1, **asdict(self))  # the network's own checks, before any data is read


@dataclass
class TrainConfig:
    """Training settings; the defaults work for about 50 scenes of up to a dozen objects."""

    iterations: int = 600
    batch_scenes: int = 16
    negatives: int = 16  # counter-examples per scene
    chain_steps: int = 6  # Langevin steps each persistent chain advances per iteration
    restart: float = 0.1  # fraction of chains restarted from uniform each iteration
    # each chain follows this schedule from its (re)start: coarse moves first, then fine ones
    chain: LangevinConfig = TRAINING
    perturbed: int = 0  # extra counter-examples: one object's true pose moved by noise of a random scale
    # log-uniform range of the position noise's std (length scales)
    perturb_pos: tuple[float, float] = (0.05, 2.0)
    perturb_angle: tuple[float, float] = (0.03, 1.5)  # log-uniform range of the angle noise's std (rad)
    # extra counter-examples: one movable object put at the pose relative to another object (not its
    # nearest) that it has to its nearest neighbour: a relation of the data on the wrong anchor (a book at
    # the row's far end instead of its place in the row)
    reanchored: int = 8
    # fraction of restarted chains that start from such a pose (one object on the wrong anchor, it alone
    # moving) halfway through their schedule, instead of from uniform: the chain relaxes it into the
    # nearest hard counter-example (flush to the wall, at the row's far end)
    reanchor_restart: float = 0.5
    # noise on every node input, fresh per object and iteration, so that the energy leans on geometry more
    # than on exact features, which carries it to objects it never saw (Table 2): Gaussian noise of std
    # feature_noise on the encoder's vector, and of std size_noise length scales on the scale descriptor
    # (the footprint's size as the network reads it; without it the network with its edge encoder orders
    # unseen objects by their width)
    feature_noise: float = 0.6
    size_noise: float = 0.3
    full_fraction: float = 0.3  # chains moving every object
    single_fraction: float = 0.5  # chains moving one object (the rest: a random subset)
    # AdamW's learning rate; None: LR_DENSE for the dense graph, LR_LOCAL for the local one (derive)
    lr: float | None = None
    lr_final: float = 2e-4  # cosine decay to this
    weight_decay: float = 0.0  # AdamW's decoupled weight decay
    energy_reg: float = 1e-3  # small L2 on energies, keeps them bounded
    grad_penalty: float = 0.0  # optional penalty on the energy's gradient norm at counter-examples
    grad_margin: float = 10.0
    network: NetworkConfig = field(default_factory=NetworkConfig)  # widths, message, activation, Abs
    # lengths in the data's own unit, stored in the checkpoint: None derives them (see data_scale);
    # a number (metres; for edge_range, length scales) sets them by hand
    length_scale: float | None = None
    edge_range: float | None = None
    # derive edge_range from the data (False: linear edge positions). Off by default: saturated offsets
    # misplace objects of unseen sizes (Table 2's spoons)
    saturate_edges: bool = False
    # the bounds' sides as fixed objects in every graph; None: when the data stands against them
    walls: bool | None = None
    # with walls: walls as lines (see EnergyConfig.wall_lines): no edge reads where along a wall an
    # object stands. Read as boxes, the four walls add up to ramps across the room that pull objects away
    # from their places (docs/studies.md, "Behind the defaults"); False reads them as boxes
    wall_lines: bool = True
    # with walls: length scales beyond which the offsets on an edge touching a wall saturate, each axis
    # on its own (EnergyConfig.wall_range); None: linear
    wall_range: float | None = None
    # round disks' headings ignored by the energy: their headings in the data are arbitrary, and a network
    # that sees them learns noise
    round_invariant: bool = True
    # width of the network's edge encoder (see EnergyConfig.edge_encoder); None: the raw edge features,
    # which leave the energy flat around the truth in larger rooms
    edge_encoder: int | None = 32
    # evaluate each batch in groups of similar object counts, each cropped to its own largest (the same
    # energies; fewer padded edges where 4 and 24 objects share a batch); False: one padded pass
    group_sizes: bool = True
    # "local": each object reads its ``neighbours`` nearest objects (and the walls), edges fading out at a
    # gap of ``radius`` length scales (None: derived from the data, see local_radius), so that a scene's
    # cost grows with its objects rather than their square (rooms); "dense": every pair; "auto": local
    # for data with scenes of more than LOCAL_FROM objects
    graph: Graph = "auto"
    neighbours: int = 6
    radius: float | None = None
    # the trained model is the exponential moving average of the weights with this decay, taken over the
    # second half of training (0: the last iterate, whose noise the average smooths out); a short run's
    # decay is lowered to 1 - 3 / (its averaged iterations), so that the weights of the average's first
    # iteration weigh at most e^-3 (0.99 from 600 iterations)
    average: float = 0.99
    # an ensemble: the energy is the mean of this many networks; where most members doubt a placed
    # object, its placement is flagged (scenescore.models.trust.members_needed). Member 0 is the single model
    # of the seed either way. Three by default: their mean removes the placements far off that one
    # network's minimum makes on some seeds (docs/studies.md, "Ensembles on the zoo"); 1 trains a third
    # of the networks
    members: int = 3
    # where the other members come from: "seeds", member m trained apart with seed seed + 1000 m
    # (members times the training); "snapshots", one run going on after member 0 for members - 1 cycles
    # of snapshot_cycle x iterations each, the learning rate restarted at each cycle's start and the
    # cycle's weights averaged over its second half (1 + (members - 1) x snapshot_cycle times the training)
    ensemble: Ensemble = "seeds"
    snapshot_cycle: float = 0.25
    # the network's passes compiled while it trains (torch.compile; scenescore.models.compiled): "on",
    # "off" (eager), or "auto": when the training's work is large enough (COMPILE_FROM) that compiling
    # pays for itself on a machine whose compiled-kernel cache is empty, and a compiler is there (see
    # docs/performance.md). The two train the same function to float rounding, not the same weights:
    # a seed names a model in one mode
    compile: Compile = "auto"

    def __post_init__(self) -> None:
        if isinstance(self.chain, dict):
            self.chain = LangevinConfig(**self.chain)
        if isinstance(self.network, dict):
            self.network = NetworkConfig(**self.network)
        own = "TrainConfig"
        check_number(own, "iterations", self.iterations, 1, 10_000_000, integer=True)
        for name in ("batch_scenes", "negatives", "chain_steps"):
            check_number(own, name, getattr(self, name), 1, 100_000, integer=True)
        check_number(own, "perturbed", self.perturbed, 0, 100_000, integer=True)
        check_number(own, "reanchored", self.reanchored, 0, 100_000, integer=True)
        check_number(own, "neighbours", self.neighbours, 1, 1024, integer=True)
        check_number(own, "members", self.members, 1, MAX_MEMBERS, integer=True)
        if self.ensemble not in get_args(Ensemble):
            raise ConfigError(f"{own}: ensemble: expected 'seeds' or 'snapshots', got {self.ensemble!r}")
        check_number(own, "snapshot_cycle", self.snapshot_cycle, 0, 1, open_lo=True)
        if self.compile not in get_args(Compile):
            raise ConfigError(f"{own}: compile: expected 'auto', 'on' or 'off', got {self.compile!r}")
        if self.graph not in get_args(Graph):
            raise ConfigError(f"{own}: graph: expected 'auto', 'dense' or 'local', got {self.graph!r}")
        if self.edge_encoder is not None:
            check_number(own, "edge_encoder", self.edge_encoder, 1, 8192, integer=True)
        for name in ("restart", "full_fraction", "single_fraction", "reanchor_restart", "average"):
            check_number(own, name, getattr(self, name), 0, 1)
        if self.average == 1:
            raise ConfigError(f"{own}: average: expected a decay below 1 (0: no averaging), got 1")
        if self.full_fraction + self.single_fraction > 1:
            raise ConfigError(
                f"{own}: full_fraction + single_fraction: expected at most 1, got "
                f"{self.full_fraction} + {self.single_fraction}"
            )
        if self.lr is not None:
            check_number(own, "lr", self.lr, 0, open_lo=True)
        for name in (
            "lr_final",
            "weight_decay",
            "energy_reg",
            "grad_penalty",
            "grad_margin",
            "feature_noise",
            "size_noise",
        ):
            check_number(own, name, getattr(self, name), 0)
        for name in ("length_scale", "edge_range", "wall_range", "radius"):
            if getattr(self, name) is not None:
                check_number(own, name, getattr(self, name), 0, open_lo=True)
        if not isinstance(self.chain, LangevinConfig):
            raise ConfigError(f"{own}: chain: expected a LangevinConfig or a dict of its fields")
        if not isinstance(self.network, NetworkConfig):
            raise ConfigError(f"{own}: network: expected a NetworkConfig or a dict of its fields")
        for name in ("saturate_edges", "round_invariant", "group_sizes", "wall_lines"):
            if not isinstance(getattr(self, name), bool):
                raise ConfigError(f"{own}: {name}: expected true or false, got {getattr(self, name)!r}")

    def to_dict(self) -> dict[str, Any]:
        return asdict(self)

    @property
    def runs(self) -> int:
        """The training runs these settings take: an ensemble of seeds one per member, else one."""
        return self.members if self.ensemble == "seeds" else 1

    @property
    def snapshots(self) -> int:
        """The members one run's snapshots give beside member 0 (0 unless ``ensemble`` is snapshots)."""
        return self.members - 1 if self.ensemble == "snapshots" else 0


#: the network without its edge encoder, with the training settings that suit it (less feature noise,
#: none on sizes, no re-anchored counter-examples): ``TrainConfig(**RAW_EDGES)``
RAW_EDGES: Mapping[str, Any] = MappingProxyType(
    {"edge_encoder": None, "feature_noise": 0.3, "size_noise": 0.0, "reanchored": 0, "reanchor_restart": 0.0}
)


#: the paper's model, one network instead of the default ensemble: ``TrainConfig(**ONE_NETWORK)``. The
#: experiments that reproduce the paper's tables, the demo and the shipped models train it
ONE_NETWORK: Mapping[str, Any] = MappingProxyType({"members": 1})


@dataclass(frozen=True)
class Derived:
    """The settings of one training run that follow from its :class:`TrainConfig` and its data."""

    encoder: Encoder  # the encoder the model keeps (a footprint encoder reads sizes in the data's unit)
    energy: EnergyConfig  # the network, its lengths in the data's unit
    batch_scenes: int  # scenes per iteration: the setting, at most the data's
    chain: LangevinConfig  # each persistent chain's schedule, without a final descent
    averaged_from: int  # the first iteration in the weights' moving average
    decay: float  # the moving average's decay (0: the last iterate)
    candidates: int  # what InfoNCE tells each true scene apart from, the scene itself included
    lr: float  # the learning rate: the setting, else the graph's (LR_DENSE, LR_LOCAL)
    work: float  # edge evaluations over the whole training (see COMPILE_FROM)


def derive(cfg: TrainConfig, scenes: Sequence[Scene], encoder: Encoder | None = None) -> Derived:
    """Everything a run of ``cfg`` on ``scenes`` decides from the data or from other settings: the length
    scale (the data's unless set), the edge range (the data's largest offset with ``saturate_edges``),
    the walls (where the data stands against its bounds, unless set) and the wall settings that apply
    only with them, the graph (local for rooms, its radius the data's) and its learning rate unless
    set, the encoder reading sizes in the data's unit, the batch, the chains' schedule and the averaging.

    A local graph's length scale is that of the objects to place (the data's movable ones): the
    network tells offsets apart to a fraction of a length scale, and in a room the large fixed furniture
    would set one too coarse for the chairs between it."""
    walls = cfg.walls if cfg.walls is not None else stands_against_walls(scenes)
    largest = max(len(s) for s in scenes) + (WALLS if walls else 0)
    local = cfg.graph == "local" or (cfg.graph == "auto" and largest > LOCAL_FROM)
    length, far = data_scale(scenes, movable=local)
    length = cfg.length_scale or length
    reach = cfg.edge_range or (far if cfg.saturate_edges else None)
    encoder = encoder or FootprintEncoder()
    if isinstance(encoder, FootprintEncoder):
        encoder = encoder.scaled(length)  # sizes in the data's unit
    radius = (cfg.radius or local_radius(scenes, length, cfg.neighbours)) if local else None
    energy = EnergyConfig(
        feat_dim=encoder.dim,
        **asdict(cfg.network),
        length_scale=length,
        edge_range=reach,
        walls=bool(walls),
        round_invariant=cfg.round_invariant,
        edge_encoder=cfg.edge_encoder,
        wall_range=cfg.wall_range if walls else None,
        wall_lines=cfg.wall_lines and bool(walls),
        neighbours=cfg.neighbours if local else None,
        radius=radius,
    )
    averaged_from, decay = averaging(cfg.average, cfg.iterations)
    return Derived(
        encoder=encoder,
        energy=energy,
        batch_scenes=min(cfg.batch_scenes, len(scenes)),
        chain=replace(cfg.chain, final_descent=0),
        averaged_from=averaged_from,
        decay=decay,
        candidates=cfg.negatives + cfg.perturbed + cfg.reanchored + 1,
        lr=cfg.lr if cfg.lr is not None else (LR_LOCAL if local else LR_DENSE),
        work=training_work(cfg, scenes, energy),
    )


def averaging(average: float, iterations: int) -> tuple[int, float]:
    """``(first averaged iteration, decay)`` of the weights' moving average over a run of ``iterations``:
    its second half, the decay ``average`` lowered to ``1 - 3 / (averaged iterations)`` for a short run
    (the first averaged iteration's weights weigh at most e^-3), 0 for no averaging."""
    start = iterations // 2
    return start, max(min(average, 1 - 3 / max(iterations - start, 1)), 0.0)


def training_work(cfg: TrainConfig, scenes: Sequence[Scene], energy: EnergyConfig) -> float:
    """Edge evaluations a training of ``cfg`` on ``scenes`` makes: each iteration's chains (``batch x
    negatives`` pose sets, ``chain_steps`` times) and loss (``batch`` x every candidate), each pose set
    of a scene of ``n`` objects ``n`` times the nodes each reads (every one, dense; its neighbours and
    the walls, local), at the scenes' mean."""
    walls = WALLS if energy.walls else 0
    reads = [(len(s) + walls) * energy.reads(len(s) + walls) for s in scenes]
    batch = min(cfg.batch_scenes, len(scenes))
    rows = batch * (cfg.negatives * cfg.chain_steps + cfg.negatives + cfg.perturbed + cfg.reanchored + 1)
    return float(cfg.iterations * rows * sum(reads) / len(reads))


def compiles(cfg: TrainConfig, d: Derived, device_type: str) -> bool:
    """Whether a training of ``cfg`` (derived as ``d``) runs its network compiled on a device of
    ``device_type``: ``compile`` on or off as set; ``"auto"``: from :data:`COMPILE_FROM` edge
    evaluations, where a compiler for the device is installed (a C++ compiler for the CPU, Triton for
    CUDA). The choice reads the training and the machine, not its load: the model is the same idle or
    loaded, for any ``--jobs`` and ``--threads``."""
    if cfg.compile != "auto":
        return cfg.compile == "on"
    return d.work >= COMPILE_FROM and compiler_available(device_type)


def shared_compile(
    cfg: TrainConfig, scenes: Sequence[Scene], trainings: int, device_type: str
) -> TrainConfig:
    """``cfg`` for one of ``trainings`` trainings of its network on data like ``scenes`` (an experiment's
    seeds, or its seeds and rules), with ``compile="auto"`` settled over their work together: the first
    of them to compile keeps the kernels in the cache folder, where the others (in any worker process)
    find them, so one cold compile serves them all. ``"on"`` where their work reaches
    :data:`COMPILE_FROM` and a compiler is installed; otherwise ``cfg`` as it is, each training then
    deciding on its own work. Settled before the trainings start, from the run's settings and data, so
    that each training, and the model cache's key, names its choice."""
    if cfg.compile != "auto" or trainings < 1:
        return cfg
    if derive(cfg, scenes).work * trainings < COMPILE_FROM or not compiler_available(device_type):
        return cfg
    return replace(cfg, compile="on")


def compiled_placements(cfg: TrainConfig | None) -> bool:
    """Whether :class:`~scenescore.planning.placement.SceneScorePlacer` (the placements of Tables 1 and
    2, many to a task) places with its network's compiled chains
    (:meth:`~scenescore.models.ScoreModel.compiled_chains`): where its trainings are settled ``"on"``
    (:func:`shared_compile`: several trainings of one shape, so that the placements' own graphs, compiled
    once, serve every task). The zoo's and tidy's tasks place eager: a zoo task's placements are too
    small a part of it to repay those graphs' first compile (docs/performance.md)."""
    return cfg is not None and cfg.compile == "on"


def compiler_available(device_type: str) -> bool:
    """Whether torch.compile can build kernels for ``device_type`` here."""
    if device_type == "cuda":
        return importlib.util.find_spec("triton") is not None
    if device_type == "cpu":
        return any(shutil.which(cc) for cc in ("c++", "g++", "clang++"))
    return False
