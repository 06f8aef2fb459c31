"""The relation library: each checker against hand-built cases on both sides of its definition, every
generated example accepted by its own checker, and `scenescore generate` writing each relation."""

from __future__ import annotations

import math

import pytest
from shapely.geometry import Polygon, box

from scenescore.cli import main
from scenescore.scenarios import RelationScenario, available, get
from scenescore.scenarios.relations import BETWEEN, FACING, NEAR, RELATIONS, TOL
from scenescore.scene.scene import Scene, SceneError, SceneObject, read_jsonl


def _scene(*poses, sizes=None, shapes=None) -> Scene:
    names = "abc"[: len(poses)]
    sizes = sizes or [(0.1, 0.1)] * len(poses)
    shapes = shapes or ["box"] * len(poses)
    return Scene(
        [SceneObject(n, n, s, p, shape=sh) for n, s, p, sh in zip(names, sizes, poses, shapes)],
        ((-1, -1), (1, 1)),
    )


def _check(relation, *poses, **kw) -> bool:
    return RELATIONS[relation].check(_scene(*poses, **kw), tuple("abc"[: len(poses)]))


# (relation, poses that hold, poses that do not): boxes of 10 cm
CASES = [
    ("left_of", [(-0.3, 0, 0), (0, 0.4, 0)], [(-0.05, 0, 0), (0, 0, 0)]),
    ("left_of", [(-0.1, 0, 0), (0, 0, 0)], [(-0.1, 0, math.pi / 4), (0, 0, 0)]),  # touching; turned: not
    ("right_of", [(0.3, 0, 0), (0, -0.2, 0)], [(-0.3, 0, 0), (0, 0, 0)]),
    ("in_front_of", [(0.2, -0.3, 0), (0, 0, 0)], [(0.2, 0.3, 0), (0, 0, 0)]),
    ("behind", [(-0.2, 0.3, 0), (0, 0, 0)], [(0, -0.3, 0), (0, 0, 0)]),
    ("aligned_x", [(0.4, 0.005, 1.0), (0, 0, 0)], [(0.4, 0.05, 0), (0, 0, 0)]),
    ("aligned_x", [(0.4, 0.005, 1.0), (0, 0, 0)], [(0.05, 0, 0), (0, 0, 0)]),  # overlapping: not
    ("aligned_y", [(0.005, 0.4, 0), (0, 0, 0)], [(0.2, 0.4, 0), (0, 0, 0)]),
    ("centred_on", [(0.005, 0.005, 1.0), (0, 0, 0)], [(0.02, 0, 0), (0, 0, 0)]),
    ("near", [(0.15, 0, 0), (0, 0, 0)], [(0.25, 0, 0), (0, 0, 0)]),
    ("near", [(0.15, 0, 0), (0, 0, 0)], [(0.05, 0, 0), (0, 0, 0)]),  # overlapping: not
    ("far_from", [(0.6, 0, 0), (0, 0, 0)], [(0.45, 0, 0), (0, 0, 0)]),
    ("facing", [(-0.4, 0, math.radians(8)), (0, 0, 0)], [(-0.4, 0, math.radians(12)), (0, 0, 0)]),
    ("facing", [(0, -0.4, math.pi / 2), (0, 0, 0)], [(0, -0.4, -math.pi / 2), (0, 0, 0)]),
    ("between", [(0, 0.01, 0), (-0.4, 0, 0), (0.4, 0, 0)], [(0, 0.04, 0), (-0.4, 0, 0), (0.4, 0, 0)]),
    ("between", [(0.2, 0, 0), (-0.4, 0, 0), (0.4, 0, 0)], [(0.6, 0, 0), (-0.4, 0, 0), (0.4, 0, 0)]),
]


@pytest.mark.parametrize("relation, holds, fails", CASES, ids=[c[0] for c in CASES])
def test_checkers_on_hand_built_cases(relation, holds, fails):
    assert _check(relation, *holds)
    assert not _check(relation, *fails)


def test_every_relation_has_cases_and_thresholds_are_edges():
    assert {c[0] for c in CASES} == set(RELATIONS) and len(RELATIONS) >= 9
    # the documented thresholds, just inside and just outside (boxes of 10 cm: gap = distance - 0.1)
    assert _check("near", (0.1 + NEAR + TOL / 2, 0, 0), (0, 0, 0))
    assert not _check("near", (0.1 + NEAR + 2 * TOL, 0, 0), (0, 0, 0))
    assert _check("facing", (-0.4, 0, FACING - 1e-6), (0, 0, 0))
    assert not _check("facing", (-0.4, 0, FACING + 1e-6), (0, 0, 0))
    assert _check("between", (0, BETWEEN + TOL / 2, 0), (-0.4, 0, 0), (0.4, 0, 0))
    assert not _check("between", (0, BETWEEN + 2 * TOL, 0), (-0.4, 0, 0), (0.4, 0, 0))
    # disks: the extent is the disk's, not its heading's box
    assert _check("left_of", (-0.1, 0, 0.7), (0, 0, 0), shapes=["disk", "box"])


def test_checkers_refuse_the_wrong_objects():
    with pytest.raises(SceneError, match="expected 3 object names"):
        RELATIONS["between"].check(_scene((0, 0, 0), (1, 0, 0)), ("a", "b"))
    scene = Scene([SceneObject("a", "a", (0.1, 0.1), None), SceneObject("b", "b", (0.1, 0.1), (0, 0, 0))])
    with pytest.raises(SceneError, match="'a' has no pose"):
        RELATIONS["left_of"].check(scene, ("a", "b"))


@pytest.mark.parametrize("relation", sorted(RELATIONS))
def test_generated_examples_hold_their_relation(relation):
    """Every example: its checker accepts it with no slack, footprints inside, roles apart (but for
    centred_on), and the seed decides the scenes."""
    scenario = get(f"relation-{relation}")
    scenes = scenario.generate(24, 3)
    arity = RELATIONS[relation].arity
    for s in scenes:
        assert scenario.check(s, tol=0.0) and s.names[:arity] == ["a", "b", "c"][:arity]
        assert ("compass" in s.names) == RELATIONS[relation].frame
        (x0, y0), (x1, y1) = s.bounds
        table = box(x0, y0, x1, y1).buffer(1e-9)
        assert all(table.covers(Polygon(o.world_polygon())) for o in s.objects), s.to_json()
    assert [s.to_json() for s in scenes] == [s.to_json() for s in scenario.generate(24, 3)]
    assert [s.to_json() for s in scenes] != [s.to_json() for s in scenario.generate(24, 4)]
    # the examples are not all one arrangement: positions spread over the table
    xs = [s["a"].pose[0] for s in scenes]
    assert max(xs) - min(xs) > 0.3


def test_generate_writes_a_relation(tmp_path, capsys):
    out = tmp_path / "left.jsonl"
    assert {f"relation-{k}" for k in RELATIONS} <= set(available())
    assert main(["generate", "relation-left_of", "--n", "10", "--out", str(out), "--quiet"]) == 0
    scenes = read_jsonl(out)
    assert len(scenes) == 10 and all(get("relation-left_of").check(s) for s in scenes)
    with pytest.raises(SceneError, match="unknown relation 'left'"):
        RelationScenario(relation="left")
