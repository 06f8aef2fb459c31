"""The energy network: invariances, gradients, checkpoints, determinism."""

import math

import pytest
import torch

from scenescore.encoders import FootprintEncoder
from scenescore.models import CheckpointError, ModelInfo, ScoreModel, TidyCalibration, load
from scenescore.models.network import EnergyConfig, EnergyNet
from scenescore.scenarios import DiningScenario

pytestmark = pytest.mark.float_order


def _model(**kw):
    torch.manual_seed(0)
    return ScoreModel.create(FootprintEncoder(), hidden=16, embed_dim=8, layers=2, **kw)


def _rigid(poses, angle, shift):
    c, s = math.cos(angle), math.sin(angle)
    rot = torch.tensor([[c, -s], [s, c]], dtype=poses.dtype)
    xy = poses[..., :2] @ rot.T + torch.tensor(shift, dtype=poses.dtype)
    return torch.cat([xy, poses[..., 2:] + angle], dim=-1)


@pytest.mark.parametrize("message", ["mlp", "linear"])
@pytest.mark.parametrize("activation", ["silu", "leaky_relu"])
def test_energy_invariant_to_rigid_motion_and_permutation(message, activation):
    model = _model(message=message, activation=activation)
    scene = DiningScenario().generate(1, seed=0)[0]
    st = model.tensors([scene])
    x = st.poses.double()
    model.net.double()
    st = model.tensors([scene])
    e0 = model.energy(x, st)
    for angle, shift in [(0.7, (0.3, -0.2)), (-2.5, (1.0, 2.0)), (math.pi, (0.0, 0.0))]:
        assert torch.allclose(model.energy(_rigid(x, angle, shift), st), e0, atol=1e-10)
    perm = torch.randperm(len(scene), generator=torch.Generator().manual_seed(1))
    st_p = model.tensors([scene])
    st_p.feats, st_p.sizes = st.feats[:, perm], st.sizes[:, perm]
    assert torch.allclose(model.energy(x[:, perm], st_p), e0, atol=1e-10)
    # and it does depend on the arrangement
    x2 = x.clone()
    x2[0, 1, :2] += 0.1
    assert not torch.allclose(model.energy(x2, st), e0, atol=1e-6)


@pytest.mark.parametrize("message", ["mlp", "linear"])
@pytest.mark.parametrize("activation", ["silu", "softplus", "leaky_relu"])
@pytest.mark.parametrize("neighbours", [None, 3])
def test_energy_without_a_gradient_is_the_energy_with_one_and_leaves_its_inputs_alone(
    message, activation, neighbours
):
    # without a gradient the message layers work in place: the same operations in the same order
    local = {} if neighbours is None else {"neighbours": neighbours, "radius": 3.0}
    torch.manual_seed(0)
    net = EnergyNet(
        EnergyConfig(feat_dim=5, hidden=16, embed_dim=8, message=message, activation=activation, **local)
    ).double()
    g = torch.Generator().manual_seed(2)
    poses = torch.rand(4, 7, 3, generator=g, dtype=torch.float64) * 2
    feats = torch.randn(4, 7, 5, generator=g, dtype=torch.float64)
    sizes = 0.1 + 0.2 * torch.rand(4, 7, 2, generator=g, dtype=torch.float64)
    mask = torch.ones(4, 7, dtype=torch.bool)
    mask[1, 5:] = False
    inputs = [t.clone() for t in (poses, feats, sizes, mask)]
    with torch.no_grad():
        e_plain = net(poses, feats, sizes, mask)
    e_grad = net(poses.clone().requires_grad_(True), feats, sizes, mask)
    assert torch.equal(e_plain, e_grad.detach())
    assert all(torch.equal(a, b) for a, b in zip(inputs, (poses, feats, sizes, mask)))


def test_abs_ablation_is_permutation_but_not_rigid_invariant():
    model = _model(absolute=True)
    model.net.double()
    scene = DiningScenario().generate(1, seed=0)[0]
    st = model.tensors([scene])
    x = st.poses
    e0 = model.energy(x, st)
    perm = torch.tensor([3, 1, 0, 2, 7, 6, 5, 4])
    st_p = model.tensors([scene])
    st_p.feats, st_p.sizes = st.feats[:, perm], st.sizes[:, perm]
    assert torch.allclose(model.energy(x[:, perm], st_p), e0, atol=1e-10)
    assert not torch.allclose(model.energy(_rigid(x, 0.7, (0.3, -0.2)), st), e0, atol=1e-6)


def test_padding_does_not_change_energy():
    model = _model()
    model.net.double()
    small, big = DiningScenario(settings=1).generate(1, 0)[0], DiningScenario().generate(1, 1)[0]
    st = model.tensors([small, big])
    alone = model.tensors([small])
    assert torch.allclose(model.energy(st.poses[:1, : len(small)], alone), model.energy(st.poses, st)[:1])


def test_energy_gradient_gradcheck_float64():
    model = _model()
    model.net.double()
    scene = DiningScenario().generate(1, seed=2)[0]
    fn = model.energy_fn(scene)
    x = model.tensors([scene]).poses.repeat(2, 1, 1).clone().requires_grad_(True)
    assert torch.autograd.gradcheck(fn, (x,), eps=1e-6, atol=1e-6)


def test_checkpoint_round_trip(tmp_path):
    model = _model(activation="softplus")
    scene = DiningScenario().generate(1, seed=0)[0]
    st = model.tensors([scene])
    path = tmp_path / "m.ckpt"
    model.info = ModelInfo(seed=3, extra={"note": "hello"})
    model.save(path)
    back = load(path)
    assert back.config == model.config and back.info == model.info and back.info.extra == {"note": "hello"}
    assert torch.equal(back.energy(st.poses, st), model.energy(st.poses, st))
    assert not list(tmp_path.glob(".*tmp"))  # the temporary file was renamed away


def test_checkpoint_refuses_unknown_version_and_garbage(tmp_path):
    from safetensors.torch import save_file

    model = _model()
    path = tmp_path / "future.ckpt"
    model.save(path)
    from safetensors import safe_open

    with safe_open(str(path), "pt") as f:
        meta, tensors = f.metadata(), {k: f.get_tensor(k) for k in f.keys()}
    meta["format_version"] = "99"
    save_file(tensors, str(path), metadata=meta)
    with pytest.raises(CheckpointError, match="format version '99' is not supported"):
        load(path)
    (tmp_path / "junk.ckpt").write_bytes(b"not a checkpoint at all")
    with pytest.raises(CheckpointError, match="junk.ckpt: not a scenescore checkpoint"):
        load(tmp_path / "junk.ckpt")
    with pytest.raises(CheckpointError, match="no such checkpoint"):
        load(tmp_path / "nope.ckpt")


def test_failed_save_keeps_previous_file(tmp_path, monkeypatch):
    model = _model()
    path = tmp_path / "m.ckpt"
    model.save(path)
    before = path.read_bytes()
    import os

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(os, "replace", boom)
    with pytest.raises(OSError):
        model.save(path)
    assert path.read_bytes() == before


@pytest.mark.parametrize("absolute", [False, True])
def test_round_objects_headings_are_ignored(absolute):
    model = _model(round_invariant=True, absolute=absolute)
    model.net.double()
    scene = DiningScenario().generate(1, seed=0)[0]  # plates and bowls are round, forks and knives not
    st = model.tensors([scene])
    assert st.round[0].tolist() == [o.round for o in scene.objects] and st.round.any() and not st.round.all()
    x = st.poses.double()
    e0 = model.energy(x, st)
    g = torch.Generator().manual_seed(3)
    turned = x.clone()
    turned[0, st.round[0], 2] = torch.rand(int(st.round.sum()), generator=g, dtype=x.dtype) * 6 - 3
    assert torch.allclose(model.energy(turned, st), e0, atol=1e-10)
    fork = x.clone()
    fork[0, 1, 2] += 0.5  # fork_0 has a heading
    assert not torch.allclose(model.energy(fork, st), e0, atol=1e-6)
    if not absolute:
        for angle, shift in [(0.7, (0.3, -0.2)), (math.pi, (0.0, 0.0))]:
            assert torch.allclose(model.energy(_rigid(x, angle, shift), st), e0, atol=1e-10)
    # without the option the same network reads the round objects' headings
    plain = _model(absolute=absolute)
    plain.net.double()
    assert not torch.allclose(plain.energy(turned, st), plain.energy(x, st), atol=1e-6)


def test_round_invariant_gradcheck_float64():
    model = _model(round_invariant=True)
    model.net.double()
    scene = DiningScenario().generate(1, seed=2)[0]
    fn = model.energy_fn(scene)
    x = model.tensors([scene]).poses.double().repeat(2, 1, 1)
    x[1, 3, :2] = x[1, 0, :2]  # a bowl on its plate's centre: two round objects at one point
    x.requires_grad_(True)
    assert torch.autograd.gradcheck(fn, (x,), eps=1e-6, atol=1e-6)


def _tamper(path, meta_edit=None, tensor_edit=None):
    """Rewrite a checkpoint with its metadata or tensors changed (as a hostile or damaged file would be)."""
    import json

    from safetensors import safe_open
    from safetensors.torch import save_file

    with safe_open(str(path), "pt") as f:
        meta, tensors = f.metadata(), {k: f.get_tensor(k) for k in f.keys()}
    if meta_edit:
        for key, edit in meta_edit.items():
            value = json.loads(meta[key])
            meta[key] = json.dumps(edit(value))
    if tensor_edit:
        tensor_edit(tensors)
    save_file(tensors, str(path), metadata=meta)


def _set(d, **kw):
    return {**d, **kw}


@pytest.mark.parametrize(
    "meta_edit, needle",
    [
        ({"energy_config": lambda c: _set(c, hidden=-3)}, "hidden"),
        ({"energy_config": lambda c: _set(c, hidden=200_000)}, "hidden"),
        ({"energy_config": lambda c: _set(c, hidden=64)}, "do not match"),  # a legal width, other weights
        ({"energy_config": lambda c: _set(c, layers="three")}, "layers"),
        ({"energy_config": lambda c: _set(c, length_scale=float("nan"))}, "length_scale"),
        ({"energy_config": lambda c: _set(c, activation="gelu")}, "activation"),
        ({"energy_config": lambda c: _set(c, colour="red")}, "colour"),
        ({"encoder": lambda e: _set(e, name="nonesuch")}, "nonesuch"),
        ({"encoder": lambda e: _set(e, config={"bogus": 1})}, "bogus"),
        ({"encoder": lambda e: _set(e, config=[1, 2])}, "encoder config"),
    ],
)
def test_damaged_checkpoint_metadata_is_one_error_naming_the_file(tmp_path, meta_edit, needle):
    path = tmp_path / "m.ckpt"
    _model().save(path)
    _tamper(path, meta_edit=meta_edit)
    with pytest.raises(CheckpointError) as e:
        load(path)
    assert str(path) in str(e.value) and needle in str(e.value)


@pytest.mark.parametrize("value", [float("nan"), float("inf")])
def test_non_finite_weights_are_refused(tmp_path, value):
    path = tmp_path / "m.ckpt"
    _model().save(path)
    name = []

    def poison(t):
        name.append(sorted(t)[0])
        t[name[0]] = (
            t[name[0]].clone().reshape(-1).index_fill(0, torch.tensor([0]), value).reshape(t[name[0]].shape)
        )

    _tamper(path, tensor_edit=poison)
    with pytest.raises(CheckpointError, match=f"weight '{name[0]}' holds NaN or infinite"):
        load(path)


def test_model_info_reads_every_stored_key_and_writes_it_back(tmp_path):
    """A checkpoint's ``info`` as training, validation and tidy's calibration store it: read into named
    fields (the trust reference and the calibration typed), written back as the same JSON object, keys
    this version does not know kept; a checkpoint with none of them loads with every field None."""
    from scenescore.models.checkpoint import read_checkpoint, write_checkpoint
    from scenescore.models.trust import reference

    model = _model()
    scenes = DiningScenario().generate(3, seed=0)
    stored = {
        "train_config": {"iterations": 5, "model": {"hidden": 16}},
        "seed": 1,
        "scenes": 3,
        "final_loss": 1.5,
        "chance_loss": 2.8,
        "seconds": 0.5,
        "history": [2.0, 1.5],
        "trust": reference(model, scenes).to_dict(),
        "validation": {"mean_t_cm": 3.0},
        "tidy": {"move_gain": 0.5},
        "note": "hello",
    }
    path = tmp_path / "m.ckpt"
    write_checkpoint(path, model.net.state_dict(), model.config.to_dict(), {"name": "footprint"}, stored)
    back = load(path)
    assert back.info.seed == 1 and back.info.history == [2.0, 1.5] and back.info.extra == {"note": "hello"}
    assert (
        back.trust is back.info.trust and back.trust is not None and back.trust.to_dict() == stored["trust"]
    )
    assert back.info.tidy == TidyCalibration(move_gain=0.5)
    assert back.info.to_dict() == stored
    again = tmp_path / "again.ckpt"
    back.save(again)
    assert read_checkpoint(again).info == stored
    assert "trust" not in back.info.training() and back.info.training()["seed"] == 1
    write_checkpoint(path, model.net.state_dict(), model.config.to_dict(), {"name": "footprint"}, {})
    bare = load(path).info
    assert bare == ModelInfo() and bare.trust is None and bare.tidy is None and bare.to_dict() == {}
