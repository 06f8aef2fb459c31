"""Which categories a handful of examples pin down: against scenes built so that the answer is known."""

from __future__ import annotations

import math

import numpy as np
import pytest

import scenescore as ss
from scenescore.models.flags import assess
from scenescore.models.freedom import BOUNDS, FREE_SPREAD, describe_spreads, spreads

WALL = ((-0.6, -0.6), (0.6, 0.6))


def _scenes(n: int, seed: int = 0) -> list[ss.Scene]:
    """A plate anywhere with a fork 0.15 m to its left (in its frame), a vase anywhere, a lamp in one
    corner of the table and a round coaster 0.1 m from the plate at any bearing."""
    rng = np.random.default_rng(seed)
    out = []
    for _ in range(n):
        plate = (*rng.uniform(-0.3, 0.3, 2), rng.uniform(-math.pi, math.pi))
        c, s = math.cos(plate[2]), math.sin(plate[2])
        fork = (plate[0] - 0.15 * c, plate[1] - 0.15 * s, plate[2])
        bearing = rng.uniform(-math.pi, math.pi)
        coaster = (plate[0] + 0.1 * math.cos(bearing), plate[1] + 0.1 * math.sin(bearing), 0.0)
        out.append(
            ss.Scene(
                [
                    ss.SceneObject("plate_0", "plate", (0.2, 0.2), plate, shape="disk"),
                    ss.SceneObject("fork_0", "fork", (0.18, 0.03), fork),
                    ss.SceneObject("vase_0", "vase", (0.1, 0.1), (*rng.uniform(-0.5, 0.5, 2), 0.0)),
                    ss.SceneObject("lamp_0", "lamp", (0.1, 0.1), (0.45, 0.45, 0.0)),
                    ss.SceneObject("coaster_0", "coaster", (0.06, 0.06), coaster, shape="disk"),
                ],
                WALL,
                meta={"unit": "m"},
            )
        )
    return out


def test_relations_the_examples_repeat_pin_a_category_and_the_rest_are_free():
    table = spreads(_scenes(5), 0.05)
    assert not table["fork"].free and table["fork"].anchor in ("plate", "coaster")
    assert table["fork"].spread < 1e-9
    assert not table["lamp"].free and table["lamp"].anchor == BOUNDS  # always in the same corner
    assert not table["coaster"].free  # a round plate has no heading: the distance alone pins it
    assert table["vase"].free and table["vase"].spread > FREE_SPREAD


def test_one_scene_pins_nothing():
    table = spreads(_scenes(1), 0.05)
    assert all(s.free and s.spread == math.inf for s in table.values())
    lines = describe_spreads(table, 0.05, "m")
    assert lines[0] == "the examples pin down: no category"
    assert "vase (in one scene only)" in lines[1]


def test_the_spreads_scale_with_the_data():
    scenes = _scenes(5)
    mm = [s.scaled(1000.0) for s in scenes]
    a, b = spreads(scenes, 0.05), spreads(mm, 50.0)
    for c in a:
        assert a[c].anchor == b[c].anchor and a[c].free == b[c].free
        assert b[c].spread == pytest.approx(a[c].spread, rel=1e-9, abs=1e-9)


def test_training_stores_the_spreads_and_a_free_placement_says_so():
    scenes = _scenes(6)
    model = ss.learn.fit(scenes, ss.learn.TrainConfig(members=1, iterations=5), seed=0, progress=False)
    ref = model.trust
    assert ref is not None and ref.spreads is not None
    assert ref.spread("vase") is not None and ref.spread("vase").free
    assert ref.spread("fork") is not None and not ref.spread("fork").free
    assert ref.spread("anvil") is None
    back = ss.models.trust.TrustReference.from_dict(ref.to_dict())
    assert back.spreads == ref.spreads and back.spread_anchors == ref.spread_anchors
    verdict = assess(ref, model, scenes[0], ["vase_0", "fork_0"])
    assert any(n.startswith("free: the examples leave a vase's place free") for n in verdict["vase_0"].notes)
    assert verdict["fork_0"].notes == []
    assert "notes" in verdict["vase_0"].to_dict() and "notes" not in verdict["fork_0"].to_dict()


def test_a_reference_without_spreads_reads_as_before():
    ref = ss.models.trust.TrustReference(
        energies=[0.0], length_scale=0.1, nearest={}, nearest_any=0.0, touches_bounds=[]
    )
    assert ref.spread("vase") is None
    with pytest.raises(ValueError, match="spreads"):
        ss.models.trust.TrustReference.from_dict({**ref.to_dict(), "spreads": {"vase": "wide"}})
