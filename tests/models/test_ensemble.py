"""Ensembles: several networks trained with different seeds, their mean energy placing and their
disagreement flagging. Each member is the single model of its seed; the ensemble's energy is the
members' mean, its gradient exact (float64), its checkpoint round-trips and refuses damage, and a
majority of members that score a placement beyond their own data flags it."""

from __future__ import annotations

import copy
import json
from dataclasses import replace

import numpy as np
import pytest
import torch

import scenescore as ss
from scenescore.cli import main
from scenescore.errors import ConfigError
from scenescore.learn import NetworkConfig, Run, TrainConfig, fit
from scenescore.models import CheckpointError, ScoreModel, load
from scenescore.models.ensemble import EnsembleNet, member_seed, members_of
from scenescore.models.flags import assess
from scenescore.models.trust import member_shares, members_needed
from scenescore.planning.placement import PLACE

CFG = TrainConfig(
    members=1, iterations=20, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)
SEED = 3


@pytest.fixture(scope="module")
def scenes():
    return ss.scenarios.get("dining").generate(10, 0)


@pytest.fixture(scope="module")
def ensemble(scenes):
    return fit(scenes, replace(CFG, members=2), seed=SEED, progress=False)


def test_each_member_is_the_single_model_of_its_seed(scenes, ensemble):
    assert ensemble.members == 2
    assert [m["seed"] for m in ensemble.info.members] == [SEED, member_seed(SEED, 1)] == [3, 1003]
    single = fit(scenes, CFG, seed=member_seed(SEED, 1), progress=False)
    second = members_of(ensemble.net)[1]
    for a, b in zip(second.state_dict().values(), single.net.state_dict().values(), strict=True):
        assert torch.equal(a, b)  # the same training, op for op


def test_the_energy_is_the_members_mean_on_every_path(scenes, ensemble):
    model = ScoreModel(
        EnsembleNet([copy.deepcopy(n).double() for n in members_of(ensemble.net)]), ensemble.encoder
    )
    st = model.tensors(scenes[:3])
    with torch.no_grad():
        mean = model.energy(st.poses, st)
        each = model.member_energies(st.poses, st)
        alone = [ScoreModel(n, ensemble.encoder).energy(st.poses, st) for n in members_of(model.net)]
        by_scene = torch.cat([model.energy_fn(s)(model.tensors([s]).poses) for s in scenes[:3]])
    assert each.shape == (2, 3)
    torch.testing.assert_close(each, torch.stack(alone))
    torch.testing.assert_close(mean, each.mean(dim=0))
    torch.testing.assert_close(by_scene, mean)  # precomputed node embeddings, side by side


def test_the_pose_gradient_is_exact(scenes, ensemble):
    model = ScoreModel(
        EnsembleNet([copy.deepcopy(n).double() for n in members_of(ensemble.net)]), ensemble.encoder
    )
    fn = model.energy_fn(scenes[0])
    x = model.tensors([scenes[0]]).poses.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda p: fn(p), (x,), eps=1e-6, atol=1e-5)


def test_a_checkpoint_round_trips_and_refuses_damaged_members(tmp_path, scenes, ensemble):
    path = tmp_path / "ens.ckpt"
    ensemble.save(path)
    back = load(path)
    assert back.members == 2 and back.info.members == ensemble.info.members
    st = back.tensors(scenes[:2])
    with torch.no_grad():
        assert torch.equal(back.energy(st.poses, st), ensemble.energy(st.poses, st))
    info = back.info.to_dict()
    info["members"] = [{"seed": 1}]  # one record for two networks' weights
    from scenescore.models.checkpoint import read_checkpoint, write_checkpoint

    ck = read_checkpoint(path)
    bad = tmp_path / "bad.ckpt"
    write_checkpoint(bad, ck.tensors, ck.energy_config, ck.encoder, info)
    with pytest.raises(CheckpointError, match=rf"{bad.name}.*members"):
        load(bad)
    del info["members"]  # two networks' weights read as one network's
    write_checkpoint(bad, ck.tensors, ck.energy_config, ck.encoder, info)
    with pytest.raises(CheckpointError, match=rf"{bad.name}.*do not match"):
        load(bad)


def test_inspect_names_the_members(tmp_path, ensemble, capsys):
    path = tmp_path / "ens.ckpt"
    ensemble.save(path)
    capsys.readouterr()
    assert main(["inspect", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["members"] == 2


def test_placement_runs_and_doubting_members_flag(scenes, ensemble):
    scene = scenes[0]
    name = scene.names[-1]
    ref = ensemble.trust
    assert ref is not None and ref.member_shares is not None and len(ref.member_shares) == 2
    quick = replace(PLACE, particles=8, candidates=64, chain=replace(PLACE.chain, steps=8, final_descent=4))
    placed = ss.place(ensemble, scene.without(name), quick, seed=0)
    assert placed[name].pose is not None
    shares = member_shares(ensemble, placed, [name])
    assert shares.shape == (2, 1) and np.isfinite(shares).all()
    # the second member's data put every share of this category far below anything a pose can score
    cat = scene[name].category
    doubting = replace(ref, member_shares=[ref.member_shares[0], {cat: [-1e9, -1e9]}])
    got = assess(doubting, ensemble, placed, [name])[name]
    assert not any(f.startswith("members:") for f in got.flags)  # one of two is no majority
    assert got.confidence == 0.0  # the lowest member's, flag or not
    # both members doubt: the flag fires, and says nothing of a disagreement
    both = replace(ref, member_shares=[{cat: [-1e9, -1e9]}, {cat: [-1e9, -1e9]}])
    flags = [f for f in assess(both, ensemble, placed, [name])[name].flags if f.startswith("members:")]
    assert len(flags) == 1 and flags[0].startswith("members: 2 of 2 members") and "disagrees" not in flags[0]
    calm = replace(ref, member_shares=[{cat: [1e9, 1e9]}, {cat: [1e9, 1e9]}], shares={cat: [1e9, 1e9]})
    assert not any(f.startswith("members:") for f in assess(calm, ensemble, placed, [name])[name].flags)


def test_most_of_three_members_must_doubt(scenes, ensemble):
    """Three members (the second network twice): one doubting member does not flag, two do, and the flag
    says they disagree with the third."""
    a, b = members_of(ensemble.net)
    three = ScoreModel(EnsembleNet([a, b, b]), ensemble.encoder)
    assert [members_needed(m) for m in (1, 2, 3, 5)] == [1, 2, 2, 3]
    scene = scenes[0]
    name = scene.names[-1]
    cat, ref = scene[name].category, ensemble.trust
    assert ref is not None and ref.member_shares is not None
    calm, doubt = {cat: [1e9, 1e9]}, {cat: [-1e9, -1e9]}

    def members_flags(shares: list[dict]) -> list[str]:
        judged = replace(ref, member_shares=shares, shares={cat: [1e9, 1e9]})
        return [f for f in assess(judged, three, scene, [name])[name].flags if f.startswith("members:")]

    assert members_flags([doubt, calm, calm]) == []
    (flag,) = members_flags([doubt, calm, doubt])
    assert flag.startswith("members: 2 of 3 members") and flag.endswith("(the ensemble disagrees)")


def test_train_members_on_the_command_line(tmp_path, scenes, capsys):
    data = tmp_path / "data.jsonl"
    ss.scene.write_jsonl(data, scenes)
    out = tmp_path / "m.ckpt"
    argv = ["train", str(data), "--out", str(out), "--members", "2", "--iterations", "20", "--val", "0"]
    argv += ["--set", "network.hidden=16", "--set", "network.layers=1", "--quiet", "--force"]
    assert main(argv) == 0
    assert load(out).members == 2
    assert "trained on 10 scenes as 2 members, " in capsys.readouterr().out
    with pytest.raises(SystemExit):
        main(["train", str(data), "--out", str(out), "--members", "17", "--quiet"])
    assert "--members" in capsys.readouterr().err


def test_members_trained_in_worker_processes_are_the_same_ensemble(scenes, ensemble):
    """Each member trains on one torch thread, so training them side by side in two spawned worker
    processes gives the ensemble one process trains, weights and trust reference alike."""
    apart = fit(scenes, replace(CFG, members=2), seed=SEED, progress=False, run=Run(jobs=2))
    assert apart.members == 2 and [m["seed"] for m in apart.info.members] == [3, 1003]
    mine, theirs = ensemble.net.state_dict(), apart.net.state_dict()
    assert mine.keys() == theirs.keys()
    for key in mine:
        assert torch.equal(mine[key], theirs[key]), key
    assert apart.info.trust.to_dict() == ensemble.info.trust.to_dict()
    assert apart.info.final_loss == ensemble.info.final_loss


@pytest.mark.parametrize("jobs", [0, -1, 1.5, True])
def test_jobs_must_be_a_whole_number_of_processes(scenes, jobs):
    with pytest.raises(ConfigError, match="jobs"):
        fit(scenes, replace(CFG, members=2), seed=SEED, progress=False, run=Run(jobs=jobs))


def test_cross_validation_folds_in_worker_processes_report_the_same(scenes):
    """The folds of cross-validation run side by side in worker processes with the report one process
    gives."""
    from scenescore.workflow.crossval import cross_validate

    one, two = (
        cross_validate(scenes[:6], CFG, 2, seed=SEED, progress=False, say=lambda line: None, jobs=j)
        for j in (1, 2)
    )
    assert one.to_dict() == two.to_dict() and one.categories
