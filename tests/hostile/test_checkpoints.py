"""Hostile checkpoints: pickles and other formats refused, damaged metadata and weights named by key,
each a :class:`CheckpointError` naming the file; nothing is ever unpickled."""

from __future__ import annotations

import json
import pickle

import pytest
import torch
from safetensors import safe_open
from safetensors.torch import save_file

from scenescore.models import CheckpointError, load

from .helpers import expect, write


@pytest.fixture(scope="module")
def parts(model_path):
    with safe_open(str(model_path), "pt") as f:
        return dict(f.metadata()), {k: f.get_tensor(k) for k in f.keys()}


def _meta(meta, key, value):
    return {**meta, key: value}


def _json(meta, key, **changes):
    d = json.loads(meta[key])
    for k, v in changes.items():
        if v is ...:
            d.pop(k, None)
        else:
            d[k] = v
    return {**meta, key: json.dumps(d)}


META = [
    (
        "format missing",
        lambda m: {k: v for k, v in m.items() if k != "format"},
        ("not a scenescore checkpoint",),
    ),
    ("format other", lambda m: _meta(m, "format", "keras"), ("'keras'",)),
    ("version 2", lambda m: _meta(m, "format_version", "2"), ("version '2'",)),
    ("version missing", lambda m: {k: v for k, v in m.items() if k != "format_version"}, ("version None",)),
    ("energy_config not JSON", lambda m: _meta(m, "energy_config", "{oops"), ("damaged",)),
    ("energy_config a list", lambda m: _meta(m, "energy_config", "[]"), ("damaged",)),
    ("energy_config missing", lambda m: {k: v for k, v in m.items() if k != "energy_config"}, ("damaged",)),
    ("hidden negative", lambda m: _json(m, "energy_config", hidden=-4), ("energy_config", "hidden", ">= 1")),
    ("hidden a string", lambda m: _json(m, "energy_config", hidden="8"), ("energy_config", "hidden")),
    ("hidden a float", lambda m: _json(m, "energy_config", hidden=8.5), ("energy_config", "hidden")),
    ("layers 0", lambda m: _json(m, "energy_config", layers=0), ("energy_config", "layers")),
    (
        "length_scale NaN",
        lambda m: _json(m, "energy_config", length_scale=float("nan")),
        ("energy_config", "length_scale"),
    ),
    (
        "activation unknown",
        lambda m: _json(m, "energy_config", activation="gelu"),
        ("energy_config", "activation"),
    ),
    ("energy_config unknown key", lambda m: _json(m, "energy_config", depth=3), ("energy_config", "depth")),
    ("feat_dim missing", lambda m: _json(m, "energy_config", feat_dim=...), ("energy_config", "feat_dim")),
    ("encoder missing", lambda m: {k: v for k, v in m.items() if k != "encoder"}, ("damaged",)),
    ("encoder without name", lambda m: _meta(m, "encoder", "{}"), ("'name'",)),
    ("encoder name a number", lambda m: _meta(m, "encoder", json.dumps({"name": 3})), ("unknown encoder 3",)),
    ("encoder unknown", lambda m: _meta(m, "encoder", json.dumps({"name": "resnet"})), ("'resnet'",)),
    (
        "encoder config a list",
        lambda m: _meta(m, "encoder", json.dumps({"name": "footprint", "config": [1]})),
        ("encoder config",),
    ),
    (
        "encoder of another width",
        lambda m: _meta(m, "encoder", json.dumps({"name": "image"})),
        ("'image'", "expects"),
    ),
    ("info a list", lambda m: _meta(m, "info", "[1]"), ("info",)),
    ("info not JSON", lambda m: _meta(m, "info", "{"), ("damaged",)),
    ("trust a string", lambda m: _meta(m, "info", json.dumps({"trust": "high"})), ("info.trust",)),
    (
        "trust missing fields",
        lambda m: _meta(m, "info", json.dumps({"trust": {"energies": [1.0]}})),
        ("info.trust",),
    ),
    (
        "trust energies NaN",
        lambda m: _meta(
            m,
            "info",
            json.dumps(
                {
                    "trust": {
                        "energies": [float("nan")],
                        "length_scale": 0.1,
                        "nearest": {},
                        "nearest_any": 1.0,
                        "touches_bounds": [],
                    }
                }
            ),
        ),
        ("info.trust", "energies"),
    ),
]


@pytest.mark.parametrize("label,edit,names", META, ids=[m[0] for m in META])
def test_checkpoint_metadata(tmp_path, parts, label, edit, names):
    meta, tensors = parts
    p = tmp_path / "bad.ckpt"
    save_file(tensors, str(p), metadata=edit(meta))
    expect(lambda: load(p), CheckpointError, str(p), *names)


def _first(t):
    return sorted(t)[0]


def _set(tensors, key, fn):
    out = dict(tensors)
    out[key] = fn(tensors[key].clone())
    return out


def _poke(value):
    def fn(t):
        t.view(-1)[0] = value
        return t

    return fn


WEIGHTS = [
    ("NaN weight", lambda t: _set(t, _first(t), _poke(float("nan"))), ("holds NaN",)),
    ("inf weight", lambda t: _set(t, _first(t), _poke(float("inf"))), ("holds NaN",)),
    ("weight missing", lambda t: {k: v for k, v in t.items() if k != _first(t)}, ("do not match",)),
    ("weight extra", lambda t: {**t, "zz.extra": torch.zeros(2)}, ("'zz.extra'",)),
    (
        "weight of the wrong shape",
        lambda t: _set(t, _first(t), lambda x: torch.zeros(x.numel() + 1)),
        ("do not match",),
    ),
    ("no weights at all", lambda t: {"x": torch.zeros(1)}, ("do not match",)),
]


@pytest.mark.parametrize("label,edit,names", WEIGHTS, ids=[w[0] for w in WEIGHTS])
def test_checkpoint_weights(tmp_path, parts, label, edit, names):
    meta, tensors = parts
    p = tmp_path / "bad.ckpt"
    save_file(edit(tensors), str(p), metadata=meta)
    msg = expect(lambda: load(p), CheckpointError, str(p), *names)
    if "NaN" in label or "inf" in label:
        assert repr(_first(tensors)) in msg  # the weight is named


def _pickle_payload():
    class Boom:
        def __reduce__(self):
            return (print, ("pickle executed",))

    return pickle.dumps(Boom())


FILES = [
    ("a pickle that would run code", _pickle_payload(), ("not a scenescore checkpoint",)),
    ("a pickled dict", pickle.dumps({"a": 1}), ("not a scenescore checkpoint",)),
    ("empty file", b"", ("not a scenescore checkpoint",)),
    ("text", b"hello world, not weights\n", ("not a scenescore checkpoint",)),
    (
        "header length beyond the file",
        (10**9).to_bytes(8, "little") + b"{}",
        ("not a scenescore checkpoint",),
    ),
    ("header not JSON", (4).to_bytes(8, "little") + b"{{{{", ("not a scenescore checkpoint",)),
]


@pytest.mark.parametrize("label,data,names", FILES, ids=[f[0] for f in FILES])
def test_checkpoint_files(tmp_path, capsys, label, data, names):
    p = write(tmp_path / "bad.ckpt", data)
    expect(lambda: load(p), CheckpointError, str(p), *names)
    assert "pickle executed" not in capsys.readouterr().out


def test_torch_save_file_is_refused(tmp_path):
    p = tmp_path / "t.ckpt"
    torch.save({"w": torch.zeros(2)}, p)
    expect(lambda: load(p), CheckpointError, str(p), "not a scenescore checkpoint")


def test_checkpoint_path_is_a_folder(tmp_path):
    expect(lambda: load(tmp_path), CheckpointError, str(tmp_path), "folder")


def test_checkpoint_path_missing(tmp_path):
    expect(lambda: load(tmp_path / "none.ckpt"), CheckpointError, "none.ckpt", "no such")


def test_truncated_checkpoint(tmp_path, model_path):
    data = model_path.read_bytes()
    p = write(tmp_path / "cut.ckpt", data[: len(data) // 2])
    expect(lambda: load(p), CheckpointError, str(p), "not a scenescore checkpoint")


def test_float64_weights_load_as_the_model_dtype(tmp_path, parts):
    meta, tensors = parts
    p = tmp_path / "f64.ckpt"
    save_file({k: v.double() for k, v in tensors.items()}, str(p), metadata=meta)
    assert load(p).dtype == torch.float32


@pytest.mark.parametrize("dtype", [torch.int8, torch.int64, torch.bool, torch.uint8])
def test_non_floating_weights_are_refused(tmp_path, parts, dtype):
    """Quantised or damaged weights (integers, booleans) are named, not cast into the network silently."""
    from scenescore.models.checkpoint import write_checkpoint

    meta, tensors = parts
    p = tmp_path / "int.ckpt"
    config, encoder, info = (json.loads(meta[k]) for k in ("energy_config", "encoder", "info"))
    write_checkpoint(p, {k: v.to(dtype) for k, v in tensors.items()}, config, encoder, info)
    kind = str(dtype).removeprefix("torch.")
    msg = expect(lambda: load(p), CheckpointError, str(p))
    assert msg == f"{p}: weight {_first(tensors)!r} is {kind}, expected a floating-point tensor"


@pytest.mark.parametrize("umask,mode", [(0o022, 0o644), (0o077, 0o600)])
def test_saved_checkpoint_follows_the_umask(tmp_path, umask, mode):
    import os

    from scenescore.encoders import make_encoder
    from scenescore.models import ScoreModel

    old = os.umask(umask)
    try:
        ScoreModel.create(make_encoder("footprint"), hidden=4, embed_dim=4).save(tmp_path / "m.ckpt")
    finally:
        os.umask(old)
    assert (tmp_path / "m.ckpt").stat().st_mode & 0o777 == mode
    assert not [p for p in tmp_path.iterdir() if p.name != "m.ckpt"]  # no temporary file left
