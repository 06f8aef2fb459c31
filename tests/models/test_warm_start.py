"""Training from another model's weights (``fit(..., run=Run(init=model))``, ``scenescore train --init``): the
run starts exactly at those weights, takes its own data's length scale, is named apart in the cache,
records where it started, and a model of another architecture or encoder is refused by name."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

import scenescore as ss
from scenescore.encoders import make_encoder
from scenescore.errors import ConfigError
from scenescore.learn import NetworkConfig, Run, TrainConfig, fit
from scenescore.learn.data import data_scale
from scenescore.learn.warm_start import Start, at_unit_scale
from scenescore.models.ensemble import members_of

CFG = TrainConfig(
    members=1, iterations=12, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)
# a run that cannot move its weights: its model is the weights it started from
FROZEN = replace(CFG, iterations=1, lr=1e-30, lr_final=0.0, average=0.0, energy_reg=0.0)


@pytest.fixture(scope="module")
def prior():
    return fit(at_unit_scale(ss.scenarios.get("dining").generate(8, 0)), CFG, seed=1, progress=False)


@pytest.fixture(scope="module")
def jars():
    return ss.scenarios.get("zoo-jars").generate(6, 0)


def _weights(model):
    return members_of(model.net)[0].state_dict()


def test_at_unit_scale_puts_the_data_at_length_scale_one():
    scenes = ss.scenarios.get("zoo-pcb").generate(4, 0)
    length, far = data_scale(scenes)
    assert length < 0.01  # millimetre parts, in metres
    scaled = at_unit_scale(scenes)
    got, got_far = data_scale(scaled)
    assert got == pytest.approx(1.0)
    assert got_far == pytest.approx(far)  # the arrangement's shape kept
    assert scaled[0].objects[0].pose[2] == scenes[0].objects[0].pose[2]  # headings unchanged


def test_a_run_starts_at_the_given_weights_in_its_own_data_scale(prior, jars):
    tuned = fit(jars, FROZEN, seed=3, progress=False, run=Run(init=prior))
    for name, w in _weights(prior).items():
        torch.testing.assert_close(_weights(tuned)[name], w, rtol=0, atol=1e-20)
    assert tuned.config.length_scale == pytest.approx(data_scale(jars)[0])  # the jars', not the prior's 1.0
    assert prior.config.length_scale == pytest.approx(1.0, rel=0.2)
    assert tuned.info.init == {"source": "the initial model", "digest": Start.of(prior).digest()}
    fresh = fit(jars, FROZEN, seed=3, progress=False)
    assert fresh.info.init is None
    differs = [not torch.equal(a, b) for a, b in zip(_weights(fresh).values(), _weights(tuned).values())]
    assert any(differs)


def test_fine_tuning_trains_from_the_start_and_is_cached_apart(tmp_path, prior, jars):
    run = Run(cache=tmp_path, init=prior)
    tuned = fit(jars, CFG, seed=3, progress=False, run=run)
    fresh = fit(jars, CFG, seed=3, progress=False, run=Run(cache=tmp_path))
    assert len(list(tmp_path.glob("*.ckpt"))) == 2  # one file each: the start names the model
    again = fit(jars, CFG, seed=3, progress=False, run=run)
    for a, b in zip(_weights(tuned).values(), _weights(again).values(), strict=True):
        assert torch.equal(a, b)
    moved = max(
        (a - b).abs().max().item() for a, b in zip(_weights(prior).values(), _weights(tuned).values())
    )
    assert moved > 0  # it trained
    assert tuned.info.final_loss is not None and fresh.info.final_loss is not None


def test_an_ensemble_starts_every_member_from_the_model(prior, jars):
    model = fit(jars, replace(FROZEN, members=2), seed=3, progress=False, run=Run(init=prior, jobs=2))
    for net in members_of(model.net):
        for name, w in _weights(prior).items():
            torch.testing.assert_close(net.state_dict()[name], w, rtol=0, atol=1e-20)
    assert model.info.init is not None


def test_another_architecture_is_refused_by_name(prior, jars):
    wide = replace(FROZEN, network=NetworkConfig(hidden=32, layers=1))
    with pytest.raises(ConfigError, match=r"hidden = 16.*network\.hidden=16"):
        fit(jars, wide, seed=0, progress=False, run=Run(init=prior))
    raw = replace(FROZEN, edge_encoder=None)
    with pytest.raises(ConfigError, match=r"edge_encoder = 32"):
        fit(jars, raw, seed=0, progress=False, run=Run(init=prior))


def test_a_run_refuses_what_is_not_a_model():
    with pytest.raises(ConfigError, match="init: expected a ScoreModel"):
        Run(init="prior.ckpt")


def test_another_encoder_is_refused_by_name(prior, jars):
    with pytest.raises(ConfigError, match=r"'footprint' encoder.*'image'"):
        fit(jars, FROZEN, seed=0, progress=False, run=Run(init=prior), encoder=make_encoder("image"))


def test_the_cli_trains_from_a_checkpoint_and_says_so(tmp_path, prior, jars, capsys):
    from scenescore.cli import main
    from scenescore.models import load
    from scenescore.scene.scene import write_jsonl

    data, start, out = tmp_path / "jars.jsonl", tmp_path / "prior.ckpt", tmp_path / "tuned.ckpt"
    write_jsonl(data, jars)
    prior.save(start)
    args = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(out),
        "--iterations",
        "12",
        "--val",
        "0",
        "--folds",
        "1",
    ]
    args += [
        "--set",
        "network.hidden=16",
        "--set",
        "network.layers=1",
        "--init",
        str(start),
        "--quiet",
        "--force",
    ]
    assert main(args) == 0
    assert load(out).info.init["source"] == str(start)
    assert f"starting from the weights of {start}" in capsys.readouterr().out
    bad = [
        "train",
        "--members",
        "1",
        str(data),
        "--out",
        str(tmp_path / "x.ckpt"),
        "--init",
        str(start),
        "--quiet",
        "--force",
    ]
    assert main([*bad, "--val", "0", "--folds", "1"]) == 2  # the defaults' wider network
    assert "network.hidden=16" in capsys.readouterr().err
