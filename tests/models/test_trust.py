"""Trust in placements: the reference training stores, and the flags that name the object and why."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch
from conftest import rounding_tolerance

import scenescore as ss
from scenescore.learn import NetworkConfig, TrainConfig, fit
from scenescore.models.flags import assess
from scenescore.models.trust import TrustReference, energy_shares
from scenescore.planning.placement import PLACE, place

SMALL = replace(PLACE, particles=16, candidates=256, chain=replace(PLACE.chain, steps=20, final_descent=10))


@pytest.fixture(scope="module")
def dining():
    torch.set_num_threads(1)
    sc = ss.scenarios.get("dining")
    tr, te = sc.generate(12, 3), sc.generate(4, 4)
    cfg = TrainConfig(
        members=1, iterations=40, batch_scenes=6, negatives=6, network=NetworkConfig(hidden=16, layers=2)
    )
    return fit(tr, cfg, seed=0, progress=False, validation=te), tr, te


def test_training_stores_the_reference(dining):
    model, tr, te = dining
    ref = model.trust
    assert isinstance(ref, TrustReference)
    assert len(ref.energies) == len(te) and ref.energies == sorted(ref.energies)
    assert set(ref.nearest) == {"plate", "fork", "knife", "bowl"}
    assert ref.touches_bounds == []  # no dining object touches the table's square bounds
    assert ref.length_scale == model.config.length_scale


def test_examples_are_in_distribution(dining):
    model, _, te = dining
    for s in te:
        a = assess(model.trust, model, s, s.names)
        assert all(not v.flags for v in a.values()), {n: v.flags for n, v in a.items() if v.flags}


def test_a_placement_forced_far_away_in_larger_bounds_is_flagged(dining):
    """A model trained on a 1.2 m table asked to place in bounds 10x larger, the bowl pulled to a corner."""
    model, _, te = dining
    big = te[0].without("bowl_0")
    big.bounds = ((-6.0, -6.0), (6.0, 6.0))
    cost = ss.costs.LearnedEnergy(model) + 100.0 * ss.costs.PoseTarget("bowl_0", (6.0, 6.0))
    r = ss.solve(
        ss.Problem(big, cost), "langevin", seed=0, options={"langevin": {"particles": 8, "steps": 20}}
    )
    a = r.confidence["bowl_0"]
    assert any(f.startswith("far:") for f in a.flags), a.flags
    assert any(f.startswith("bound:") for f in a.flags), a.flags
    assert any("bowl_0: far:" in w for w in r.warnings)
    assert "warning: bowl_0" in r.summary()
    assert r.to_dict()["confidence"]["bowl_0"]["flags"] == a.flags


def test_an_object_far_from_the_training_categories_is_flagged(dining):
    model, _, te = dining
    s = te[1]
    odd = ss.SceneObject("thing", "anvil", (0.5, 0.4), None, color=(255, 0, 255), shape="box")
    q = ss.Scene([*s.objects, odd], s.bounds)
    out = place(model, q, SMALL, seed=0)
    flags = out.meta["placement"]["thing"]["flags"]
    assert any(f.startswith("novel:") for f in flags), flags
    assert 0.0 <= out.meta["placement"]["thing"]["confidence"] <= 1.0


def test_energy_beyond_the_reference_is_flagged(dining):
    model, _, te = dining
    ref = model.trust
    assert ref.shares is not None
    low = replace(ref, shares={c: [v - 1e3 for v in vs] for c, vs in ref.shares.items()})
    a = assess(low, model, te[0], ["fork_0"])
    assert a["fork_0"].confidence == 0.0
    assert [f for f in a["fork_0"].flags if f.startswith("energy:")] == [
        f"energy: its share of the scene's energy {float(energy_shares(model, te[0], ['fork_0'])[0]):.3g} lies "
        f"beyond any fork's in the data ({low.share_limit('fork'):.3g})"
    ]
    # a checkpoint from before the shares were stored judges the scene's energy per object
    old = replace(ref, shares=None, energies=[e - 1e3 for e in ref.energies])
    a = assess(old, model, te[0], ["fork_0"])
    assert a["fork_0"].confidence == 0.0 and any(
        f.startswith("energy: the scene's") for f in a["fork_0"].flags
    )
    # a reference that round-trips through a checkpoint's JSON is the same reference
    assert TrustReference.from_dict(ref.to_dict()) == ref
    assert np.isfinite(ref.energy_limit)


def test_outside_data_agrees_with_the_bound_far_and_apart_flags(dining):
    """The batched check marks exactly the rows in which the one-pose check flags the object ``bound``,
    ``far`` or ``apart``."""
    from scenescore.models.trust import outside_data

    model, _, te = dining
    s, rng = te[0], np.random.default_rng(0)
    (x0, y0), (x1, y1) = s.bounds
    poses = np.repeat(s.poses()[None], 48, axis=0)
    i = s.index("plate_0")
    poses[:, i, 0] = rng.uniform(x0, x1, 48)
    poses[:, i, 1] = rng.uniform(y0, y1, 48)
    poses[:, i, 2] = rng.uniform(-np.pi, np.pi, 48)
    rows = outside_data(model.trust, s, ["plate_0"], poses)
    flags = [assess(model.trust, model, s.with_poses(p), ["plate_0"])["plate_0"].flags for p in poses]
    want = [any(f.startswith(("bound:", "far:", "apart:")) for f in fl) for fl in flags]
    assert rows.tolist() == want and 0 < sum(want) < 48
    assert any(f.startswith("bound:") for fl in flags for f in fl)
    # a category that comes near a bound in the data, and may lie anywhere, is never outside it
    gaps = {**(model.trust.bound_gaps or {}), "plate": 0.0}
    ref = replace(model.trust, bound_gaps=gaps, nearest={**model.trust.nearest, "plate": 1e9}, apart=None)
    assert not outside_data(ref, s, ["plate_0"], poses).any()


def test_the_reference_stores_how_far_each_category_stands_from_the_nearest_of_each_other():
    from scenescore.models.layout import apart_limits

    near, far = _two_objects((0.5, -0.1, 0.0)), _two_objects((0.2, 0.5, 0.0))  # 0.3 and 0.6 m from a_0
    lone = ss.Scene([ss.SceneObject("c_0", "c", (0.1, 0.1), (0.0, 0.0, 0.0))], near.bounds)
    # in length scales (0.1 m); a lone object stands apart from none
    got = apart_limits([near, far, lone], length=0.1)
    assert got.keys() == {"a", "b"} and got["a"].keys() == {"b"} and got["b"].keys() == {"a"}
    assert got["a"]["b"] == pytest.approx(6.0) and got["b"]["a"] == pytest.approx(6.0)


def test_an_object_farther_from_every_object_of_a_category_than_the_data_is_flagged(dining):
    """A fork among the plates but farther from every knife than any fork in the data stands: flagged
    ``apart`` (naming the knife, in the scene's unit), doubted by ``outside_data``, and the data's own
    scenes not."""
    from scenescore.models.trust import outside_data
    from scenescore.scene.units import length_unit

    model, tr, te = dining
    ref = model.trust
    assert ref.apart is not None and ref.apart["fork"]["knife"] > 0
    s = te[0]
    unit = length_unit(s)
    knives = [o.pose for o in s.objects if o.category == "knife"]
    poses = np.repeat(s.poses()[None], 2, axis=0)
    lone = replace(ref, apart={"fork": {"knife": 0.1 * min(ref.apart["fork"]["knife"], 1.0)}})
    got = assess(lone, model, s, ["fork_0"])["fork_0"].flags
    d = min(float(np.hypot(s["fork_0"].pose[0] - k[0], s["fork_0"].pose[1] - k[1])) for k in knives)
    assert [f for f in got if f.startswith("apart:")] == [
        f"apart: {d:.3g} {unit} from the nearest knife; no fork in the data is more than "
        f"{0.1 * min(ref.apart['fork']['knife'], 1.0) * ref.length_scale:.3g} {unit} from one"
    ]
    assert outside_data(lone, s, ["fork_0"], poses).all()
    assert not outside_data(ref, s, ["fork_0"], poses).any()
    assert not any(
        f.startswith("apart:") for t in tr for a in assess(ref, model, t, t.names).values() for f in a.flags
    )
    bad = {**ref.to_dict(), "apart": {"fork": {"knife": float("inf")}}}
    with pytest.raises(ValueError, match="apart"):
        TrustReference.from_dict(bad)


def test_an_objects_share_is_the_energy_it_adds_to_its_scene(dining):
    """``energy_shares``: the scene's energy minus the scene's without the object, for each object; the
    reference keeps every reference object's share by category, sorted."""
    model, _, te = dining
    s = te[0]

    def energy(scene):
        with torch.no_grad():
            st = model.tensors([scene])
            return float(model.energy(st.poses, st)[0])

    want = [energy(s) - energy(replace(s, objects=[o for o in s.objects if o.name != n])) for n in s.names]
    # float32 in a padded batch against one scene at a time: equal to the rounding of the network's sums,
    # at the scale of the scene's energy (a share is a difference of two energies)
    scale = torch.tensor([energy(s)], dtype=torch.float64)
    tol = rounding_tolerance(
        scale, model.net.cfg.layers * (len(s) + 4 + 2 * model.net.cfg.hidden), torch.float32
    )
    assert energy_shares(model, s).tolist() == pytest.approx(want, abs=tol)
    assert energy_shares(model, s, [s.names[1]]).tolist() == pytest.approx(want[1:2], abs=tol)
    lone = replace(s, objects=s.objects[:1])
    assert energy_shares(model, lone).tolist() == pytest.approx([energy(lone)], abs=tol)
    ref = model.trust
    counts = {c: sum(o.category == c for t in te for o in t.objects) for c in ref.shares}
    assert {c: len(v) for c, v in ref.shares.items()} == counts
    assert all(v == sorted(v) for v in ref.shares.values())
    unseen = ref.category_shares("anvil")  # an unseen category: every category's
    assert len(unseen) == sum(counts.values())


def test_the_reference_stores_how_near_each_category_comes_to_the_bounds(dining):
    from scenescore.models.layout import bound_gap

    model, tr, te = dining
    length = model.config.length_scale
    want: dict[str, float] = {}
    for s in [*tr, *te]:
        for o in s.objects:
            g = max(0.0, bound_gap(o, o.pose, s.bounds)) / length
            want[o.category] = min(want.get(o.category, np.inf), g)
    assert model.trust.bound_gaps == pytest.approx(want, rel=1e-12)
    # a plate 10 cm inside the x >= -0.6 side of a 1.2 m table: its footprint's nearest bound
    plate = next(o for o in tr[0].objects if o.category == "plate")
    r = max(plate.size) / 2
    assert bound_gap(plate, (-0.5 + r, 0.0, 0.0), ((-0.6, -0.6), (0.6, 0.6))) == pytest.approx(0.1, abs=1e-6)


def test_a_category_near_a_bound_in_the_data_may_be_pinned_there(dining):
    """Pinned at a bound is outside the data only for a category whose data keep more than NEAR_BOUND
    length scales from every bound (a nightstand that stands 1.6 cm from the wall may stand against it)."""
    from scenescore.models.trust import NEAR_BOUND, outside_data

    model, _, te = dining
    s = replace(te[0], meta={**te[0].meta, "unit": "m"})  # the flag says lengths in the unit named
    i = s.index("plate_0")
    (x0, _), _ = s.bounds
    pinned = s.poses()
    pinned[i, :2] = (x0 + max(s.objects[i].size) / 2, s.poses()[i, 1])  # against the x >= x0 side
    near = replace(model.trust, bound_gaps={**(model.trust.bound_gaps or {}), "plate": 0.9 * NEAR_BOUND})
    away = replace(model.trust, bound_gaps={**(model.trust.bound_gaps or {}), "plate": 1.1 * NEAR_BOUND})
    assert not outside_data(near, s, ["plate_0"], pinned[None])[0]
    assert outside_data(away, s, ["plate_0"], pinned[None])[0]
    flag = [
        f
        for f in assess(away, model, s.with_poses(pinned), ["plate_0"])["plate_0"].flags
        if f.startswith("bound:")
    ]
    want = f"comes within {1.1 * NEAR_BOUND * away.length_scale:.3g} m of a bound"
    assert len(flag) == 1 and want in flag[0] and "plate" in flag[0], flag
    unnamed = replace(s, meta={k: v for k, v in s.meta.items() if k != "unit"}).with_poses(pinned)
    flag = [f for f in assess(away, model, unnamed, ["plate_0"])["plate_0"].flags if f.startswith("bound:")]
    assert "data units of a bound" in flag[0], flag
    assert not any(
        f.startswith("bound:")
        for f in assess(near, model, s.with_poses(pinned), ["plate_0"])["plate_0"].flags
    )
    # a checkpoint from before the gaps were stored: only the categories that touched a bound may
    old = replace(model.trust, bound_gaps=None)
    assert outside_data(old, s, ["plate_0"], pinned[None])[0]
    assert not outside_data(replace(old, touches_bounds=["plate"]), s, ["plate_0"], pinned[None])[0]
    with pytest.raises(ValueError, match="bound_gaps"):
        TrustReference.from_dict({**model.trust.to_dict(), "bound_gaps": {"plate": float("nan")}})


def test_trusted_first_prefers_a_particle_off_the_bounds(dining):
    """A cost that pulls the bowl into a corner: ``trusted_first`` answers with the best particle that no
    bound pins, and says how many were pinned; without it the corner wins, flagged."""
    model, _, te = dining
    s = te[0].without("bowl_0")
    (x0, y0), (x1, y1) = s.bounds
    cost = ss.costs.LearnedEnergy(model) + 10.0 * ss.costs.PoseTarget("bowl_0", (x1, y1))
    problem = ss.Problem(s, cost)
    opts = {"particles": 16, "steps": 20}
    plain = ss.solve(problem, "langevin", seed=0, options={"langevin": opts})
    first = ss.solve(problem, "langevin", seed=0, options={"langevin": {**opts, "trusted_first": True}})
    assert any(f.startswith("bound:") for f in plain.confidence["bowl_0"].flags)
    assert not any(f.startswith("bound:") for f in first.confidence["bowl_0"].flags)
    assert first.objective >= plain.objective  # it gave up cost to stay where the data has bowls
    # the same population either way: only the answer differs
    assert np.array_equal(plain.samples, first.samples)
    pinned = problem.doubted(torch.as_tensor(first.samples))
    assert 0 < int(pinned.sum()) < 16 and bool(pinned[int(np.argmin(first.sample_costs))])
    assert f"{int(pinned.sum())} of 16 particles put an object where its data has none" in first.message
    assert not plain.message


def test_best_first_orders_feasible_then_trusted_then_cost():
    from scenescore.solvers.result import best_first

    feasible = torch.tensor([True, True, False, True, False])
    trusted = torch.tensor([False, True, True, True, True])
    cost = torch.tensor([0.0, 3.0, -5.0, float("nan"), 1.0])
    assert best_first(feasible, cost, trusted).tolist() == [1, 3, 0, 2, 4]
    assert best_first(feasible, cost).tolist() == [0, 1, 3, 2, 4]


# -- relations: where the data puts each category beside each other, and the candidates drawn from them --
def _two_objects(pose_b: tuple[float, float, float], size: tuple[float, float] = (0.1, 0.1)) -> ss.Scene:
    return ss.Scene(
        [
            ss.SceneObject("a_0", "a", size, (0.2, -0.1, 0.5)),
            ss.SceneObject("b_0", "b", size, pose_b),
        ],
        ((-1.0, -1.0), (1.0, 1.0)),
    )


def test_relations_hold_each_pose_in_the_frame_of_each_other_object():
    from scenescore.geometry.poses import relative_poses
    from scenescore.models.layout import relations
    from scenescore.scene.scene import wrap_angle

    s = _two_objects((0.5, 0.3, -2.9))
    rel = relations([s], length=0.25)
    p = torch.tensor(s.poses())
    want = relative_poses(p[0], p[1]).numpy()
    got = np.asarray(rel["b"]["a"][0])
    assert got[:2] == pytest.approx(want[:2] / 0.25)
    assert got[2] == pytest.approx(float(wrap_angle(want[2])))
    assert set(rel) == {"a", "b"} and list(rel["a"]) == ["b"]


def test_relations_in_a_room_are_to_each_objects_nearest_only():
    """A scene of more than ALL_PAIRS objects keeps each object's pose in the frames of its
    NEAR_RELATIONS nearest objects only; a smaller scene keeps every pair."""
    from scenescore.models.layout import ALL_PAIRS, NEAR_RELATIONS, relations

    def row(n: int, gap: float) -> ss.Scene:  # n objects in a line, ``gap`` apart
        objs = [ss.SceneObject(f"o_{i}", "o", (0.1, 0.1), (gap * i, 0.0, 0.0)) for i in range(n)]
        return ss.Scene(objs, ((-1.0, -1.0), (gap * n + 1.0, 1.0)))

    room = relations([row(ALL_PAIRS + 8, 0.5)], length=0.5)["o"]["o"]
    reach = np.abs(np.asarray(room)[:, 0])  # distances in length scales: whole numbers of gaps
    assert reach.max() <= NEAR_RELATIONS  # at most the 8th nearest's distance (one side, then both)
    table = relations([row(20, 0.5)], length=0.5)["o"]["o"]
    assert np.abs(np.asarray(table)[:, 0]).max() >= 10  # every pair, subsampled: far ones too


def test_relations_are_subsampled_evenly_to_the_cap():
    from scenescore.models.layout import RELATIONS_PER_PAIR, relations

    scenes = [_two_objects((0.01 * k, 0.0, 0.0)) for k in range(3 * RELATIONS_PER_PAIR)]
    rows = relations(scenes, length=1.0)["b"]["a"]
    assert len(rows) == RELATIONS_PER_PAIR
    firsts = relations(scenes[:1], 1.0)["b"]["a"][0], relations(scenes[-1:], 1.0)["b"]["a"][0]
    assert rows[0] == firsts[0] and rows[-1] == firsts[1]  # the first and the last kept


def test_anchored_uses_its_own_category_and_pools_for_an_unseen_one():
    ref = TrustReference(
        energies=[0.0],
        length_scale=2.0,
        nearest={},
        nearest_any=0.0,
        touches_bounds=[],
        relations={"b": {"a": [[1.0, 0.0, 0.5]]}, "c": {"d": [[0.0, 3.0, 0.0]]}},
    )
    idx, rel = ref.anchored("b", ["d", "a", "a"])
    assert idx.tolist() == [1, 2] and rel.tolist() == [[2.0, 0.0, 0.5]] * 2  # metres: x length scale
    idx, rel = ref.anchored("unseen", ["a", "x"])  # pooled over categories, beside anchors the data knows
    assert idx.tolist() == [0] and rel.tolist() == [[2.0, 0.0, 0.5]]
    idx, rel = ref.anchored("unseen", ["x"])  # no anchor the data knows: any relation beside any anchor
    assert idx.tolist() == [0, 0] and sorted(map(tuple, rel.tolist())) == [(0.0, 6.0, 0.0), (2.0, 0.0, 0.5)]
    assert len(replace(ref, relations=None).anchored("b", ["a"])[0]) == 0


def test_a_malformed_relations_table_is_named():
    ref = TrustReference(energies=[0.0], length_scale=1.0, nearest={}, nearest_any=0.0, touches_bounds=[])
    bad = {**ref.to_dict(), "relations": {"b": {"a": [[1.0, float("nan"), 0.0]]}}}
    with pytest.raises(ValueError, match="relations"):
        TrustReference.from_dict(bad)


def test_training_stores_relations_of_the_training_scenes_only(dining):
    from scenescore.models.layout import relations

    model, tr, _ = dining
    assert model.trust.relations == relations(tr, model.config.length_scale)


def test_proposed_candidates_sit_where_the_data_puts_the_object_beside_a_known_one(dining):
    from scenescore.geometry.poses import compose_poses

    model, _, te = dining
    scene = te[0].without("fork_0")
    p = ss.Problem(scene, ss.costs.LearnedEnergy(model))
    gen = lambda: torch.Generator().manual_seed(3)  # noqa: E731
    uniform = p.initial(64, gen())
    x = p.initial(64, gen(), proposals=0.5)
    assert torch.equal(x[32:], uniform[32:])  # the rest: the same uniform draws as without proposals
    assert torch.equal(x, p.initial(64, gen(), proposals=0.5))  # seeded
    i = scene.index("fork_0")
    known = [k for k in range(len(scene)) if k != i]
    idx, rel = model.trust.anchored("fork", [scene.objects[k].category for k in known])
    base = torch.tensor(scene.poses())[[known[j] for j in idx]]
    want = compose_poses(base, torch.tensor(rel))  # (K, 3): every pose the data suggests
    want[:, 2] = torch.remainder(want[:, 2] + torch.pi, 2 * torch.pi) - torch.pi
    want[:, :2] = torch.minimum(torch.maximum(want[:, :2], p.lo), p.hi)
    gap = (x[:32, i, None] - want[None]).abs().amax(-1).amin(-1)  # each candidate to its nearest suggestion
    assert gap.max() < 1e-9
    assert not torch.equal(x[:32, i], uniform[:32, i])
    others = [k for k in range(len(scene)) if k != i]
    assert torch.equal(x[:, others], uniform[:, others])  # known objects stay


def test_proposals_out_of_range_are_named():
    from scenescore.errors import ConfigError
    from scenescore.solvers.langevin import LangevinOptions

    with pytest.raises(ConfigError, match="proposals"):
        LangevinOptions(proposals=1.5)


def test_costs_without_a_learned_energy_propose_nothing():
    scene = _two_objects((0.5, 0.3, -2.9))
    p = ss.Problem(scene, ss.costs.PoseTarget("b_0", (0.0, 0.0)), movable=["b_0"])
    a = p.initial(16, torch.Generator().manual_seed(0))
    b = p.initial(16, torch.Generator().manual_seed(0), proposals=1.0)
    assert torch.equal(a, b)
