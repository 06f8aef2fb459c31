"""The thread budget: scoped, checked, capping the automatic choices; training and placement leave torch's
setting as they found it."""

from dataclasses import replace

import pytest
import torch

import scenescore as ss
import scenescore.models.chunks as chunks
import scenescore.models.network as network
import scenescore.runtime.threads as th
from scenescore.errors import ConfigError
from scenescore.learn import TrainConfig, fit
from scenescore.planning.placement import place
from scenescore.runtime import cores
from scenescore.runtime.ahead import Ahead
from scenescore.solvers.kernel import PLACEMENT
from scenescore.solvers.langevin import LangevinOptions

pytestmark = pytest.mark.own_threads

SHORT = replace(PLACEMENT, steps=3, final_descent=1)


@pytest.fixture(autouse=True)
def one_thread():
    old = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(old)


def test_budget_is_scoped_and_nests():
    with ss.thread_budget(3) as n:
        assert n == 3 and torch.get_num_threads() == 3 and th.budget() == 3
        with ss.thread_budget(2):
            assert torch.get_num_threads() == 2 and th.workers() == 2
        assert torch.get_num_threads() == 3 and th.budget() == 3
    assert torch.get_num_threads() == 1 and th.budget() == 1
    with ss.thread_budget(None) as n:  # automatic: torch's own setting, untouched
        assert n == 1 and torch.get_num_threads() == 1


def test_budget_restored_after_an_error():
    with pytest.raises(RuntimeError), ss.thread_budget(2):
        raise RuntimeError("boom")
    assert torch.get_num_threads() == 1 and th.budget() == 1


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2", 10**6])
def test_bad_budget_is_one_line(bad):
    with pytest.raises(ConfigError, match=r"thread_budget: threads: expected an integer >= 1") as e:
        with ss.thread_budget(bad):
            pass
    assert "\n" not in str(e.value)
    assert torch.get_num_threads() == 1


def test_a_given_budget_is_used_whatever_the_load(monkeypatch):
    monkeypatch.setattr(th, "free_cores", lambda: 0.0)  # a busy machine: ignored when the budget is given
    with ss.thread_budget(4):
        assert th.workers() == 4


def test_automatic_choice_takes_free_cores_within_the_budget(monkeypatch):
    torch.set_num_threads(4)
    monkeypatch.setattr(th, "free_cores", lambda: 0.1)
    assert th.workers() == 1  # every core busy with other processes
    monkeypatch.setattr(th, "free_cores", lambda: 2.0)
    assert th.workers() == 2
    monkeypatch.setattr(th, "free_cores", lambda: 16.0)
    assert th.workers() == 4  # never above the budget
    monkeypatch.setattr(th, "free_cores", lambda: None)  # cannot tell: the budget
    assert th.workers() == 4


def test_choices_inside_a_one_thread_block_see_the_callers_budget(monkeypatch):
    torch.set_num_threads(3)
    monkeypatch.setattr(th, "free_cores", lambda: 8.0)
    with th.torch_threads(1):
        assert torch.get_num_threads() == 1
        assert th.budget() == 3 and th.workers() == 3
    assert torch.get_num_threads() == 3


def test_free_cores_is_a_share_of_this_process_cpus():
    free = th.free_cores()
    if free is None:
        pytest.skip("the CPU times cannot be read here")
    assert 0.0 <= free <= cores.usable_cores()


def test_train_and_place_leave_torchs_setting_alone():
    scenes = ss.scenarios.get("dining").generate(4, 0)
    torch.set_num_threads(2)
    model = fit(scenes, TrainConfig(members=1, iterations=2, negatives=2), seed=0, progress=False)
    assert torch.get_num_threads() == 2
    with ss.thread_budget(1):
        place(model, scenes[0].without("fork_0"), LangevinOptions(particles=4, chain=SHORT), seed=0)
        assert torch.get_num_threads() == 1
    assert torch.get_num_threads() == 2


def test_ahead_answers_a_submitted_key_from_its_worker_and_any_other_here():
    import threading

    main = threading.current_thread()
    ran: list[tuple[str, bool]] = []

    def work(key: str):
        def run() -> str:
            ran.append((key, threading.current_thread() is main))
            return key * 2

        return run

    gate = threading.Event()
    with Ahead() as ahead:
        ahead.submit("a", lambda: gate.wait(5) and work("a")())
        ahead.submit("b", work("b"))  # waits behind a
        ahead.submit("c", work("c"))  # cancels b, which has not started
        ahead.submit("c", work("never"))  # once per key
        gate.set()
        assert ahead.result("a", work("a-here")) == "aa"  # started: its worker's answer
        assert ahead.result("d", work("d")) == "dd"  # never submitted: computed here; c cancelled
    assert ("a", False) in ran and ("d", True) in ran
    assert not any(k in ("b", "c", "never") for k, _ in ran)


def test_ahead_raises_the_workers_error_and_is_not_worth_it_on_one_thread():
    with Ahead() as ahead:
        ahead.submit("x", lambda: 1 / 0)
        with pytest.raises(ZeroDivisionError):
            ahead.result("x", lambda: 0)  # a failure is not hidden by computing again
    with ss.thread_budget(1):
        assert not Ahead.worth()  # --threads 1: no second core


def test_in_parallel_answers_in_order_each_piece_on_one_torch_thread():
    import threading

    def work(k: int):
        return lambda: (k, threading.current_thread().name, torch.get_num_threads())

    torch.set_num_threads(2)
    with ss.thread_budget(3):
        got = th.in_parallel([work(k) for k in range(7)])
        assert [k for k, _, _ in got] == list(range(7))
        assert {name.startswith("scenescore-piece") for _, name, _ in got} == {True, False}  # workers too
        assert all(n == 1 for _, _, n in got)
        assert torch.get_num_threads() == 3  # the block's setting is back
        one = th.in_parallel([work(k) for k in range(3)], parallel=False)
        assert {name for _, name, _ in one} == {threading.current_thread().name}


def test_a_seed_names_the_weights_and_placements_whatever_the_load(monkeypatch):
    """The mechanism behind "a seed names a result": large batches in pieces fixed by the machine's
    cores, each on one torch thread, so a busy machine (one piece at a time) and an idle one (two at
    once) give the same model and the same placement, bit for bit."""
    torch.set_num_threads(2)  # no budget given: the automatic choice, up to two at once
    monkeypatch.setattr(network, "usable_cores", lambda: 2)  # the pieces: fixed by the machine, not the load
    # 48 rows of up to 25 books: torch's own threads gave two models here (silu rounds by thread share)
    scenes = ss.scenarios.get("zoo-books").generate(48, 0)
    hole = scenes[0].without(scenes[0].objects[1].name)
    threads_seen: set[str] = set()
    real = chunks.in_parallel

    def spy(work, parallel=True):
        threads_seen.add(f"{th.workers()}")
        return real(work, parallel)

    monkeypatch.setattr(chunks, "in_parallel", spy)

    def run():
        model = fit(scenes, TrainConfig(members=1, iterations=1), seed=0, progress=False)
        placed = place(model, hole, LangevinOptions(particles=256, chain=SHORT), seed=0)
        return [p.detach().clone() for p in model.net.parameters()], placed

    monkeypatch.setattr(th, "free_cores", lambda: 0.2)  # busy: one piece at a time
    busy_w, busy_p = run()
    monkeypatch.setattr(th, "free_cores", lambda: 2.0)  # idle: two at once
    idle_w, idle_p = run()
    assert threads_seen == {"1", "2"}  # the energy did run in pieces, one and two at once
    assert all(torch.equal(a, b) for a, b in zip(busy_w, idle_w, strict=True))
    assert [o.pose for o in busy_p.objects] == [o.pose for o in idle_p.objects]
