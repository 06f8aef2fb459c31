"""``explain``: an object's well split into its neighbours' parts, which add up to it; the relation a
model learned from its data is the one that holds the object; rigid motions and units change nothing."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenescore as ss
from scenescore.models.explain import explain, well_depth

BOUNDS = ((-0.6, -0.6), (0.6, 0.6))
# where the cup stands in the frame of the object that holds it (its heading the holder's)
OFFSET = {"tray": (0.0, 0.17), "book": (0.0, -0.17)}


def _at(anchor: tuple[float, float, float], offset: tuple[float, float]) -> tuple[float, float, float]:
    x, y, t = anchor
    c, s = math.cos(t), math.sin(t)
    return (x + c * offset[0] - s * offset[1], y + s * offset[0] + c * offset[1], t)


def _scene(rng: np.random.Generator, holder: str) -> ss.Scene:
    """A tray and a book somewhere apart on the table, and a cup beside ``holder`` (tray or book)."""
    while True:
        tray = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
        book = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
        if math.dist(tray[:2], book[:2]) > 0.45:
            break
    cup = _at(tray if holder == "tray" else book, OFFSET[holder])
    return ss.Scene(
        [
            ss.SceneObject("tray_0", "tray", (0.24, 0.12), tray, color=(200, 160, 90)),
            ss.SceneObject("book_0", "book", (0.20, 0.14), book, color=(60, 90, 160)),
            ss.SceneObject("cup_0", "cup", (0.08, 0.05), cup, color=(220, 60, 60)),
        ],
        BOUNDS,
        meta={"unit": "m"},
    )


def _model(holder: str) -> ss.models.ScoreModel:
    rng = np.random.default_rng(0 if holder == "tray" else 1)
    scenes = [_scene(rng, holder) for _ in range(24)]
    return ss.learn.fit(scenes, ss.learn.TrainConfig(members=1, iterations=150), seed=0, progress=False)


@pytest.fixture(scope="module")
def by_tray() -> ss.models.ScoreModel:
    return _model("tray")


@pytest.fixture(scope="module")
def by_book() -> ss.models.ScoreModel:
    return _model("book")


def _both() -> ss.Scene:
    """A scene whose cup stands where either rule puts it: beside the tray and beside the book, all
    three turned alike."""
    cup = (-0.05, 0.02, 0.3)
    c, s = math.cos(cup[2]), math.sin(cup[2])
    tray = (cup[0] + s * OFFSET["tray"][1], cup[1] - c * OFFSET["tray"][1], cup[2])
    book = (cup[0] + s * OFFSET["book"][1], cup[1] - c * OFFSET["book"][1], cup[2])
    return ss.Scene(
        [
            ss.SceneObject("tray_0", "tray", (0.24, 0.12), tray),
            ss.SceneObject("book_0", "book", (0.20, 0.14), book),
            ss.SceneObject("cup_0", "cup", (0.08, 0.05), cup),
        ],
        BOUNDS,
        meta={"unit": "m"},
    )


def test_the_relation_in_the_data_is_the_one_that_holds_the_object(by_tray, by_book):
    rng = np.random.default_rng(7)
    for scene in [_scene(rng, "tray") for _ in range(3)]:  # cups beside trays, books elsewhere
        held = explain(by_tray, scene, "cup_0")
        assert held.depth > 0
        assert held.strongest is not None and held.strongest.neighbour == "tray_0"
        tray = next(r for r in held.relations if r.neighbour == "tray_0")
        assert tray.part > 0.5 * held.depth and tray.shown > 0 and tray.pairs >= tray.shown
        # the relation taken out of the data (cups beside books instead): the tray no longer holds the
        # cup but pushes it off, and the examples do not show the cup there
        other = explain(by_book, scene, "cup_0")
        tray_now = next(r for r in other.relations if r.neighbour == "tray_0")
        assert tray_now.part < 0 < tray.part
        assert other.strongest is None or other.strongest.neighbour != "tray_0"
        assert tray_now.shown == 0


def test_the_parts_add_up_to_the_well(by_tray):
    scene = _both()
    e = explain(by_tray, scene, "cup_0")
    total = sum(r.part for r in e.relations) + e.others + (e.walls or 0.0)
    assert abs(total + e.rest - e.depth) < 1e-9  # the books balance by construction
    assert abs(e.rest) < 0.02 * abs(e.depth) + 1e-6  # the integration leaves next to nothing
    offsets = np.array([[0.05, 0.0], [-0.05, 0.0], [0.0, 0.05], [0.0, -0.05]])
    assert well_depth(by_tray, scene, "cup_0", offsets) == pytest.approx(
        float(np.mean([well_depth(by_tray, scene, "cup_0", offsets[k : k + 1]) for k in range(4)])), abs=1e-5
    )


def test_a_rigid_motion_of_the_whole_scene_changes_no_part(by_tray):
    scene = _both()
    moved = scene.with_poses(
        np.array([_at((0.07, -0.04, 0.9), (p[0], p[1])) for p in scene.poses()])
        + np.array([[0.0, 0.0, p[2]] for p in scene.poses()])
    )
    a, b = explain(by_tray, scene, "cup_0"), explain(by_tray, moved, "cup_0")
    assert b.depth == pytest.approx(a.depth, rel=1e-4, abs=1e-5)
    for r, s in zip(a.relations, b.relations):
        assert (r.neighbour, r.shown) == (s.neighbour, s.shown)
        assert s.part == pytest.approx(r.part, rel=1e-4, abs=1e-5)


def test_explain_refuses_what_it_cannot_explain(by_tray):
    scene = _both()
    with pytest.raises(KeyError, match="no object 'mug'"):
        explain(by_tray, scene, "mug")
    with pytest.raises(ValueError, match="place cup_0 first"):
        explain(by_tray, scene.without("cup_0"), "tray_0")


def test_a_result_explains_its_placement(by_tray):
    scene = _both().without("cup_0")
    r = ss.solve(ss.planning.placement.placement_problem(by_tray, scene), "langevin", seed=0)
    e = r.explain()
    assert e.name == "cup_0" and e.strongest is not None
    assert e.pose == pytest.approx(tuple(r.poses[scene.index("cup_0")]))
    assert "cup_0 (cup)" in e.table() and "tray_0" in e.table()
    with pytest.raises(ValueError, match="no learned energy"):
        ss.solve(ss.Problem(scene, ss.costs.Bounds(), movable=["cup_0"]), "langevin", seed=0).explain()


def test_example_scenes_given_are_named_by_index(by_tray):
    rng = np.random.default_rng(5)
    examples = [_scene(rng, "tray") for _ in range(3)] + [_scene(rng, "book") for _ in range(2)]
    e = explain(by_tray, _both(), "cup_0", examples)
    tray = next(r for r in e.relations if r.neighbour == "tray_0")
    book = next(r for r in e.relations if r.neighbour == "book_0")
    assert tray.scenes == [0, 1, 2] and book.scenes == [3, 4]
    assert "3 example scenes (0, 1, 2)" in tray.examples


def test_the_depth_is_the_energy_s_rise_as_the_model_places(by_tray):
    from scenescore.models.explain import RINGS, _offsets

    scene = _both()
    e = explain(by_tray, scene, "cup_0")
    length = by_tray.config.length_scale
    assert e.rings == pytest.approx(tuple(r * length for r in RINGS))
    assert e.depth == pytest.approx(well_depth(by_tray, scene, "cup_0", _offsets(length)), rel=1e-4, abs=1e-4)


def _row(n: int) -> ss.Scene:
    rng = np.random.default_rng(3)
    objs = [
        ss.SceneObject(
            f"box_{k}",
            "box" if k % 2 else "crate",
            (0.1, 0.06),
            (-0.55 + 0.1 * k, rng.uniform(-0.05, 0.05), 0.2 * k),
        )
        for k in range(n)
    ]
    return ss.Scene(objs, BOUNDS, meta={"unit": "m"})


@pytest.mark.parametrize(
    "config",
    [{"neighbours": 4, "radius": 1.0}, {"walls": True}, {}],
    ids=["local graph", "walls", "dense"],
)
def test_the_parts_add_up_for_every_graph(config):
    import torch

    from scenescore.encoders import FootprintEncoder

    torch.manual_seed(0)
    model = ss.models.ScoreModel.create(
        FootprintEncoder(), hidden=16, edge_encoder=16, length_scale=0.05, **config
    )
    scene = _row(12)
    e = explain(model, scene, "box_5", neighbours=3)
    total = sum(r.part for r in e.relations) + e.others + (e.walls or 0.0)
    assert abs(total + e.rest - e.depth) < 1e-9
    assert abs(e.rest) < 0.02 * max(abs(e.depth), 1e-3)
    assert (e.walls is not None) == bool(config.get("walls")) and e.unlisted == 11 - 3


def test_an_ensemble_s_parts_are_its_members_mean():
    from scenescore.encoders import FootprintEncoder
    from scenescore.models.ensemble import EnsembleNet

    scene = _row(5)
    one = [ss.models.ScoreModel.create(FootprintEncoder(), hidden=8, length_scale=0.05) for _ in range(2)]
    both = ss.models.ScoreModel(EnsembleNet([m.net for m in one]), one[0].encoder)
    each = [explain(m, scene, "box_2") for m in one]
    mean = explain(both, scene, "box_2")
    assert mean.depth == pytest.approx(np.mean([x.depth for x in each]), abs=1e-9)
    parts = {r.neighbour: r.part for r in mean.relations}
    for name in parts:
        assert parts[name] == pytest.approx(
            np.mean([{r.neighbour: r.part for r in x.relations}[name] for x in each]), abs=1e-9
        )


def test_a_flagged_placement_names_the_relation_it_doubts_unless_told_not_to(by_tray):
    from scenescore.costs.guide import guides
    from scenescore.models.trust import Assessment
    from scenescore.planning.placement import place_many, placement_problem

    scene = _both()
    hole = scene.without("cup_0")
    said = {}
    for relations in (True, False):
        (energy,) = guides(placement_problem(by_tray, hole, relations=relations).cost)
        said[relations] = energy.doubted(scene.poses(), {"cup_0": Assessment(0.2, ["far: a test's flag"])})
    assert said[True]["cup_0"].startswith("relation: its place rests most on") and said[False] == {}
    # leaving the relation out changes neither the placement nor whether it is flagged
    rng = np.random.default_rng(11)
    holes = [_scene(rng, "book").without("cup_0") for _ in range(3)] + [hole]
    named, plain = (place_many(by_tray, holes, seed=0, relations=r) for r in (True, False))
    assert any(f.startswith("relation:") for s in named for f in s.meta["placement"]["cup_0"]["flags"])
    for a, b in zip(named, plain):
        assert np.array_equal(a.poses(), b.poses())
        flags_a, flags_b = (s.meta["placement"]["cup_0"]["flags"] for s in (a, b))
        assert [f for f in flags_a if not f.startswith("relation:")] == flags_b
        assert not any(f.startswith("relation:") for f in flags_b)
