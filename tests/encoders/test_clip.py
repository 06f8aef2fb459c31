"""The CLIP encoder through the path a user's weights take: a tiny open_clip model with random weights,
built from a model config, saved to a file and loaded by ``ClipEncoder(weights=..., model_config=...)``.
Runs where the ``clip`` extra is installed (CI installs it with .ci/install_clip.sh)."""

from __future__ import annotations

import importlib.util
import json

import numpy as np
import pytest

from scenescore.encoders import make_encoder
from scenescore.scene.scene import SceneError, SceneObject

HAS_OPEN_CLIP = importlib.util.find_spec("open_clip") is not None
needs_clip = pytest.mark.skipif(
    not HAS_OPEN_CLIP,
    reason="open_clip is not installed (the 'clip' extra; CI runs bash .ci/install_clip.sh)",
)

TINY = {
    "embed_dim": 16,
    "vision_cfg": {"image_size": 32, "layers": 1, "width": 32, "head_width": 16, "patch_size": 8},
    "text_cfg": {"context_length": 16, "vocab_size": 49408, "width": 32, "heads": 2, "layers": 1},
}


@pytest.fixture(scope="module")
def tiny_clip(tmp_path_factory):
    from scenescore.encoders.clip import import_open_clip

    open_clip = import_open_clip()
    import torch

    d = tmp_path_factory.mktemp("clip")
    cfg = d / "scenescore-tiny-clip.json"
    cfg.write_text(json.dumps(TINY))
    open_clip.add_model_config(str(cfg))
    torch.manual_seed(0)
    model = open_clip.create_model("scenescore-tiny-clip", pretrained=None)
    weights = d / "tiny.pt"
    torch.save(model.state_dict(), weights)
    return model, str(weights), str(cfg)


@needs_clip
def test_clip_encoder_loads_saved_weights_and_encodes(tiny_clip):
    import torch

    model, weights, cfg = tiny_clip
    enc = make_encoder(
        "clip", {"model_name": "scenescore-tiny-clip", "weights": weights, "model_config": cfg}
    )
    assert enc.dim == 16
    for k, v in model.state_dict().items():  # the weights are the saved ones, not a fresh random draw
        assert torch.equal(enc.model.state_dict()[k], v), k
    fork = SceneObject("f", "fork", (0.19, 0.03), None, (165, 165, 180))
    plate = SceneObject("p", "plate", (0.24, 0.24), None, (240, 240, 232), shape="disk")
    vf, vp = enc.encode(fork), enc.encode(plate)
    assert vf.shape == (16,) and vf.dtype == np.float32
    assert np.isclose(np.linalg.norm(vf), 1.0, atol=1e-5)
    assert np.linalg.norm(vf - vp) > 1e-3  # different crops, different vectors
    assert np.allclose(enc.encode(fork), vf, atol=1e-6)  # deterministic
    # a checkpoint rebuilds the same encoder from its name and config
    again = make_encoder("clip", enc.config())
    assert np.allclose(again.encode(fork), vf, atol=1e-6)


@needs_clip
def test_clip_encoder_in_the_image_pipeline(tiny_clip):
    import scenescore as ss
    from scenescore.vision.graph import graphs_from_renders

    _, weights, cfg = tiny_clip
    enc = make_encoder(
        "clip", {"model_name": "scenescore-tiny-clip", "weights": weights, "model_config": cfg}
    )
    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    (g,) = graphs_from_renders([scene], encoder=enc)
    assert all(len(o.features) == 16 for o in g.objects)
    assert g.meta["vision"]["missed"] == []


@needs_clip
def test_clip_missing_weights_file_names_the_option(tiny_clip, tmp_path):
    _, _, cfg = tiny_clip
    with pytest.raises(SceneError, match="weights"):
        make_encoder(
            "clip",
            {"model_name": "scenescore-tiny-clip", "weights": str(tmp_path / "nope.pt"), "model_config": cfg},
        )


def test_clip_without_weights_names_the_option(monkeypatch):
    """No weights configured: the error says which option (or variable) to set, before importing open_clip."""
    monkeypatch.delenv("SCENESCORE_CLIP_WEIGHTS", raising=False)
    with pytest.raises(SceneError, match=r"'weights'.*SCENESCORE_CLIP_WEIGHTS"):
        make_encoder("clip", {})
