"""Devices: where a model's weights, a problem's tensors and their random numbers live.

Everything runs on the CPU unless asked otherwise. A model's device (:func:`scenescore.models.load`
with ``device=``, :func:`scenescore.learn.train` with ``device=``, or ``model.to(device)``) drives
the problems built on it: :class:`~scenescore.problem.problem.Problem` puts its tensors, its bound costs and its
solvers' particles on the device of the learned energy it holds (or the ``device`` it is given).

Random numbers come from a generator on that same device (:func:`generator`): a seed gives the same
numbers on every run on one device, and on the CPU the numbers are those of ``torch.Generator()``;
a CUDA device draws different numbers for the same seed. The numpy, shapely, OSQP and CasADi parts
(exact checks, the ``osqp`` and ``casadi`` stages) stay on the CPU: they copy what they read to it.
"""

from __future__ import annotations

import torch

from ..errors import ConfigError

__all__ = ["resolve_device", "generator", "draw"]


def resolve_device(spec: str | torch.device | None = None, what: str = "device") -> torch.device:
    """``spec`` as a torch device, checked: ``None`` or ``"cpu"`` is the CPU; ``"cuda"`` (``"cuda:N"``)
    needs CUDA (and that GPU) on this machine; ``"mps"`` Apple's GPU. Anything else is a
    :class:`~scenescore.errors.ConfigError` naming ``what`` (``"--device"`` on the command line)."""
    if spec is None:
        return torch.device("cpu")
    text = str(spec)
    try:
        dev = torch.device(spec)
    except (RuntimeError, TypeError, ValueError):
        dev = None
    if dev is None or dev.type not in ("cpu", "cuda", "mps"):
        raise ConfigError(f"{what} {text}: unknown device; expected cpu, cuda or cuda:N (a GPU's index)")
    if dev.type == "cpu":
        return torch.device("cpu")
    if dev.type == "mps":
        if not torch.backends.mps.is_available():
            raise ConfigError(
                f"{what} {text}: MPS is not available on this machine (torch {torch.__version__})"
            )
        return torch.device("mps", 0)  # what its tensors report
    if not torch.cuda.is_available():
        raise ConfigError(f"{what} {text}: CUDA is not available on this machine (torch {torch.__version__})")
    count = torch.cuda.device_count()
    index = torch.cuda.current_device() if dev.index is None else dev.index
    if index >= count:
        raise ConfigError(
            f"{what} {text}: no such GPU; this machine has {count} (cuda:0 to cuda:{count - 1})"
        )
    return torch.device("cuda", index)


def generator(seed: int, device: str | torch.device | None = None) -> torch.Generator:
    """A generator seeded with ``seed`` on ``device`` (default the CPU: ``torch.Generator().manual_seed``)."""
    return torch.Generator(device=torch.device("cpu") if device is None else device).manual_seed(int(seed))


def draw(
    kind: str,
    shape: tuple[int, ...],
    gen: torch.Generator,
    device: torch.device,
    dtype: torch.dtype | None = None,
) -> torch.Tensor:
    """``torch.rand`` (``kind="rand"``) or ``torch.randn`` numbers from ``gen`` on ``device``: drawn on the
    generator's own device, then moved (no copy when the two agree), so the numbers depend on the
    generator alone."""
    fn = torch.rand if kind == "rand" else torch.randn
    return fn(shape, generator=gen, dtype=dtype, device=gen.device).to(device)
