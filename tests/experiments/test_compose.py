"""Experiment 3 (Fig. 4): rows, figures, the PNG and the CLI's report.md."""

import pytest
import torch

from scenescore.experiments import compose
from scenescore.experiments.execution import Execution


@pytest.mark.slow
def test_compose_quick_rows_and_plot(tmp_path):
    torch.set_num_threads(1)
    res = compose.run(
        seeds=1, quick=True, levels=[0, 1], samples=8, refine=1, execution=Execution(progress=False)
    )
    rows = {r.method: r.figures for r in res.rows()}
    assert set(rows) == set(compose.METHODS)
    for m, fig in rows.items():
        budget = res.refine if m in compose.CHAINS else res.samples  # real counts, never scaled
        assert fig["samples"] == budget
        for n in (0, 1):
            assert 0 <= fig[f"distinct_at_{n}_objects"] <= fig[f"correct_at_{n}_objects"] <= budget
        assert fig["seconds"] > 0
    md = compose.format_compose(res)
    main, per_solve = md.split("Per-solve refinement")
    assert "SceneScore (langevin>alm)" in main and "1 clutter" in main and "estimate" not in md
    assert "SceneScore (langevin>casadi)" in per_solve and "langevin>casadi" not in main
    assert "1 samples per clutter level" in per_solve
    compose.plot_compose(res, tmp_path / "fig4.png")
    assert (tmp_path / "fig4.png").read_bytes()[:4] == b"\x89PNG"


@pytest.mark.slow
def test_compose_seeds_in_worker_processes_give_the_same_counts():
    torch.set_num_threads(1)
    kw = dict(seeds=2, methods=["SceneScore", "SceneScore (langevin>alm)"], quick=True, levels=[1])
    kw.update(samples=8, refine=1)
    one = compose.run(execution=Execution(progress=False, jobs=1), **kw)
    two = compose.run(execution=Execution(progress=False, jobs=2), **kw)
    assert two.correct == one.correct and two.distinct == one.distinct
    assert len(two.correct["SceneScore"]) == 2  # one row of counts per seed, in seed order


@pytest.mark.slow
def test_the_refined_rows_alm_options_reach_it_and_its_words():
    torch.set_num_threads(1)
    kw = dict(seeds=1, methods=["SceneScore (langevin>alm)"], quick=True, levels=[1])
    kw.update(samples=8, refine=1, execution=Execution(progress=False))
    repair = compose.run(refine_options={"polish": False}, **kw)
    assert repair.refine_options == {"polish": False}
    assert '(alm options {"polish": false}: a repair' in compose.format_compose(repair)
    default = compose.run(**kw)
    assert default.refine_options == compose.REFINE
    assert "descends until feasible" in compose.format_compose(default)
