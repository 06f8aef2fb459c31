"""Devices: ``--device`` on the commands that run a model, and the library's device plumbing.

No test needs a GPU. The plumbing is checked on a pretend one (:class:`FakeGPU`): tensors put "on
cuda:0" are CPU tensors marked as such, and any operation that mixes a marked tensor with an
unmarked one (beyond CPU scalars and CPU index tensors, which CUDA accepts too), or converts a
marked tensor to numpy, raises as CUDA would. Training, placing and every solver then run there,
and must give the CPU's numbers exactly (the pretend GPU draws with a CPU generator).
"""

from __future__ import annotations

import contextlib
import json
from collections.abc import Iterator
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import torch
from torch.overrides import TorchFunctionMode
from torch.utils._pytree import tree_flatten

import scenescore as ss
from scenescore.cli import main
from scenescore.costs import Bounds, CostError, Displacement, HingeCollision, LearnedEnergy, ReachLimit
from scenescore.errors import ConfigError
from scenescore.geometry.poses import uniform_init
from scenescore.runtime.devices import draw, generator, resolve_device

HAS_CUDA = torch.cuda.is_available()
NO_CUDA = f"CUDA is not available on this machine (torch {torch.__version__})"

# -- a pretend GPU ---------------------------------------------------------------------------------------

GPU = torch.device("cuda", 0)
CPU = torch.device("cpu")
_Generator = torch.Generator
_FACTORIES = {
    torch.zeros, torch.ones, torch.empty, torch.full, torch.arange, torch.tensor, torch.as_tensor,
    torch.rand, torch.randn, torch.randint, torch.randperm, torch.linspace, torch.eye,
    torch.scalar_tensor, torch.zeros_like, torch.ones_like, torch.full_like, torch.empty_like,
}  # fmt: skip
_MOVES = {"to", "new_tensor", "new_zeros", "new_ones", "new_full", "new_empty"}
_NO_DATA = {"_has_compatible_shallow_copy_type", "is_same_size"}  # compare types, not data


class DeviceMismatch(RuntimeError):
    """What CUDA would raise: tensors of two devices in one operation, or a GPU tensor given to numpy."""


def on_gpu(t: Any) -> bool:
    return isinstance(t, torch.Tensor) and getattr(t, "_on_fake_gpu", False)


def _mark(out: Any, flag: bool) -> Any:
    for t in tree_flatten(out)[0]:
        if isinstance(t, torch.Tensor):
            t._on_fake_gpu = flag  # type: ignore[attr-defined]
    return out


def _is_gpu(d: Any) -> bool:
    return isinstance(d, (str, torch.device)) and torch.device(d).type == "cuda"


def _target(func: Any, args: tuple, kwargs: dict) -> torch.device | None:
    """The device a factory or a move asks for (None: it names none)."""
    if "device" in kwargs and kwargs["device"] is not None:
        return torch.device(kwargs["device"])
    if getattr(func, "__name__", "") == "to":
        for a in args[1:]:
            if isinstance(a, (str, torch.device)):
                return torch.device(a)
            if isinstance(a, torch.Tensor):
                return GPU if on_gpu(a) else CPU
    return None


class FakeGPU(TorchFunctionMode):
    """Tensors on "cuda:0" are marked CPU tensors; mixing them with unmarked ones raises."""

    def __torch_function__(self, func: Any, types: Any, args: tuple = (), kwargs: dict | None = None) -> Any:
        kwargs = dict(kwargs or {})
        owner, name = getattr(func, "__self__", None), getattr(func, "__name__", "")
        if owner is torch.Tensor.device and name == "__get__":
            return GPU if on_gpu(args[0]) else func(*args)
        if owner is torch.Tensor.is_cuda and name == "__get__":
            return on_gpu(args[0])
        if owner is torch.Tensor.data and name == "__set__":  # Module.to sets each parameter's data
            func(*args)
            args[0]._on_fake_gpu = on_gpu(args[1])
            return None
        if func in (torch.Tensor.numpy, torch.Tensor.__array__) and on_gpu(args[0]):
            raise DeviceMismatch("can't convert a cuda:0 tensor to numpy; copy it to the CPU first")
        if func is torch.Tensor.cpu:
            out = func(*args, **kwargs)
            return _mark(out.clone(), False) if out is args[0] and on_gpu(out) else out
        if func is torch.autograd.grad:  # across devices, as CUDA's: each gradient where its input is
            inputs = kwargs.get("inputs", args[1] if len(args) > 1 else None)
            inputs = [inputs] if isinstance(inputs, torch.Tensor) else list(inputs)
            grads = func(*args, **kwargs)
            for g, x in zip(grads, inputs):
                if g is not None:
                    g._on_fake_gpu = on_gpu(x)
            return grads
        leaves = [t for t in tree_flatten((args, kwargs))[0] if isinstance(t, torch.Tensor)]
        target = _target(func, args, kwargs) if func in _FACTORIES or name in _MOVES else None
        if target is not None:
            if "device" in kwargs:
                kwargs["device"] = CPU
            args = tuple(CPU if i and _is_gpu(a) else a for i, a in enumerate(args))
            out = func(*args, **kwargs)
            if any(out is t for t in leaves) and on_gpu(out) != (target.type == "cuda"):
                out = out.clone()  # a real move copies
            return _mark(out, target.type == "cuda")
        gpu = any(on_gpu(t) for t in leaves)
        if gpu and name not in _NO_DATA:
            if name in ("__getitem__", "__setitem__"):  # CPU index tensors are fine on CUDA
                values = leaves[2:] if name == "__setitem__" else []
                if not on_gpu(args[0]) or any(not on_gpu(t) and t.dim() > 0 for t in values):
                    raise DeviceMismatch(f"{name}: tensors on cuda:0 and on cpu")
            else:
                cpu = [t for t in leaves if not on_gpu(t) and t.dim() > 0]  # CPU scalars are fine
                if cpu:
                    raise DeviceMismatch(
                        f"{name}: expected all tensors on one device, found cuda:0 and cpu "
                        f"(a cpu tensor of shape {tuple(cpu[0].shape)})"
                    )
        out = func(*args, **kwargs)
        if gpu and name != "__setitem__":
            _mark(out, True)
        return out


class _IsGenerator(type):
    def __instancecheck__(cls, obj: Any) -> bool:
        return isinstance(obj, _Generator)


class _CPUGenerator(metaclass=_IsGenerator):
    """``torch.Generator(device=...)`` on the pretend GPU: a CPU generator."""

    def __new__(cls, device: Any = None) -> Any:  # type: ignore[misc]
        return _Generator()


@contextlib.contextmanager
def fake_gpu(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """CUDA "available" with one GPU, whose generators draw on the CPU (the same numbers as the CPU's)."""
    monkeypatch.setattr(torch.cuda, "is_available", lambda: True)
    monkeypatch.setattr(torch.cuda, "device_count", lambda: 1)
    monkeypatch.setattr(torch.cuda, "current_device", lambda: 0)
    monkeypatch.setattr(torch, "Generator", _CPUGenerator)
    with FakeGPU():
        yield
    monkeypatch.undo()


# -- devices ---------------------------------------------------------------------------------------------


def test_resolve_device_accepts_the_cpu_and_names_what_it_refuses():
    assert resolve_device(None) == resolve_device("cpu") == resolve_device(torch.device("cpu")) == CPU
    with pytest.raises(ConfigError, match=r"^device tpu9: unknown device; expected cpu, cuda or cuda:N"):
        resolve_device("tpu9")
    with pytest.raises(ConfigError, match="^--device meta: unknown device"):
        resolve_device("meta", "--device")


@pytest.mark.skipif(HAS_CUDA, reason="this machine has CUDA")
def test_cuda_without_cuda_is_a_clear_error():
    with pytest.raises(ConfigError) as e:
        resolve_device("cuda")
    assert str(e.value) == f"device cuda: {NO_CUDA}"
    scene = ss.Scene([ss.SceneObject("a", "box", (0.1, 0.1), (0.0, 0.0, 0.0))])
    with pytest.raises(ConfigError, match="CUDA is not available"):
        ss.Problem(scene, Bounds(), movable=["a"], device="cuda")


def test_cpu_random_numbers_are_those_of_a_plain_generator():
    a = draw("rand", (3, 4), generator(5), CPU, torch.float64)
    assert torch.equal(a, torch.rand(3, 4, generator=torch.Generator().manual_seed(5), dtype=torch.float64))
    b = draw("randn", (7,), generator(6), CPU)
    assert torch.equal(b, torch.randn(7, generator=torch.Generator().manual_seed(6)))
    lo, hi = torch.tensor([-1.0, -2.0]), torch.tensor([1.0, 2.0])
    u = uniform_init((4, 2), lo, hi, generator(1))
    v = torch.rand(4, 2, 3, generator=torch.Generator().manual_seed(1))
    assert torch.equal(u[..., 0], -1.0 + v[..., 0] * 2.0)


def test_the_pretend_gpu_catches_what_cuda_would():
    mp = pytest.MonkeyPatch()
    with fake_gpu(mp):
        x = torch.zeros(3, device="cuda")
        assert x.device == GPU and (x + 1).device == GPU and x.cpu().device == CPU
        with pytest.raises(DeviceMismatch, match="found cuda:0 and cpu"):
            x + torch.ones(3)
        with pytest.raises(DeviceMismatch, match="numpy"):
            np.asarray(x)
        assert float((x + torch.tensor(2.0))[0]) == 2.0  # CPU scalars mix, as on CUDA


# -- the command line ------------------------------------------------------------------------------------


@pytest.mark.parametrize("command", ["train", "place", "solve", "compare", "experiment"])
@pytest.mark.parametrize("device", ["cuda", "tpu9"])
def test_device_errors_are_one_line_before_any_work(command, device, tmp_path, capsys):
    if device == "cuda" and HAS_CUDA:
        pytest.skip("this machine has CUDA")
    none = str(tmp_path / "none")  # no file is read: the device is checked first
    argv = {
        "train": ["train", none + ".jsonl", "--out", str(tmp_path / "m.ckpt")],
        "place": ["place", none + ".ckpt", none + ".json"],
        "solve": ["solve", none + ".yaml"],
        "compare": ["compare", none + ".yaml"],
        "experiment": ["experiment", "missing", "--quick", "--out", str(tmp_path / "x")],
    }[command]
    assert main([*argv, "--device", device]) == 2
    err = capsys.readouterr().err
    why = NO_CUDA if device == "cuda" else "unknown device; expected cpu, cuda or cuda:N (a GPU's index)"
    assert err == f"scenescore {command}: error: --device {device}: {why}\n"
    assert not (tmp_path / "x").exists()


@pytest.fixture(scope="module")
def files(tmp_path_factory):
    torch.set_num_threads(1)
    d = tmp_path_factory.mktemp("device")
    assert main(["generate", "dining", "--n", "3", "--out", str(d / "data.jsonl"), "--seed", "1"]) == 0
    train = [
        "train",
        "--members",
        "1",
        str(d / "data.jsonl"),
        "--iterations",
        "2",
        "--val",
        "0",
        "--quiet",
        "--force",
    ]
    assert main([*train, "--out", str(d / "m.ckpt"), "--device", "cpu"]) == 0
    scene = json.loads((d / "data.jsonl").read_text().splitlines()[0])
    scene["objects"][1]["pose"] = None
    (d / "q.json").write_text(json.dumps(scene))
    (d / "p.yaml").write_text(
        "scene: q.json\nmodel: m.ckpt\ncosts:\n  - {type: energy}\n  - {type: collision, weight: 10}\n"
        "  - {type: bounds, weight: 10}\nsolver: langevin>alm\n"
        "options:\n  langevin: {particles: 8, steps: 5}\n  alm: {iterations: 3}\nseed: 0\n"
    )
    return d


def test_device_cpu_is_the_default(files, capsys):
    d = files
    assert ss.models.load(d / "m.ckpt").device == CPU
    place = ["place", str(d / "m.ckpt"), str(d / "q.json"), "--particles", "8", "--quiet"]
    assert main([*place, "--out", str(d / "a.json"), "--device", "cpu"]) == 0
    assert main([*place, "--out", str(d / "b.json")]) == 0
    assert json.loads((d / "a.json").read_text()) == json.loads((d / "b.json").read_text())
    solve = ["solve", str(d / "p.yaml"), "--quiet"]
    assert main([*solve, "--out", str(d / "a.result.json"), "--device", "cpu"]) in (0, 1)  # 1: infeasible
    assert main([*solve, "--out", str(d / "b.result.json")]) in (0, 1)
    a, b = (json.loads((d / f"{k}.result.json").read_text()) for k in "ab")
    assert a["poses"] == b["poses"] and a["objective"] == b["objective"]
    compare = ["compare", str(d / "p.yaml"), "--solvers", "langevin>alm", "--seeds", "1"]
    assert main([*compare, "--quiet", "--device", "cpu"]) == 0
    assert "| langevin>alm |" in capsys.readouterr().out


# -- the library on the pretend GPU ----------------------------------------------------------------------


def _run(device: str, scenes: list[ss.Scene], tmp: Path) -> dict[str, Any]:
    """Train, save and load, place, and solve with every solver on ``device``: the numbers."""
    from scenescore.learn import TrainConfig, fit, heldout_loss
    from scenescore.planning.placement import PLACE, place
    from scenescore.solvers.compare import compare
    from scenescore.solvers.kernel import PLACEMENT

    out: dict[str, Any] = {}
    cfg = TrainConfig(members=1, iterations=2, batch_scenes=2, negatives=2, perturbed=1, chain_steps=2)
    model = fit(scenes[:3], cfg, seed=5, progress=False, validation=scenes[3:], device=device)
    assert model.device == (CPU if device == "cpu" else GPU)
    model.save(tmp / f"{device}.ckpt")
    model = ss.models.load(tmp / f"{device}.ckpt", device=device)
    out["weights"] = torch.cat([p.detach().cpu().flatten() for p in model.net.parameters()]).tolist()
    out["heldout"] = heldout_loss(model, scenes[3:], negatives=2, seed=2)
    q = scenes[4].without(scenes[4].objects[1].name)
    short = replace(PLACE, particles=4, candidates=8, chain=replace(PLACEMENT, steps=3, final_descent=2))
    out["place"] = place(model, q, short, seed=3).poses().tolist()
    s = scenes[4].copy()
    s.objects[1].pose = None
    cost = (
        LearnedEnergy(model)
        + 10.0 * HingeCollision(margin=0.01)
        + 10.0 * Bounds()
        + 10.0 * ReachLimit(base=(0.0, -0.7), radius=1.2)
        + 0.1 * Displacement(objects=[s.objects[2].name])
    )
    prob = ss.Problem(s, cost, movable=[s.objects[1].name, s.objects[2].name])
    assert prob.device == model.device
    opts = {
        "langevin": {"particles": 4, "steps": 3, "final_descent": 1, "candidates": 8, "resample": 1},
        "alm": {"iterations": 2},
        "osqp": {"max_iter": 2},
        "casadi": {"max_iter": 2, "energy": "callback"},
    }
    for solver in ["langevin>alm", "langevin>osqp", "langevin>casadi"]:
        r = ss.solve(prob, solver, seed=7, options=opts)
        assert isinstance(r.poses, np.ndarray) and isinstance(r.samples, np.ndarray)
        out[solver] = [r.poses.tolist(), r.samples.tolist(), r.objective, r.feasible]
    qp = {"langevin": {"particles": 2, "steps": 2, "final_descent": 0, "projection": "qp"}}
    out["qp"] = ss.solve(prob, "langevin", seed=1, options=qp).samples.tolist()  # type: ignore[union-attr]
    cmp = compare(prob, ["langevin"], seeds=[0], options=opts)
    out["compare"] = [row["objective"] for row in cmp.rows]
    return out


def test_train_place_and_solve_on_a_pretend_gpu_give_the_cpus_numbers(tmp_path):
    torch.set_num_threads(1)
    scenes = ss.scenarios.get("dining").generate(5, 3)
    cpu = _run("cpu", scenes, tmp_path)
    mp = pytest.MonkeyPatch()
    with fake_gpu(mp):
        gpu = _run("cuda", scenes, tmp_path)
    assert gpu == cpu


def test_a_learned_energy_runs_where_its_model_is(tmp_path):
    from scenescore.learn import TrainConfig, fit

    scenes = ss.scenarios.get("dining").generate(4, 0)
    mp = pytest.MonkeyPatch()
    with fake_gpu(mp):
        model = fit(scenes, TrainConfig(members=1, iterations=1, negatives=2), progress=False, device="cuda")
        q = scenes[0].copy()
        q.objects[0].pose = None
        assert ss.Problem(q, LearnedEnergy(model)).device == GPU  # the model's device by default
        with pytest.raises(CostError, match="the model is on cuda:0, the problem on cpu"):
            ss.Problem(q, LearnedEnergy(model), device="cpu")
