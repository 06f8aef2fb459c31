"""The zoo's verdicts: catastrophic and good placements against the oracle, and the trust check's
pooled line, on hand-made case records."""

from __future__ import annotations

from scenescore.experiments.zoo_verdicts import catastrophic, good, trust_line


def _case(t: float, flags: list[str], oracle: float = 1.0) -> dict:
    return {"t_cm": t, "oracle_t_cm": oracle, "flagged": bool(flags), "flags": flags}


def test_catastrophic_needs_both_the_distance_and_the_oracle_multiple():
    cases = [_case(30.0, []), _case(2.0, []), _case(24.0, []), _case(3.0, [])]
    assert catastrophic(cases).tolist() == [True, False, False, False]
    assert good(cases).tolist() == [False, True, False, True]
    # with an oracle mean of 4 cm, 30 cm is under 10 oracle means: not catastrophic
    assert not catastrophic([_case(30.0, [], oracle=4.0), _case(1.0, [], oracle=4.0)]).any()


def test_the_trust_line_pools_the_scenarios_and_counts_the_rival_flag():
    per_case = {
        "a": [_case(40.0, ["rival: another particle ..."]), _case(1.0, []), _case(1.0, ["energy: ..."])],
        "b": [_case(50.0, []), _case(0.5, []), _case(0.8, [])],
    }
    assert trust_line(per_case) == "flagged: 1 of 2 catastrophic (1 by rival), 1 of 4 good (25.0%)"
