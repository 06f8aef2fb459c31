"""Snapshot ensembles (``TrainConfig(ensemble="snapshots")``): one run whose member 0 is the single model
of the seed and whose further members come from short cycles after it, the learning rate restarted in
each. The run's own model is untouched by the cycles, the members differ, the checkpoint round-trips
and a bad setting is refused by name."""

from __future__ import annotations

from dataclasses import replace

import pytest
import torch

import scenescore as ss
from scenescore.errors import ConfigError
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.models import load
from scenescore.models.ensemble import members_of

CFG = TrainConfig(
    members=1, iterations=20, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)
SNAP = replace(CFG, members=3, ensemble="snapshots", snapshot_cycle=0.5)
SEED = 5


@pytest.fixture(scope="module")
def scenes():
    return ss.scenarios.get("dining").generate(10, 0)


@pytest.fixture(scope="module")
def snapshots(scenes):
    return fit(scenes, SNAP, seed=SEED, progress=False)


def test_member_zero_is_the_single_model_of_the_seed(scenes, snapshots):
    single = fit(scenes, CFG, seed=SEED, progress=False)
    first = members_of(snapshots.net)[0]
    for a, b in zip(first.state_dict().values(), single.net.state_dict().values(), strict=True):
        assert torch.equal(a, b)  # the same run, op for op, up to its end
    assert snapshots.info.history == single.info.history  # the cycles keep their losses apart
    assert snapshots.info.final_loss == single.info.final_loss


def test_the_cycles_give_members_of_their_own(scenes, snapshots):
    nets = members_of(snapshots.net)
    assert snapshots.members == 3 and len(nets) == 3
    assert [m["snapshot"] for m in snapshots.info.members] == [0, 1, 2]
    assert all(m["seed"] == SEED for m in snapshots.info.members)
    first = [p for p in nets[0].parameters()]
    for other in nets[1:]:
        assert max((a - b).abs().max().item() for a, b in zip(first, other.parameters(), strict=True)) > 0
    st = snapshots.tensors(scenes[:3])
    with torch.no_grad():
        each = snapshots.member_energies(st.poses, st)
        torch.testing.assert_close(snapshots.energy(st.poses, st), each.mean(dim=0))
    assert torch.isfinite(each).all()


def test_a_snapshot_checkpoint_round_trips(tmp_path, scenes, snapshots):
    path = tmp_path / "snap.ckpt"
    snapshots.save(path)
    back = load(path)
    assert back.members == 3 and back.info.members == snapshots.info.members
    assert back.info.train_config["ensemble"] == "snapshots"
    st = back.tensors(scenes[:2])
    with torch.no_grad():
        torch.testing.assert_close(back.energy(st.poses, st), snapshots.energy(st.poses, st))


def test_one_run_however_many_snapshots():
    assert SNAP.runs == 1 and SNAP.snapshots == 2
    assert replace(SNAP, ensemble="seeds").runs == 3 and replace(SNAP, ensemble="seeds").snapshots == 0
    assert replace(SNAP, members=1).snapshots == 0


@pytest.mark.parametrize(
    "field, value",
    [
        ("ensemble", "bagging"),
        ("snapshot_cycle", 0.0),
        ("snapshot_cycle", 1.5),
        ("snapshot_cycle", float("nan")),
    ],
)
def test_bad_snapshot_settings_are_refused_by_name(field, value):
    with pytest.raises(ConfigError, match=field):
        replace(SNAP, **{field: value})


def test_snapshots_on_the_command_line(tmp_path, scenes, capsys):
    from scenescore.cli import main

    data = tmp_path / "data.jsonl"
    ss.scene.write_jsonl(data, scenes)
    out = tmp_path / "m.ckpt"
    argv = ["train", str(data), "--out", str(out), "--members", "3", "--iterations", "20", "--val", "0"]
    argv += ["--set", "ensemble=snapshots", "--set", "network.hidden=16", "--set", "network.layers=1"]
    assert main([*argv, "--quiet", "--force"]) == 0
    model = load(out)
    assert model.members == 3 and [m["snapshot"] for m in model.info.members] == [0, 1, 2]
    assert "as 3 snapshots of one run, in " in capsys.readouterr().out
    assert main([*argv[:-4], "--set", "ensemble=bagging", "--quiet"]) != 0
    assert "TrainConfig: ensemble: expected 'seeds' or 'snapshots', got 'bagging'" in capsys.readouterr().err


def test_a_run_resumed_from_its_last_state_gives_the_same_snapshots(tmp_path, scenes, snapshots):
    """The state covers the run up to member 0; the cycles go on from it, so a run resumed from its
    last state trains every snapshot again, the same op for op."""
    from scenescore.learn import Run

    state = tmp_path / "state.safetensors"
    fit(scenes, SNAP, seed=SEED, progress=False, run=Run(state=state, keep_state=True))
    again = fit(scenes, SNAP, seed=SEED, progress=False, run=Run(state=state, resume=True))
    for a, b in zip(again.net.state_dict().values(), snapshots.net.state_dict().values(), strict=True):
        assert torch.equal(a, b)
