"""The tidy experiment at a tiny size: messy cases, the scenario's check, every method's row, the chart."""

from __future__ import annotations

from dataclasses import replace

from scenescore.experiments import tidy as T
from scenescore.experiments.execution import Execution
from scenescore.learn import TrainConfig
from scenescore.planning.tidying import TidyOptions
from scenescore.scenarios import get
from scenescore.solvers.kernel import PLACEMENT
from scenescore.solvers.langevin import LangevinOptions


def test_messy_cases_are_feasible_and_rejected_by_the_check():
    for name in ("dining", "desk", "tv", "zoo-hall", "zoo-jars"):  # jars: a broken grid has no oracle
        sc = get(name)
        truth = sc.generate(1, 3)
        assert T.accepts(sc, truth[0], truth[0]), name
        cases = T.messy_cases(sc, truth, seed=0)
        assert cases and {c.kind for c in cases} <= {"shift", "swap"}, name
        for c in cases:
            assert not T.accepts(sc, c.messy, c.truth) and c.putback > 0, (name, c.displaced)
            moved = [n for n in c.truth.names if c.truth[n].pose != c.messy[n].pose]
            assert sorted(moved) == c.displaced


def test_run_reports_every_method_and_draws_the_chart(tmp_path):
    chain = replace(PLACEMENT, steps=2, final_descent=1)
    tiny = LangevinOptions(particles=2, candidates=4, chain=chain)
    opts = TidyOptions(propose=tiny, refine_options={"max_iter": 2})
    res = T.run(
        ("desk",),
        efforts=(1.0,),
        test_scenes=1,
        config=TrainConfig(members=1, iterations=2, batch_scenes=4),
        sizes=(0.4,),
        options=opts,
        place_options=tiny,
        execution=Execution(progress=False, log=lambda s: None),
    )
    methods = [r.method for r in res.rows()]
    assert methods == ["tidy (effort 1) default", "re-place all", "missing placement"]
    for r in res.rows():
        f = r.figures
        assert 0 <= f["accepted"] <= 1 and 0 <= f["precision"] <= 1 and 0 <= f["recall"] <= 1
        assert f["cases"] == len(res.cases)
    for m in res.outcomes:  # plans valid is over the plans made; none made leaves it out
        f = res.figures(m)
        assert 0 <= f["no_plan"] <= 1 and ("plans_valid" in f) == (f["no_plan"] < 1)
    missing = res.figures("missing placement")
    assert missing["precision"] == 1.0 and missing["recall"] == 1.0
    per_case = res.per_case()
    assert len(per_case) == len(res.cases)
    for c, rec in zip(res.cases, per_case):
        assert rec["displaced"] == c.displaced and set(rec["methods"]) == set(methods)
        assert rec["methods"]["missing placement"]["moved"] == sorted(c.displaced)
    md = T.format_tidy(res)
    assert "### All cases" in md and "### desk" in md and "| missing placement |" in md
    T.plot_pareto(res, tmp_path / "pareto.png")
    assert (tmp_path / "pareto.png").stat().st_size > 1000


def test_worker_processes_give_the_same_outcomes_in_the_order_asked():
    import pytest

    from scenescore.scene.scene import SceneError

    chain = replace(PLACEMENT, steps=2, final_descent=1)
    tiny = LangevinOptions(particles=2, candidates=4, chain=chain)
    kw = dict(
        efforts=(1.0,),
        test_scenes=1,
        config=TrainConfig(members=1, iterations=2, batch_scenes=4),
        sizes=(0.4,),
        options=TidyOptions(propose=tiny, refine_options={"max_iter": 2}),
        place_options=tiny,
    )
    quiet = Execution(progress=False, log=lambda s: None)
    one = T.run(("desk", "tv"), execution=replace(quiet, jobs=1), **kw)
    two = T.run(("desk", "tv"), execution=replace(quiet, jobs=2), **kw)
    assert [c.scenario for c in two.cases] == [c.scenario for c in one.cases]
    assert two.outcomes == one.outcomes
    with pytest.raises(SceneError, match="jobs must be a whole number >= 1"):
        T.run(("desk",), execution=replace(quiet, jobs=0), **kw)
    for bad in ((), (-1,), (0.5,)):
        with pytest.raises(SceneError, match="seeds must be one or more whole numbers >= 0"):
            T.run(("desk",), seeds=bad, execution=quiet, **kw)
