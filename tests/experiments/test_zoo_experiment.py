"""The zoo experiment at tiny sizes: its table, and worker processes that change nothing."""

import pytest

from scenescore.experiments import zoo
from scenescore.learn import TrainConfig
from scenescore.scene import SceneError

TINY = TrainConfig(iterations=3, batch_scenes=4, negatives=2)


def test_zoo_in_workers_equals_one_process():
    one = zoo.run(
        seeds=1, scenarios=["zoo-cascade", "zoo-hall"], progress=False, log=lambda s: None, config=TINY
    )
    two = zoo.run(
        seeds=1,
        scenarios=["zoo-cascade", "zoo-hall"],
        progress=False,
        log=lambda s: None,
        config=TINY,
        jobs=2,
    )
    assert list(one.per_case) == list(two.per_case) == ["zoo-cascade", "zoo-hall"]
    for name in one.per_case:
        assert len(one.per_case[name]) == 16
        a = [x for c in one.per_case[name] for x in c["pose"]]
        b = [x for c in two.per_case[name] for x in c["pose"]]
        assert a == pytest.approx(b, abs=1e-5)
    md = zoo.format_zoo(two)
    assert "| zoo-cascade |" in md and "| zoo-hall |" in md and "32 placements" in md


def test_zoo_rejects_unknown_scenario_and_bad_jobs():
    with pytest.raises(SceneError, match="zoo-nope"):
        zoo.run(seeds=1, scenarios=["zoo-nope"], log=lambda s: None)
    with pytest.raises(SceneError, match="jobs"):
        zoo.run(seeds=1, scenarios=["zoo-hall"], log=lambda s: None, jobs=0)


def test_zoo_place_options_reach_every_worker():
    """Placement options given to the zoo replace PLACE's, in one process and in workers alike."""
    from dataclasses import replace

    from scenescore.placement import PLACE

    kw = dict(seeds=1, scenarios=["zoo-hall"], progress=False, log=lambda s: None, config=TINY)
    plain = zoo.run(**kw)
    off = replace(PLACE, proposals=0.0)
    one, two = zoo.run(**kw, place=off), zoo.run(**kw, place=off, jobs=2)

    def poses(r: zoo.ZooResult) -> list[float]:
        return [x for c in r.per_case["zoo-hall"] for x in c["pose"]]

    assert poses(one) == pytest.approx(poses(two), abs=1e-5)
    assert poses(one) != pytest.approx(poses(plain), abs=1e-5)
