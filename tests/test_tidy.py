"""Tidying: the pick-and-place plan (swaps through a buffer), its validator, and tidy's output."""

from __future__ import annotations

import importlib
import json
import math
from dataclasses import replace

import numpy as np
import pytest
import torch

from scenescore.encoders import FootprintEncoder
from scenescore.errors import ConfigError
from scenescore.models import ScoreModel, TidyCalibration, load
from scenescore.planning.tidying import (
    Step,
    TidyError,
    TidyOptions,
    calibrate,
    count_weight,
    effort_weights,
    plan_moves,
    tidy,
    validate_plan,
)
from scenescore.planning.tidying.calibration import move_gains, object_gains
from scenescore.planning.tidying.draws import NEAR, exchanges, near_draws, swap_draws
from scenescore.planning.tidying.problem import tidy_problem
from scenescore.planning.tidying.pruning import place_again
from scenescore.planning.tidying.selection import select_moves
from scenescore.planning.tidying.types import COUNT
from scenescore.problem.problem import Problem
from scenescore.scene.scene import Scene, SceneObject
from scenescore.solvers.kernel import PLACEMENT
from scenescore.solvers.langevin import LangevinOptions


def _two(a=(-0.2, 0.0), b=(0.2, 0.0)) -> Scene:
    return Scene(
        [
            SceneObject("red", "box", (0.2, 0.2), (*a, 0.0)),
            SceneObject("blue", "box", (0.2, 0.2), (*b, 0.0)),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )


def test_a_swap_goes_through_a_buffer_and_replays():
    before = _two()
    after = _two(a=(0.2, 0.0), b=(-0.2, 0.0))
    steps = plan_moves(before, after, seed=0)
    assert len(steps) == 3 and sum(s.buffer for s in steps) == 1
    assert steps[0].buffer and steps[-1].name == steps[0].name
    check = validate_plan(before, after, steps)
    assert check.valid, check.describe()
    # the same plan through JSON
    assert validate_plan(before, after, [json.loads(json.dumps(s.to_dict())) for s in steps]).valid


def test_a_chain_needs_no_buffer_and_goes_in_order():
    before = _two(a=(-0.2, 0.0), b=(0.05, 0.0))
    after = _two(a=(0.05, 0.0), b=(0.35, 0.0))  # red onto blue's place: blue first
    steps = plan_moves(before, after)
    assert [s.name for s in steps] == ["blue", "red"] and not any(s.buffer for s in steps)
    assert validate_plan(before, after, steps).valid


def test_the_validator_catches_bad_plans():
    before = _two(a=(-0.2, 0.0), b=(0.05, 0.0))
    after = _two(a=(0.05, 0.0), b=(0.35, 0.0))
    wrong_order = [
        Step("red", (-0.2, 0.0, 0.0), (0.05, 0.0, 0.0)),
        Step("blue", (0.05, 0.0, 0.0), (0.35, 0.0, 0.0)),
    ]
    check = validate_plan(before, after, wrong_order)
    assert not check.valid and "step 1: 'red' put down on 'blue'" in check.describe()
    short = validate_plan(before, after, wrong_order[1:])
    assert not short.valid and "'red' does not end at its target" in short.describe()
    outside = [Step("blue", (0.05, 0.0, 0.0), (0.58, 0.0, 0.0))]
    assert "out of bounds" in validate_plan(before, before, outside).describe()
    reach = validate_plan(before, after, plan_moves(before, after), reach=((-0.2, 0.0), 0.3))
    assert not reach.valid and "out of reach" in reach.describe()


def test_a_target_on_an_object_that_stays_is_an_error():
    before = Scene(
        [
            SceneObject("red", "box", (0.2, 0.2), (-0.3, 0.0, 0.0)),
            SceneObject("wall", "box", (0.2, 0.2), (0.2, 0.0, 0.0), fixed=True),
        ]
    )
    after = before.with_poses([[0.2, 0.05, 0.0]], ["red"])
    with pytest.raises(TidyError, match="'red''s target overlaps 'wall', which does not move"):
        plan_moves(before, after)


def _flat_model() -> ScoreModel:
    """A model whose learned energy is flat: a hand-made cost added to its problem is the only preference."""
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    with torch.no_grad():
        for prm in model.net.parameters():
            prm.zero_()
    return model


def _quick() -> TidyOptions:
    chain = replace(PLACEMENT, steps=3, final_descent=2)
    return TidyOptions(
        propose=LangevinOptions(particles=2, candidates=4, chain=chain), refine_options={"max_iter": 3}
    )


def test_tidy_reports_moves_targets_and_a_valid_plan():
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scene = _two(a=(-0.3, 0.1), b=(0.3, -0.1))
    r = tidy(model, scene, effort=0.0, seed=0, options=_quick())
    d = r.to_dict()
    assert set(d["objects"]) == {"red", "blue"} and d["moved"] == r.moved
    assert d["plan"]["valid"] and len(d["plan"]["steps"]) >= len(r.moved)
    assert math.isclose(d["total_displacement"], sum(d["objects"][n]["displacement"] for n in r.moved))
    for n in scene.names:
        if n not in r.moved:
            assert r.after[n].pose == scene[n].pose  # exactly where it was
    with pytest.raises(TidyError, match="no object may move"):
        tidy(model, scene, stay=["red", "blue"], options=_quick())
    with pytest.raises(TidyError, match="pose null"):
        tidy(model, scene.without("red"), options=_quick())
    with pytest.raises(TidyError, match="stay: no object named 'green'"):
        tidy(model, scene, stay=["green"], options=_quick())


def test_the_cli_writes_the_moves_the_plan_and_the_plot(tmp_path, capsys):
    from scenescore.cli import main
    from scenescore.scenarios import DeskScenario

    torch.manual_seed(0)
    ScoreModel.create(FootprintEncoder(), hidden=8, layers=1).save(tmp_path / "m.ckpt")
    scene = DeskScenario().arrange((0.0, 0.0, 0.0), 0.2)
    scene.with_poses([[0.3, 0.25, 0.4]], ["pen"]).to_json(tmp_path / "messy.json")
    args = [str(tmp_path / "m.ckpt"), str(tmp_path / "messy.json"), "--out", str(tmp_path / "t.json")]
    rc = main(["tidy", *args, "--plot", str(tmp_path / "t.png"), "--stay", "book", "--quiet"])
    assert rc == 0
    out = json.loads((tmp_path / "t.json").read_text())
    assert out["plan"]["valid"] and not out["objects"]["book"]["moves"]
    assert (tmp_path / "t.png").stat().st_size > 1000
    assert "plan:" in capsys.readouterr().out
    assert main(["tidy", *args, "--reach", "0,0"]) == 2
    assert "--reach: expected X,Y,R" in capsys.readouterr().err
    assert main(["tidy", *args, "--stay", "book,pen,mug"]) == 2
    assert "no object may move" in capsys.readouterr().err


def test_options_are_checked_and_the_count_weight_falls_back_in_order():
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    with pytest.raises(ConfigError, match="TidyOptions: sigma: expected a finite number > 0"):
        TidyOptions(sigma=0.0)
    with pytest.raises(ConfigError, match="TidyOptions: count: expected a finite number >= 0"):
        TidyOptions(count=-1.0)
    with pytest.raises(ConfigError, match="TidyOptions: place: expected true or false"):
        TidyOptions(place="yes")  # type: ignore[arg-type]
    assert count_weight(model) == COUNT  # no calibration stored
    model.info.tidy = TidyCalibration(move_gain=0.42)
    assert count_weight(model) == 0.42
    assert count_weight(model, TidyOptions(count=2.0)) == 2.0  # an explicit weight wins
    model.info.tidy = TidyCalibration(move_gain=float("nan"))
    assert count_weight(model) == COUNT


def test_calibrate_stores_the_move_gain_in_the_checkpoint(tmp_path):
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scenes = [_two(a=(-0.3, 0.1 * k), b=(0.3, -0.1)) for k in range(3)]
    gains = move_gains(model, scenes, seed=0)
    assert gains.shape == (3,) and (gains >= 0).all()
    gain = calibrate(model, scenes, seed=0)
    assert gain == pytest.approx(float(np.quantile(gains, 0.75)))
    model.save(tmp_path / "m.ckpt")
    assert count_weight(load(tmp_path / "m.ckpt")) == pytest.approx(gain)
    with pytest.raises(TidyError, match="no scene with every pose known"):
        calibrate(model, [scenes[0].without("red")])


def test_the_selection_moves_only_the_object_that_is_out_of_place():
    """A hand-made energy (a cost the model would learn): blue belongs 0.3 m right of red. Blue moved
    away is put back; red, already right, stays exactly where it is; at a large effort nothing moves."""
    from scenescore.costs import PoseTarget

    model = _flat_model()  # the target below is the only preference
    scene = _two(a=(-0.2, 0.0), b=(0.3, 0.3))
    chain = replace(PLACEMENT, steps=2, final_descent=1)
    o = TidyOptions(propose=LangevinOptions(particles=256, chain=chain))
    target = 50.0 * PoseTarget("blue", (0.1, 0.0))
    prob = tidy_problem(model, scene, 1.0, options=o)
    x = select_moves(model, [scene], [Problem(scene, prob.cost + target, movable=prob.movable)], o, seed=0)[0]
    assert np.array_equal(x[scene.index("red")], scene.poses()[scene.index("red")])
    assert np.hypot(*(x[scene.index("blue"), :2] - [0.1, 0.0])) < 0.15
    prob = tidy_problem(model, scene, 1000.0, options=o)
    x = select_moves(model, [scene], [Problem(scene, prob.cost + target, movable=prob.movable)], o, seed=0)[0]
    assert np.array_equal(x, scene.poses())  # every move costs more than it gains


def test_a_target_outside_the_bounds_gets_no_plan():
    before = _two(a=(-0.3, 0.0), b=(0.3, 0.0))
    after = before.with_poses([[0.58, 0.0, 0.0]], ["blue"])  # its footprint sticks out of the bounds
    with pytest.raises(TidyError, match="'blue''s target is not allowed: .*out of bounds"):
        plan_moves(before, after)


def test_the_move_cost_follows_the_scene_size_and_falls_back_in_order():
    """A move costs the ``GAIN_QUANTILE ** (1 / M)`` quantile of the calibrated gains, ``M`` the scene's
    objects that may move; an explicit ``count`` overrides; a model calibrated before gains per object
    pays its one ``move_gain``; without a scene, ``move_gain``."""
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    two = Scene(
        [
            SceneObject("r", "resistor", (0.1, 0.1), (0.0, 0.0, 0.0)),
            SceneObject("c", "capacitor", (0.1, 0.1), (0.3, 0.0, 0.0)),
            SceneObject("w", "wall", (0.1, 0.1), (0.0, 0.3, 0.0), fixed=True),
        ]
    )
    assert count_weight(model, scene=two) == COUNT  # never calibrated
    model.info.tidy = TidyCalibration(move_gain=0.5)  # calibrated before gains per object
    assert count_weight(model, scene=two) == 0.5
    gains = [0.01 * k for k in range(20)]
    model.info.tidy = TidyCalibration(move_gain=0.5, gains=gains)
    assert count_weight(model, scene=two) == pytest.approx(float(np.quantile(gains, 0.75 ** (1 / 2))))
    one = Scene([two.objects[0]])
    assert count_weight(model, scene=one) == pytest.approx(float(np.quantile(gains, 0.75)))
    assert count_weight(model, scene=two) > count_weight(model, scene=one)  # more objects: a rarer gain
    assert count_weight(model) == 0.5  # no scene: the one cost
    assert count_weight(model, TidyOptions(count=1.0), two) == 1.0
    model.info.tidy.gains = [float("nan")] * 20  # damaged: not used
    assert count_weight(model, scene=two) == 0.5


def test_calibrate_stores_every_objects_gain(tmp_path):
    """``gains``: every object's single-move gain (at least 0), sorted; ``move_gain``: the quantile of
    each scene's best, returned."""
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scenes = [_two(a=(-0.3, 0.1 * k), b=(0.3, -0.1)) for k in range(4)]
    gains = object_gains(model, scenes, seed=0)
    assert [(k, n) for k, n, _ in gains] == [(k, n) for k in range(4) for n in ("red", "blue")]
    gain = calibrate(model, scenes, seed=0)
    info = model.info.tidy
    assert info is not None and info.gains == pytest.approx(sorted(max(0.0, g) for _, _, g in gains))
    best = [max(max(0.0, g) for k2, _, g in gains if k2 == k) for k in range(4)]
    assert gain == info.move_gain == pytest.approx(float(np.quantile(best, 0.75)))
    model.save(tmp_path / "m.ckpt")
    assert load(tmp_path / "m.ckpt").info.tidy == model.info.tidy


def test_a_deferred_calibration_is_measured_at_the_first_tidy_and_kept_for_the_next(tmp_path, monkeypatch):
    """``defer`` keeps the scenes in the checkpoint; the first tidy measures the same gains ``calibrate``
    would have, keeps them in the user's cache, and a later tidy with the same checkpoint reads them."""
    from scenescore.planning.tidying import calibration

    monkeypatch.setenv("SCENESCORE_CACHE_DIR", str(tmp_path / "cache"))
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scenes = [_two(a=(-0.3, 0.1 * k), b=(0.3, -0.1)) for k in range(3)]
    now = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    now.net.load_state_dict(model.net.state_dict())
    calibrate(now, scenes, seed=2)
    calibration.defer(model, scenes, seed=2)
    assert count_weight(model) == COUNT  # not measured yet: the default cost of a move
    model.save(tmp_path / "m.ckpt")
    first = load(tmp_path / "m.ckpt")
    said: list[str] = []
    calibration.ensure_calibrated(first, say=said.append)
    assert first.info.tidy == now.info.tidy and len(said) == 1  # measured: the same gains
    assert len(list((tmp_path / "cache" / "tidy").glob("*.json"))) == 1

    def never(*a, **k):
        raise AssertionError("measured again")

    monkeypatch.setattr(calibration, "calibrate", never)
    again = load(tmp_path / "m.ckpt")
    tidy(again, scenes[0], seed=0, options=TidyOptions(place=False, refine=None))  # reads the cache
    assert again.info.tidy == now.info.tidy
    with pytest.raises(TidyError, match="no scene with every pose known"):
        calibration.defer(model, [scenes[0].without("red")])
    # other code (an upgrade) measures again: the cache's key holds the code's version
    upgraded = load(tmp_path / "m.ckpt")
    monkeypatch.setattr(calibration, "code_version", lambda: "scenescore 99; source other")
    with pytest.raises(AssertionError, match="measured again"):
        calibration.ensure_calibrated(upgraded)


def test_swap_draws_put_each_pair_in_each_others_places():
    scene = Scene(
        [
            SceneObject("a", "box", (0.1, 0.1), (-0.3, 0.0, 0.1)),
            SceneObject("b", "bowl", (0.1, 0.1), (0.3, 0.0, 0.2)),
            SceneObject("c", "cup", (0.1, 0.1), (0.0, 0.3, 0.3)),
        ]
    )
    x = torch.zeros(12, 3, 3, dtype=torch.float64)
    swap_draws(x, scene, ["a", "b", "c"])
    now = torch.as_tensor(scene.poses())
    assert torch.equal(x[:9], torch.zeros(9, 3, 3, dtype=torch.float64))  # the first three quarters as drawn
    assert torch.equal(x[9, 0], now[1]) and torch.equal(x[9, 1], now[0])  # a <-> b
    assert torch.equal(x[10, 0], now[2]) and torch.equal(x[10, 2], now[0])  # a <-> c
    assert torch.equal(x[11, 1], now[2]) and torch.equal(x[11, 2], now[1])  # b <-> c
    z = torch.zeros(24, 3, 3, dtype=torch.float64)  # two rounds: the second trades positions only
    swap_draws(z, scene, ["a", "b", "c"])
    assert not z[:18].any() and torch.equal(z[18:21], x[9:12])
    assert torch.equal(z[21, 0], torch.stack([now[1, 0], now[1, 1], now[0, 2]]))  # at b's spot, own heading
    assert torch.equal(z[21, 1], torch.stack([now[0, 0], now[0, 1], now[1, 2]])) and not z[21, 2].any()
    assert torch.equal(z[23, 2], torch.stack([now[1, 0], now[1, 1], now[2, 2]])) and not z[23, 0].any()
    y = torch.zeros(8, 3, 3, dtype=torch.float64)
    swap_draws(y, scene, ["a"])  # one object: nothing to trade
    assert not y.any()


def _swapped_wells(
    pairs: int, swaps: int = 0, kinds: tuple[str, str] = ("box", "box")
) -> tuple[list[str], np.ndarray]:
    """Two large boxes, each where the other belongs (a hand-made energy: a narrow well at each one's
    right place): a single move cannot reach its well, the other box is in it; the pair can. Returns
    which objects the selection moved (with ``PAIR_CANDIDATES = pairs``, ``SWAP_CANDIDATES = swaps``;
    ``kinds``: the boxes' categories) and the poses."""
    from scenescore.costs import CostFn

    model = _flat_model()
    scene = Scene(
        [
            SceneObject("red", kinds[0], (0.4, 0.4), (-0.3, 0.0, 0.0)),
            SceneObject("blue", kinds[1], (0.4, 0.4), (0.3, 0.0, 0.0)),
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )
    want = torch.tensor([[0.3, 0.0], [-0.3, 0.0]], dtype=torch.float64)

    def wells(x: torch.Tensor) -> torch.Tensor:
        d2 = ((x[..., :2] - want.to(x.dtype)) ** 2).sum(-1)  # (B, 2)
        return -10.0 * torch.exp(-d2 / 0.04).sum(-1)

    chain = replace(PLACEMENT, steps=1, final_descent=0)
    o = TidyOptions(propose=LangevinOptions(particles=4096, chain=chain))
    prob = tidy_problem(model, scene, 1.0, options=o)
    tidy_module = importlib.import_module("scenescore.planning.tidying.selection")
    old = tidy_module.PAIR_CANDIDATES, tidy_module.SWAP_CANDIDATES
    tidy_module.PAIR_CANDIDATES, tidy_module.SWAP_CANDIDATES = pairs, swaps
    try:
        problem = Problem(scene, prob.cost + CostFn(wells, name="wells"), movable=prob.movable)
        x = select_moves(model, [scene], [problem], o, seed=0)[0]
    finally:
        tidy_module.PAIR_CANDIDATES, tidy_module.SWAP_CANDIDATES = old
    moved = [n for i, n in enumerate(scene.names) if not np.array_equal(x[i], scene.poses()[i])]
    return moved, x


def test_the_selection_moves_a_swapped_pair_that_no_single_move_fixes():
    moved, x = _swapped_wells(pairs=0)  # without pairs: neither box can reach its well alone
    assert moved == []
    moved, x = _swapped_wells(pairs=5)
    assert sorted(moved) == ["blue", "red"]
    assert np.hypot(*(x[0, :2] - [0.3, 0.0])) < 0.15 and np.hypot(*(x[1, :2] - [-0.3, 0.0])) < 0.15


def test_the_selection_tries_the_exchange_of_two_objects_of_different_kinds():
    # no pair search: two boxes of one kind trade places for nothing, so no exchange is tried
    assert _swapped_wells(pairs=0, swaps=3)[0] == []
    # of different kinds: without exchanges neither moves; with them both do, each into its well
    assert _swapped_wells(pairs=0, swaps=0, kinds=("box", "crate"))[0] == []
    moved, x = _swapped_wells(pairs=0, swaps=3, kinds=("box", "crate"))
    assert sorted(moved) == ["blue", "red"]
    assert np.hypot(*(x[0, :2] - [0.3, 0.0])) < 0.15 and np.hypot(*(x[1, :2] - [-0.3, 0.0])) < 0.15


def test_near_draws_start_an_eighth_of_the_draws_beside_the_current_poses():
    scene = _two(a=(-0.3, 0.1), b=(0.3, -0.1))
    x = torch.full((32, 2, 3), 9.0, dtype=torch.float64)
    near_draws(x, scene, [1], 0.05, torch.Generator().manual_seed(0))
    near = x[20:24, 1]  # 32 draws: the eighth before the last quarter
    now = torch.as_tensor(scene.poses()[1])
    assert torch.all((near[:, :2] - now[:2]).abs() < 5 * NEAR * 0.05) and not torch.equal(near[0], now)
    assert torch.all(x[:20] == 9.0) and torch.all(x[24:] == 9.0) and torch.all(x[:, 0] == 9.0)


def test_exchanges_trade_whole_poses_then_positions():
    x = np.array([[0.0, 0.0, 0.1], [1.0, 0.0, 0.2], [0.0, 1.0, 0.3]])
    out = exchanges(x, [(0, 1), (1, 2)])
    assert out.shape == (4, 3, 3)
    assert np.array_equal(
        out[0], [[1.0, 0.0, 0.2], [0.0, 0.0, 0.1], [0.0, 1.0, 0.3]]
    )  # 0 <-> 1, headings too
    assert np.array_equal(
        out[3], [[0.0, 0.0, 0.1], [0.0, 1.0, 0.2], [1.0, 0.0, 0.3]]
    )  # 1 <-> 2, positions only


def test_effort_weights_charge_larger_objects_more_and_keep_the_users():
    table = SceneObject("table", "table", (2.0, 2.0), (0.0, 0.0, 0.0), fixed=True)
    scene = Scene(
        [
            table,
            SceneObject("plate", "plate", (0.3, 0.3), (0.0, 0.0, 0.0)),
            SceneObject("bowl", "bowl", (0.1, 0.1), (0.3, 0.0, 0.0)),
            SceneObject("knife", "knife", (0.2, 0.02), (-0.3, 0.0, 0.0)),
        ],
        bounds=((-1.5, -1.5), (1.5, 1.5)),
    )
    w = effort_weights(scene)
    assert w is not None
    # the median area is the bowl's (the fixed table does not count): the plate 3x as wide costs 3x
    assert w["plate"] == pytest.approx(3.0) and w["bowl"] == 1.0 and w["knife"] == 1.0
    w = effort_weights(scene, {"knife": 2.0, "plate": 0.5})
    assert w is not None and w["knife"] == 2.0 and w["plate"] == pytest.approx(1.5)
    assert effort_weights(scene, {"knife": 2.0}, TidyOptions(by_size=False)) == {"knife": 2.0}
    assert effort_weights(scene, None, TidyOptions(by_size=False)) is None
    with pytest.raises(ConfigError, match="TidyOptions: by_size: expected true or false"):
        TidyOptions(by_size=1)  # type: ignore[arg-type]


def _relation_tie(weights: dict[str, float] | None) -> list[str]:
    """A hand-made relational energy: blue belongs 0.3 m right of red, wherever red is. Moving either one
    by the same vector fixes it, at the same displacement; only the effort weights tell them apart.
    Returns which objects the selection moved."""
    from scenescore.costs import CostFn

    model = _flat_model()
    scene = Scene(
        [
            SceneObject("red", "box", (0.3, 0.3), (-0.2, -0.1, 0.0)),
            SceneObject("blue", "box", (0.1, 0.1), (0.3, 0.2, 0.0)),
        ],
        bounds=((-0.7, -0.7), (0.7, 0.7)),
    )

    def relation(x: torch.Tensor) -> torch.Tensor:
        off = x[..., 1, :2] - x[..., 0, :2] - torch.tensor([0.3, 0.0], dtype=x.dtype)  # (B, 2)
        return 50.0 * (off**2).sum(-1)

    chain = replace(PLACEMENT, steps=6, final_descent=4)
    o = TidyOptions(propose=LangevinOptions(particles=512, chain=chain))
    prob = tidy_problem(model, scene, 1.0, weights=weights, options=o)
    problem = Problem(scene, prob.cost + CostFn(relation, name="relation"), movable=prob.movable)
    x = select_moves(model, [scene], [problem], o, seed=0)[0]
    return [n for i, n in enumerate(scene.names) if not np.array_equal(x[i], scene.poses()[i])]


def test_the_smaller_end_of_a_relation_is_the_one_moved():
    assert _relation_tie(None) == ["blue"]  # red is 3x as wide: it costs more to move
    assert _relation_tie({"blue": 6.0}) == ["red"]  # unless the user says blue is the costly one


def test_the_placement_candidates_leave_each_moved_object_out_in_turn():
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scene = _two(a=(-0.3, 0.1), b=(0.3, -0.1))
    now = scene.poses()
    one, two, none = place_again(model, [scene, scene, scene], [["red"], ["red", "blue"], []], seed=0)
    assert len(one) == 1 and len(two) == 3 and none == []
    assert np.array_equal(one[0][1], now[1])  # blue, not in the set, stays exactly
    # the whole set placed, then the set with red left where it is, then with blue left where it is
    assert np.array_equal(two[1][0], now[0]) and np.array_equal(two[2][1], now[1])


@pytest.mark.float_order
def test_placing_ahead_on_a_second_core_gives_the_same_answer_to_the_bit(monkeypatch):
    import threading

    from scenescore.runtime.ahead import Ahead

    T = importlib.import_module("scenescore.planning.tidying.pipeline")
    torch.manual_seed(0)
    model = ScoreModel.create(FootprintEncoder(), hidden=8, layers=1)
    scene = Scene(
        [
            SceneObject(f"o{k}", ("cup", "box")[k % 2], (0.1, 0.1), (0.15 * k - 0.3, 0.05 * k, 0.3 * k))
            for k in range(3)
        ],
        bounds=((-0.6, -0.6), (0.6, 0.6)),
    )
    o = replace(_quick(), count=0.0)  # moving is free: the selection moves objects, so there is work ahead
    used: list[tuple[list[str], bool, list[np.ndarray]]] = []
    placed = T.place_again

    def spy(model, scenes, moved, seed):
        out = placed(model, scenes, moved, seed)
        used.append((moved[0], threading.current_thread() is threading.main_thread(), out[0]))
        return out

    def patient(self, key, work):  # the worker's answer wherever the key is still to run there
        f = self._futures.get(key)
        return work() if f is None or f.cancelled() else f.result()

    monkeypatch.setattr(T, "place_again", spy)
    threads = torch.get_num_threads()
    monkeypatch.setattr(Ahead, "worth", staticmethod(lambda: False))  # serial whatever the budget and load
    serial = tidy(model, scene, effort=0.2, seed=3, options=o).to_dict()
    assert serial["moved"] and used == [(serial["moved"], True, used[0][2])]
    monkeypatch.setattr(Ahead, "worth", staticmethod(lambda: True))
    monkeypatch.setattr(Ahead, "result", patient)
    ahead = tidy(model, scene, effort=0.2, seed=3, options=o).to_dict()
    names, main, poses = used[-1]
    assert names == serial["moved"] and not main  # the worker placed the moved set
    assert len(poses) == len(used[0][2]) and all(np.array_equal(a, b) for a, b in zip(poses, used[0][2]))
    assert json.dumps(ahead, sort_keys=True) == json.dumps(serial, sort_keys=True)
    assert torch.get_num_threads() == threads  # the caller's setting is left alone
