"""The training loss and its terms: InfoNCE of each true scene among its counter-examples (the paper's
equation 2), a small L2 on the energies, an optional penalty on steep energies at the counter-examples;
and the held-out InfoNCE that validation reports."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import torch
import torch.nn.functional as F

from ..geometry.poses import uniform_init
from ..models import SceneTensors, ScoreModel
from ..runtime.devices import generator
from ..runtime.threads import torch_threads
from ..scene.scene import Scene
from ..solvers.kernel import TRAINING, Limits, chain
from .config import TrainConfig

__all__ = ["ABSENT", "infonce_loss", "energy_l2", "gradient_penalty", "training_loss", "heldout_loss"]

ABSENT = 1e4  # the energy given to a counter-example that is not there: its softmax weight is 0


def infonce_loss(e_pos: torch.Tensor, e_neg: torch.Tensor) -> torch.Tensor:
    """The paper's equation 2: ``-log softmax`` of the true scene among its counter-examples.

    ``e_pos``: ``(B,)``; ``e_neg``: ``(B, K)``.
    """
    logits = -torch.cat([e_pos[:, None], e_neg], dim=1)  # (B, 1 + K)
    target = torch.zeros(e_pos.shape[0], dtype=torch.long, device=e_pos.device)
    return F.cross_entropy(logits, target)


def energy_l2(e_pos: torch.Tensor, e_real: torch.Tensor) -> torch.Tensor:
    """The mean squared energy of the true scenes plus that of the counter-examples that are there:
    InfoNCE sees only differences of energies, this keeps their level bounded."""
    return e_pos.pow(2).mean() + e_real.pow(2).mean()


def gradient_penalty(model: ScoreModel, neg: torch.Tensor, rep: SceneTensors, margin: float) -> torch.Tensor:
    """The squared excess over ``margin`` of the energy's largest gradient component at each
    counter-example ``neg (B, N, 3)`` of the scenes ``rep``, averaged (differentiable in the weights)."""
    x = neg.detach().requires_grad_(True)
    (g,) = torch.autograd.grad(model.energy(x, rep).sum(), x, create_graph=True)
    gmax = g.abs().amax(dim=(1, 2))
    return F.relu(gmax - margin).pow(2).mean()


def training_loss(
    cfg: TrainConfig,
    model: ScoreModel,
    e_pos: torch.Tensor,
    e_neg: torch.Tensor,
    e_real: torch.Tensor,
    neg: torch.Tensor,
    rep: SceneTensors,
) -> tuple[torch.Tensor, torch.Tensor]:
    """``(loss, infonce)``: InfoNCE of ``e_pos (B,)`` among ``e_neg (B, K)``, plus ``cfg.energy_reg`` times
    :func:`energy_l2` (``e_real``: the energies of the counter-examples that are there) and
    ``cfg.grad_penalty`` times :func:`gradient_penalty` at the chains' counter-examples ``neg`` (of
    ``rep``); a weight of 0 leaves its term out."""
    loss = infonce = infonce_loss(e_pos, e_neg)
    if cfg.energy_reg:
        loss = loss + cfg.energy_reg * energy_l2(e_pos, e_real)
    if cfg.grad_penalty:
        loss = loss + cfg.grad_penalty * gradient_penalty(model, neg, rep, cfg.grad_margin)
    return loss, infonce


def heldout_loss(
    model: ScoreModel, scenes: Sequence[Scene], negatives: int = 16, seed: int = 0
) -> tuple[float, float]:
    """InfoNCE on ``scenes`` against fresh counter-examples (Langevin chains moving every movable object
    from uniform starts, the training schedule run to its end): ``(loss, chance)``; on the model's device."""
    gen = generator(seed, model.device)
    st = model.tensors(scenes)
    rep = st.repeat(negatives)
    movable = rep.mask & ~rep.fixed
    init = torch.where(
        movable[..., None],
        uniform_init((rep.mask.shape[0], rep.mask.shape[1]), rep.lo, rep.hi, gen, rep.poses.dtype),
        rep.poses,
    )

    def energy(x: torch.Tensor) -> torch.Tensor:
        return model.energy(x, rep)

    with torch_threads(1):  # large batches: pieces side by side (EnergyNet.forward)
        limits = Limits(movable, rep.lo, rep.hi)
        neg = chain(energy, init, limits, replace(TRAINING, final_descent=0), gen)
        with torch.no_grad():
            loss = infonce_loss(
                model.energy(st.poses, st), model.energy(neg, rep).reshape(len(scenes), negatives)
            )
    return float(loss), math.log(negatives + 1)
