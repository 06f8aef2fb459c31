"""Resumable training: a run interrupted (by an exception, or SIGKILL) and resumed from its training state
ends with the weights of an uninterrupted run, bit for bit; a state of another training is refused.

Exact equality holds here: the resumed run does the same operations in the same order on the same
numbers as the uninterrupted one (the state restores every value the remaining iterations read)."""

from __future__ import annotations

import os
import re
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest
import torch

import scenescore as ss
import scenescore.learn.loop as loop
from scenescore.cli import main
from scenescore.learn import NetworkConfig, Run, StateError, TrainConfig, fit
from scenescore.models import load

CFG = TrainConfig(
    members=1, iterations=30, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)
SEED = 3


class Interrupted(Exception):
    """Stands for the run being killed."""


@pytest.fixture(scope="module")
def scenes():
    return ss.scenarios.get("dining").generate(12, 0)


@pytest.fixture(scope="module")
def uninterrupted(scenes):
    return fit(scenes, CFG, seed=SEED, progress=False)


def _interrupt_at(monkeypatch: pytest.MonkeyPatch, iteration: int) -> None:
    """Make the run die when it would write the state of ``iteration`` (the states before it written)."""
    real = loop.write_state

    def write_or_die(path, key, run, t):
        if run.iteration == iteration:
            raise Interrupted
        real(path, key, run, t)

    monkeypatch.setattr(loop, "write_state", write_or_die)


def _die(*args: object) -> None:
    raise Interrupted


def _same_weights(a: torch.nn.Module, b: torch.nn.Module) -> None:
    sa, sb = a.state_dict(), b.state_dict()
    assert sa.keys() == sb.keys()
    for k in sa:
        assert torch.equal(sa[k], sb[k]), k


# 20: the state of iteration 10 is resumed, before the weights' average starts (iteration 15), and the
# dead run's iterations 10-19 are done again; 30: that of iteration 20, the average under way
@pytest.mark.parametrize("dies_at", [20, 30])
def test_resumed_training_ends_with_the_uninterrupted_weights(
    scenes, uninterrupted, tmp_path, monkeypatch, dies_at
):
    state = tmp_path / "run.state"
    with monkeypatch.context() as m:
        _interrupt_at(m, dies_at)
        with pytest.raises(Interrupted):
            fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, save_every=10))
    assert state.exists()
    resumed = fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, save_every=10, resume=True))
    _same_weights(resumed.net, uninterrupted.net)
    assert resumed.info.history == uninterrupted.info.history
    assert resumed.info.final_loss == uninterrupted.info.final_loss
    assert not state.exists()  # removed once training ended


def test_a_finished_state_resumes_without_training(scenes, uninterrupted, tmp_path, monkeypatch):
    state = tmp_path / "run.state"
    fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, save_every=10, keep_state=True))
    assert state.exists()
    monkeypatch.setattr(loop, "write_state", _die)  # an iteration done now would die: the last writes
    resumed = fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, resume=True))
    _same_weights(resumed.net, uninterrupted.net)


@pytest.mark.parametrize(
    "change, part",
    [
        ({"seed": SEED + 1}, "seed"),
        ({"scenes_from": 1}, "scenes"),
        ({"config": TrainConfig(members=1, iterations=40, batch_scenes=4, negatives=4)}, "settings"),
    ],
)
def test_a_state_of_another_training_is_refused(scenes, tmp_path, change, part):
    state = tmp_path / "run.state"
    fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, save_every=10, keep_state=True))
    data = scenes[change.get("scenes_from", 0) :]
    with pytest.raises(
        StateError, match=rf"^{re.escape(str(state))}: .*another training \(its {part} differ"
    ):
        fit(
            data,
            change.get("config", CFG),
            seed=change.get("seed", SEED),
            progress=False,
            run=Run(state=state, resume=True),
        )
    assert state.exists()  # a refused state is left as it was


def test_a_file_that_is_not_a_state_is_refused(scenes, tmp_path):
    state = tmp_path / "run.state"
    state.write_text("not a state\n")
    with pytest.raises(StateError, match=rf"^{re.escape(str(state))}: not a training state"):
        fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, resume=True))


def _cli(data: Path, out: Path, *extra: str) -> list[str]:
    """``scenescore train`` with the settings of ``CFG``, on every scene (``--val 0``)."""
    settings = ["--set", "batch_scenes=4", "--set", "network.hidden=16", "--set", "network.layers=1"]
    return [
        sys.executable, "-m", "scenescore", "train", "--members", "1", str(data), "--out", str(out), "--iterations", "30",
        "--negatives", "4", *settings, "--val", "0", "--force", "--quiet", "--seed", str(SEED),
        "--threads", "1", "--save-every", "10", *extra,
    ]  # fmt: skip


@pytest.mark.parametrize("folds", [False, True])  # --val 0; six scenes cross-validated, in workers
def test_sigkill_then_resume_writes_the_uninterrupted_weights(scenes, tmp_path, folds):
    few = scenes[:6]  # cross-validated and evaluated after training: few keep the test short
    data = tmp_path / "dining.jsonl"
    ss.write_jsonl(data, few)
    # TMPDIR: the killed run cannot remove its temporary folders; they go with the test's
    env = {**os.environ, "OMP_NUM_THREADS": "1", "TMPDIR": str(tmp_path)}
    out = tmp_path / "model.ckpt"
    state = tmp_path / "model.ckpt.state"  # beside --out by default

    def cli(*extra: str) -> list[str]:
        argv = _cli(data, out, *extra)
        if folds:  # the final model's state is written by the worker process that trains it
            i = argv.index("--val")
            argv[i : i + 2] = ["--jobs", "2"]
        return argv

    proc = subprocess.Popen(cli(), env=env, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 60
        while not state.exists() and proc.poll() is None and time.monotonic() < deadline:
            time.sleep(0.005)
        time.sleep(0.05)  # a few iterations past the first state
        proc.send_signal(signal.SIGKILL)
    finally:
        proc.wait(timeout=30)
    assert proc.returncode == -signal.SIGKILL and state.exists() and not out.exists()
    done = subprocess.run(cli("--resume"), env=env, capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert not state.exists()  # removed once the checkpoint is written
    _same_weights(load(out).net, fit(few, CFG, seed=SEED, progress=False).net)


def test_resume_without_a_state_yet_trains_from_the_start(scenes, uninterrupted, tmp_path, capsys):
    state = tmp_path / "run.state"
    model = fit(scenes, CFG, seed=SEED, progress=False, run=Run(state=state, resume=True))
    assert f"no training state at {state} yet" in capsys.readouterr().err
    _same_weights(model.net, uninterrupted.net)


def test_the_cli_refuses_a_state_of_another_seed_in_one_line(scenes, tmp_path, capsys):
    data, state = tmp_path / "dining.jsonl", tmp_path / "other.state"
    ss.write_jsonl(data, scenes)
    fit(scenes, CFG, seed=SEED + 1, progress=False, run=Run(state=state, save_every=10, keep_state=True))
    argv = _cli(data, tmp_path / "m.ckpt", "--resume", "--state", str(state))[3:]  # after `-m scenescore`
    assert main(argv) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and f"{state}: this training state belongs to another training (its seed" in err[0]
    assert not (tmp_path / "m.ckpt").exists()
