"""The zoo experiment at tiny sizes: its table, and worker processes that change nothing."""

from dataclasses import replace

import pytest

from scenescore.experiments import zoo
from scenescore.experiments.execution import Execution
from scenescore.learn import TrainConfig
from scenescore.scene.scene import SceneError

TINY = TrainConfig(members=1, iterations=3, batch_scenes=4, negatives=2)
QUIET = Execution(progress=False, log=lambda s: None)


def test_zoo_in_workers_equals_one_process():
    one = zoo.run(seeds=1, scenarios=["zoo-cascade", "zoo-hall"], config=TINY, execution=QUIET)
    two = zoo.run(
        seeds=1,
        scenarios=["zoo-cascade", "zoo-hall"],
        config=TINY,
        execution=replace(QUIET, jobs=2),
    )
    assert list(one.per_case) == list(two.per_case) == ["zoo-cascade", "zoo-hall"]
    for name in one.per_case:
        assert len(one.per_case[name]) == 16
        a = [x for c in one.per_case[name] for x in c["pose"]]
        b = [x for c in two.per_case[name] for x in c["pose"]]
        assert a == pytest.approx(b, abs=1e-5)
    md = zoo.format_zoo(two)
    assert "| zoo-cascade |" in md and "| zoo-hall |" in md and "32 placements" in md
    assert "Trust check, flagged: " in md and " catastrophic (" in md


def test_zoo_rejects_unknown_scenario_and_bad_jobs():
    with pytest.raises(SceneError, match="zoo-nope"):
        zoo.run(seeds=1, scenarios=["zoo-nope"], execution=Execution(log=lambda s: None))
    with pytest.raises(SceneError, match="jobs"):
        zoo.run(seeds=1, scenarios=["zoo-hall"], execution=Execution(log=lambda s: None, jobs=0))


def test_zoo_place_options_reach_every_worker():
    """Placement options given to the zoo replace PLACE's, in one process and in workers alike."""
    from scenescore.planning.placement import PLACE

    kw = dict(seeds=1, scenarios=["zoo-hall"], config=TINY)
    plain = zoo.run(**kw, execution=QUIET)
    off = replace(PLACE, proposals=0.0)
    one = zoo.run(**kw, place=off, execution=QUIET)
    two = zoo.run(**kw, place=off, execution=replace(QUIET, jobs=2))

    def poses(r: zoo.ZooResult) -> list[float]:
        return [x for c in r.per_case["zoo-hall"] for x in c["pose"]]

    assert poses(one) == pytest.approx(poses(two), abs=1e-5)
    assert poses(one) != pytest.approx(poses(plain), abs=1e-5)


def test_zoo_cases_remove_three_chairs_in_rooms_and_one_object_elsewhere():
    """Rooms: three chairs per test scene, their poses null and their truths the scene's; the other
    scenarios: the same one object per scene as ever (the seed's draws unchanged)."""
    from scenescore.scenarios import get

    for name in ("zoo-classroom", "zoo-cafe"):
        sc = get(name)
        test = sc.split(0)[1]
        cases = zoo.zoo_cases(sc, test, 0)
        assert len(cases) == 16
        for c, s in zip(cases, test):
            assert len(c.names) == len(set(c.names)) == 3 and sorted(c.scene.unknown) == sorted(c.names)
            assert all(s[n].category == "chair" for n in c.names)
            assert [q.truth for q in c.singles()] == [s[n].pose for n in c.names]
        assert [c.names for c in zoo.zoo_cases(sc, test, 0)] == [c.names for c in cases]
        assert [c.names for c in zoo.zoo_cases(sc, test, 1)] != [c.names for c in cases]
    hall = zoo.zoo_cases(get("zoo-hall"), get("zoo-hall").split(0)[1], 0)
    assert all(c.others == () and c.singles() == [c] and c.scene.unknown == [c.name] for c in hall)
    assert [c.name for c in hall] == (
        "vase_0 vase_1 vase_1 vase_1 vase_1 vase_1 stool_0 vase_0 vase_1 vase_0 stool_0 stool_0 vase_0 "
        "vase_1 stool_0 vase_1"
    ).split()
    banquet = zoo.zoo_cases(get("zoo-banquet"), get("zoo-banquet").split(0)[1], 0)
    assert [int(c.name.split("_")[1]) for c in banquet] == [1, 4, 1, 4, 5, 4, 8, 2, 2, 1, 7, 6, 0, 1, 3, 4]


def test_zoo_room_run_scores_each_chair_by_assignment():
    """A smoke run on zoo-classroom (a few training steps, a tiny placement): one record per missing
    chair, each matched to a distinct placed chair of its scene, the oracle a few centimetres off, the
    worst placement the one drawn; a room is named like any scenario."""
    from scenescore.planning.placement import PLACE

    tiny_place = replace(PLACE, particles=2, candidates=0, proposals=0.0, chain=replace(PLACE.chain, steps=3))
    one = zoo.run_one("zoo-classroom", 0, TINY, place=tiny_place)
    recs = one["cases"]
    assert len(recs) == 48
    for k in range(0, 48, 3):
        scene = recs[k : k + 3]
        assert len({r["object"] for r in scene}) == 3
        assert {r["placed"] for r in scene} == {r["object"] for r in scene}
        assert len({r["energy_truth"] for r in scene}) == 1
    oracle = [r["oracle_t_cm"] for r in recs]
    assert sum(oracle) / len(oracle) < 5.0 and max(oracle) < 10.0
    case, placed, t = one["worst"]
    assert t == max(r["t_cm"] for r in recs) and placed[case.name].pose is not None
    with pytest.raises(SceneError, match="zoo-nope"):  # the rooms are named, like any scenario
        zoo.run(seeds=1, scenarios=["zoo-classroom", "zoo-nope"], execution=Execution(log=lambda s: None))


def test_zoo_small_data_variant_trains_on_fewer_scenes_and_places_the_same_cases(monkeypatch):
    """``train_scenes`` (``experiment zoo --train-scenes 12``): the first N training scenes, the same
    test cases; a count outside 2..48 is refused."""
    import scenescore.experiments.zoo as zoo_module

    seen: list[int] = []
    real = zoo_module.fit

    def counting(scenes, *args, **kwargs):
        seen.append(len(scenes))
        return real(scenes, *args, **kwargs)

    monkeypatch.setattr(zoo_module, "fit", counting)
    kw = dict(seeds=1, scenarios=["zoo-hall"], config=TINY, execution=QUIET)
    full, small = zoo.run(**kw), zoo.run(**kw, train_scenes=12)
    assert seen == [48, 12]
    assert [c["truth"] for c in full.per_case["zoo-hall"]] == [c["truth"] for c in small.per_case["zoo-hall"]]
    with pytest.raises(SceneError, match="train_scenes"):
        zoo.run(**kw, train_scenes=1)
