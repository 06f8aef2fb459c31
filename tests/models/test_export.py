"""ONNX export of the energy: onnxruntime gives torch's energies for any batch size and object count,
the embedding graph gives the same nodes, and ``scenescore export`` writes the file or fails in one line."""

import json
import sys

import numpy as np
import pytest
import torch

onnx = pytest.importorskip("onnx")
ort = pytest.importorskip("onnxruntime")

from scenescore.cli import main  # noqa: E402
from scenescore.encoders import FootprintEncoder  # noqa: E402
from scenescore.learn import NetworkConfig, TrainConfig, fit  # noqa: E402
from scenescore.models import ScoreModel  # noqa: E402
from scenescore.models.ensemble import EnsembleNet  # noqa: E402
from scenescore.models.export import (  # noqa: E402
    energy_inputs,
    export_embedding_onnx,
    export_onnx,
    node_embeddings,
    scene_inputs,
)
from scenescore.models.network import EnergyNet  # noqa: E402
from scenescore.scenarios import get  # noqa: E402

TOL = 1e-4
CPU = ["CPUExecutionProvider"]


@pytest.fixture(scope="module")
def trained(tmp_path_factory):
    """A tiny model trained on bedrooms (5 to 7 objects, two round), the walls in its graph."""
    torch.set_num_threads(1)
    scenes = get("zoo-bedroom").generate(6, seed=0)
    cfg = TrainConfig(
        members=1,
        iterations=3,
        batch_scenes=4,
        negatives=4,
        walls=True,
        network=NetworkConfig(hidden=16, layers=2),
    )
    model = fit(scenes, cfg, seed=0, progress=False)
    d = tmp_path_factory.mktemp("export")
    model.save(d / "m.ckpt")
    scenes[0].to_json(d / "scene.json")
    return model, d


def _test_scenes():
    scenes = get("zoo-bedroom").generate(3, seed=0)
    assert len({len(s) for s in scenes}) == 2  # two object counts
    return scenes


def _poses(scene, b, rng):
    (x0, y0), (x1, y1) = scene.bounds
    n = len(scene)
    p = [rng.uniform(x0, x1, (b, n)), rng.uniform(y0, y1, (b, n)), rng.uniform(-np.pi, np.pi, (b, n))]
    return np.stack(p, -1).astype(np.float32)


def _max_diff(model, path, scenes, embed_path=None):
    sess = ort.InferenceSession(str(path), providers=CPU)
    embed = ort.InferenceSession(str(embed_path), providers=CPU) if embed_path else None
    rng = np.random.default_rng(0)
    worst = 0.0
    for scene in scenes:
        inputs = scene_inputs(model, scene)
        if embed is not None:
            st = model.tensors([scene])
            (nodes,) = embed.run(None, {"feats": st.feats[0].numpy(), "sizes": st.sizes[0].numpy()})
            assert np.abs(nodes - inputs.nodes).max() < 1e-5
            inputs.nodes = nodes
        for b in (1, 6):
            poses = _poses(scene, b, rng)
            (got,) = sess.run(None, inputs.feeds(poses))
            with torch.no_grad():
                want = model.energy_fn(scene)(torch.from_numpy(poses)).numpy()
            assert got.shape == (b,)
            worst = max(worst, float(np.abs(got - want).max()))
    return worst


def test_onnx_matches_torch_for_any_batch_and_object_count(trained, tmp_path):
    model, _ = trained
    path = export_onnx(model, tmp_path / "energy.onnx")
    embed = export_embedding_onnx(model, tmp_path / "embedding.onnx")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["embedding.onnx", "energy.onnx"]  # no temp left
    proto = onnx.load(str(path))
    meta = {p.key: p.value for p in proto.metadata_props}
    assert float(meta["length_scale"]) == pytest.approx(model.config.length_scale)
    assert json.loads(meta["inputs"]) == ["poses", "nodes", "round"] == [i.name for i in proto.graph.input]
    assert meta["walls"] == "true" and meta["round_invariant"] == "true"
    scenes = _test_scenes()
    assert any(o.round for o in scenes[0].objects)
    assert _max_diff(model, path, scenes, embed) < TOL
    nodes = node_embeddings(model, scenes[1])
    assert nodes.shape == (len(scenes[1]) + 4, model.config.embed_dim + 2)  # the objects and four walls


@pytest.mark.parametrize(
    "config",
    [
        {"round_invariant": False},
        {"absolute": True, "round_invariant": True, "message": "linear", "activation": "leaky_relu"},
        {"round_invariant": True, "edge_range": 3.0, "activation": "softplus"},
        {"round_invariant": True, "edge_encoder": 8},
        {"round_invariant": True, "edge_encoder": 8, "walls": True, "wall_range": 1.5},
        {"round_invariant": True, "edge_encoder": 8, "walls": True, "wall_lines": True},
    ],
)
def test_other_architectures(config, tmp_path):
    torch.manual_seed(0)
    model = ScoreModel.create(
        FootprintEncoder(), hidden=16, embed_dim=8, layers=2, length_scale=0.2, **config
    )
    model.eval()
    path = export_onnx(model, tmp_path / "e.onnx")
    assert [i.name for i in onnx.load(str(path)).graph.input] == list(energy_inputs(model))
    assert _max_diff(model, path, _test_scenes()) < TOL


def test_an_ensemble_exports_its_members_mean(trained, tmp_path):
    model, _ = trained
    torch.manual_seed(1)
    ensemble = ScoreModel(EnsembleNet([model.net, EnergyNet(model.config)]), model.encoder).eval()
    path = export_onnx(ensemble, tmp_path / "energy.onnx")
    embed = export_embedding_onnx(ensemble, tmp_path / "embedding.onnx")
    meta = {p.key: p.value for p in onnx.load(str(path)).metadata_props}
    assert meta["members"] == "2" and int(meta["embed_dim"]) == 2 * (model.config.embed_dim + 2)
    scenes = _test_scenes()
    assert _max_diff(ensemble, path, scenes, embed) < TOL
    poses = torch.from_numpy(_poses(scenes[0], 4, np.random.default_rng(1)))
    with torch.no_grad():
        assert (ensemble.energy_fn(scenes[0])(poses) - model.energy_fn(scenes[0])(poses)).abs().max() > 1e-3


def test_cli_export_and_check(trained, tmp_path, capsys):
    _, d = trained
    out = tmp_path / "sub" / "energy.onnx"
    argv = ["export", str(d / "m.ckpt"), "--onnx", str(out), "--embed-onnx", str(tmp_path / "emb.onnx")]
    assert main([*argv, "--check", str(d / "scene.json")]) == 0
    lines = capsys.readouterr().out.strip().splitlines()
    wrote = f"wrote the energy (poses, nodes, round -> energy) to {out}, the node embedding to {tmp_path}"
    assert lines[0] == wrote + "/emb.onnx"
    diff = float(lines[1].split("= ")[1].split()[0])
    assert diff < TOL and "over 17 arrangements" in lines[1]
    assert out.is_file() and (tmp_path / "emb.onnx").is_file()


def test_cli_bad_output_is_one_line(trained, tmp_path, capsys, monkeypatch):
    _, d = trained
    (tmp_path / "afile").write_text("x")
    cases = [
        (["--out", str(tmp_path / "afile" / "e.onnx")], "is a file, not a folder"),  # --onnx: the same
        (["--onnx", str(tmp_path)], "is a folder; expected a file"),
        (["--onnx", str(tmp_path / "e.onnx"), "--check", str(tmp_path / "none.json")], "no such file"),
    ]
    for extra, msg in cases:
        assert main(["export", str(d / "m.ckpt"), *extra]) == 2
        err = capsys.readouterr().err
        assert msg in err and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    monkeypatch.setitem(sys.modules, "onnx", None)  # as if not installed
    assert main(["export", str(d / "m.ckpt"), "--onnx", str(tmp_path / "e.onnx")]) == 2
    err = capsys.readouterr().err
    assert "pip install -e '.[export]'" in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "e.onnx").exists()


@pytest.mark.slow
def test_dynamo_exporter(trained, tmp_path):
    """``torch.export``'s exporter (the default of torch.onnx.export) gives the same graph's numbers."""
    pytest.importorskip("onnxscript")
    model, _ = trained
    path = export_onnx(model, tmp_path / "energy.onnx", dynamo=True)
    assert _max_diff(model, path, _test_scenes()) < TOL
