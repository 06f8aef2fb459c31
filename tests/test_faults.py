"""Faults while outputs are written: a file-size limit (``ulimit -f``) hit while a checkpoint, a dataset or
a report is saved gives a one-line error naming the file and leaves the earlier file as it was, with no
temporary file beside it; two processes writing one output leave one of the two whole, never a mix.

The command line runs in a subprocess under ``RLIMIT_FSIZE`` (Python ignores SIGXFSZ, so a write past the
limit raises ``OSError(EFBIG)``). The limit applies only to the files the process writes; starting Python
and torch writes none that large. Read-only folders and SIGKILL+resume are tested elsewhere
(tests/hostile/test_cli_args.py, tests/test_resume.py)."""

from __future__ import annotations

import errno
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import pytest

import scenescore as ss
from scenescore.cli import main
from scenescore.learn import NetworkConfig, Run, TrainConfig, fit
from scenescore.scene.outputs import WriteError, atomic_write_bytes

try:
    import resource
except ImportError:  # not POSIX: no RLIMIT_FSIZE
    resource = None  # type: ignore[assignment]

needs_rlimit = pytest.mark.skipif(resource is None, reason="RLIMIT_FSIZE needs POSIX (the resource module)")

LIMIT = 4096  # bytes: below every new output here, far above what starting the command writes
ENV = {**os.environ, "OMP_NUM_THREADS": "1"}
CFG = TrainConfig(
    members=1, iterations=30, batch_scenes=4, negatives=4, network=NetworkConfig(hidden=16, layers=1)
)
SEED = 3


def _limited() -> None:
    resource.setrlimit(resource.RLIMIT_FSIZE, (LIMIT, LIMIT))


def _scenescore(*argv: object) -> subprocess.CompletedProcess[str]:
    """``python -m scenescore ARGV`` in a subprocess, under the file-size limit when ``limit``."""
    cmd = [sys.executable, "-m", "scenescore", *map(str, argv)]
    return subprocess.run(cmd, env=ENV, capture_output=True, text=True, timeout=120, preexec_fn=_limited)


def _fails_in_one_line(done: subprocess.CompletedProcess[str], command: str, path: Path) -> str:
    """The command failed with one error line on stderr, its last, naming ``path``; no traceback."""
    assert done.returncode == 2, f"exit {done.returncode}; stderr: {done.stderr}"
    assert "Traceback" not in done.stderr, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines, "nothing on stderr"
    last = lines[-1]
    assert last.startswith(f"scenescore {command}: error: {path}: could not be written"), last
    assert "File too large" in last and "the earlier file is unchanged" in last, last
    return last


def _intact(folder: Path, before: dict[str, bytes]) -> None:
    """Every file of ``folder`` holds its bytes of ``before``, and there is no other (no temporary file)."""
    assert sorted(p.name for p in folder.iterdir()) == sorted(before)
    for name, data in before.items():
        assert (folder / name).read_bytes() == data, f"{name} was changed"


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir()}


# -- a file-size limit hit while an output is saved --------------------------------------------------


@pytest.fixture(scope="module")
def trained(tmp_path_factory: pytest.TempPathFactory) -> tuple[Path, Path, Path]:
    """(training data, a checkpoint of an earlier run, the finished training state of a run with the
    command line's settings below on that data)."""
    folder = tmp_path_factory.mktemp("trained")
    data, ckpt, state = folder / "dining.jsonl", folder / "earlier.ckpt", folder / "finished.state"
    scenes = ss.scenarios.get("dining").generate(6, 0)
    ss.write_jsonl(data, scenes)
    model = fit(ss.read_jsonl(data), CFG, seed=SEED, progress=False, run=Run(state=state, keep_state=True))
    model.save(ckpt)
    return data, ckpt, state


def _train_argv(data: Path, out: Path, *extra: object) -> list[object]:
    """``scenescore train`` with the settings of ``CFG``, on every scene (``--val 0``)."""
    settings = ["--set", "batch_scenes=4", "--set", "network.hidden=16", "--set", "network.layers=1"]
    return [
        "train", "--members", "1", data, "--out", out, "--iterations", "30", "--negatives", "4", *settings, "--val", "0",
        "--force", "--quiet", "--seed", SEED, "--threads", "1", *extra,
    ]  # fmt: skip


def _earlier_training(folder: Path, trained: tuple[Path, Path, Path]) -> tuple[Path, Path]:
    """A folder holding the checkpoint and report of an earlier run: (checkpoint, report)."""
    out, report = folder / "m.ckpt", folder / "train_report.json"
    folder.mkdir(exist_ok=True)
    out.write_bytes(trained[1].read_bytes())
    report.write_text('{"checkpoint": "m.ckpt"}\n')
    return out, report


@needs_rlimit
@pytest.mark.slow
def test_train_over_a_checkpoint_past_the_size_limit_keeps_it(trained, tmp_path):
    """The limit is hit at the checkpoint itself: training resumes from a finished state (so nothing but
    the checkpoint and its report is written), the checkpoint fails, the report is not begun."""
    data, _, finished = trained
    out, _ = _earlier_training(tmp_path / "out", trained)
    state = tmp_path / "run.state"
    state.write_bytes(finished.read_bytes())
    before = _snapshot(out.parent)
    done = _scenescore(*_train_argv(data, out, "--resume", "--state", state))
    _fails_in_one_line(done, "train", out)
    _intact(out.parent, before)
    assert state.read_bytes() == finished.read_bytes()  # kept: a rerun resumes without training again


@needs_rlimit
@pytest.mark.slow
def test_train_past_the_size_limit_at_its_state_keeps_the_checkpoint(trained, tmp_path):
    """A run from the start hits the limit at its first training state (beside --out): one line naming
    the state, and the earlier checkpoint and report untouched."""
    data = trained[0]
    out, _ = _earlier_training(tmp_path, trained)
    before = _snapshot(tmp_path)
    done = _scenescore(*_train_argv(data, out, "--save-every", "5"))
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr
    last = done.stderr.strip().splitlines()[-1]
    assert last.startswith(f"scenescore train: error: {out}.state: could not be written (File too large)")
    assert last.endswith("nothing was written"), last
    _intact(tmp_path, before)


@needs_rlimit
@pytest.mark.slow
def test_generate_over_a_dataset_past_the_size_limit_keeps_it(tmp_path):
    out = tmp_path / "data.jsonl"
    assert main(["generate", "dining", "--n", "3", "--seed", "1", "--out", str(out), "--quiet"]) == 0
    before = _snapshot(tmp_path)
    done = _scenescore("generate", "dining", "--n", "50", "--seed", "2", "--out", out, "--quiet")
    _fails_in_one_line(done, "generate", out)
    _intact(tmp_path, before)


def _results(path: Path) -> Path:
    """A results.json whose page is well past :data:`LIMIT`."""
    from scenescore.experiments.report import RESULTS_FORMAT, Row, experiment_entry

    table = "| method | mean_t_cm |\n|---|---|\n" + "".join(f"| m{i} | {i / 7:.3f} |\n" for i in range(400))
    entry = experiment_entry("missing", [Row("SceneScore", {"mean_t_cm": 1.5})], table, 1.0)
    doc = {
        "format": RESULTS_FORMAT,
        "provenance": {"command": "scenescore experiment"},
        "experiments": [entry],
    }
    path.write_text(json.dumps(doc))
    return path


@needs_rlimit
@pytest.mark.slow
def test_report_over_a_page_past_the_size_limit_keeps_it(tmp_path):
    results, page = _results(tmp_path / "results.json"), tmp_path / "page.md"
    page.write_text("# Results\n\nthe earlier page\n")
    before = _snapshot(tmp_path)
    done = _scenescore("report", results, "--out", page)
    _fails_in_one_line(done, "report", page)
    _intact(tmp_path, before)
    unlimited = tmp_path / "unlimited" / "page.md"  # what the page would have been: well past the limit
    assert main(["report", str(results), "--out", str(unlimited)]) == 0
    assert unlimited.stat().st_size > LIMIT


@pytest.mark.parametrize("code", [errno.ENOSPC, errno.EIO])
def test_a_failed_write_is_one_line_naming_the_file_and_keeps_the_old_one(tmp_path, monkeypatch, code):
    """A full disk or an I/O error at the file's sync: a ``WriteError`` (an OSError with the cause's errno,
    and a SceneError the command line prints in one line), the old file kept, no temporary file left."""
    path = tmp_path / "out.bin"
    path.write_bytes(b"old")

    def fail(fd: int) -> None:
        raise OSError(code, os.strerror(code))

    monkeypatch.setattr(os, "fsync", fail)
    with pytest.raises(WriteError) as info:
        atomic_write_bytes(path, b"new" * 1000)
    assert isinstance(info.value, OSError) and isinstance(info.value, ss.SceneError)
    assert info.value.errno == code
    assert (
        str(info.value)
        == f"{path}: could not be written ({os.strerror(code)}); the earlier file is unchanged"
    )
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"] and path.read_bytes() == b"old"


def test_an_error_of_the_callers_own_work_is_not_called_a_write_error(tmp_path):
    """An OSError naming another file (a read in the block of ``write_jsonl``'s scenes) passes unchanged."""

    def scenes():
        yield ss.scenarios.get("dining").generate(1, 0)[0]
        open(tmp_path / "missing.json")  # noqa: SIM115 - raises

    with pytest.raises(FileNotFoundError) as info:
        ss.write_jsonl(tmp_path / "out.jsonl", scenes())
    assert not isinstance(info.value, WriteError)
    assert list(tmp_path.iterdir()) == []


# -- two processes writing one output ----------------------------------------------------------------

SIZE = 1 << 20
WRITES = 50

WRITER = """
import sys
from scenescore.scene.outputs import atomic_write_bytes

path, who = sys.argv[1], sys.argv[2]
sys.stdin.readline()  # the start: both writers are ready
for i in range({writes}):
    atomic_write_bytes(path, (f"{{who}}:{{i}};".encode() * {size})[:{size}])
"""


def _content(data: bytes) -> tuple[str, int]:
    """Which write ``data`` is, ``(writer, i)``, asserting that it is that write whole."""
    head = data[: data.index(b";")].decode()
    who, i = head.split(":")
    assert data == (f"{head};".encode() * SIZE)[:SIZE], f"not one whole write (starts {head!r})"
    return who, int(i)


@pytest.mark.slow
def test_two_processes_writing_one_file_leave_one_whole_write(tmp_path):
    """Two processes each write 50 distinct 1 MB contents to one path while it is read over and over: every
    read, and the file at the end, is one whole write, the last of one of the two; no temporary is left."""
    path = tmp_path / "out.bin"
    code = WRITER.format(writes=WRITES, size=SIZE)
    procs = [
        subprocess.Popen([sys.executable, "-c", code, str(path), who], stdin=subprocess.PIPE, env=ENV)
        for who in ("a", "b")
    ]
    reads: list[tuple[str, int]] = []
    try:
        for p in procs:  # both have imported what they need once the start line is read
            assert p.stdin is not None
            p.stdin.write(b"go\n")
            p.stdin.flush()
        while any(p.poll() is None for p in procs):
            if path.exists():
                reads.append(_content(path.read_bytes()))
    finally:
        for p in procs:
            p.wait(timeout=60)
    assert [p.returncode for p in procs] == [0, 0]
    assert _content(path.read_bytes()) in {("a", WRITES - 1), ("b", WRITES - 1)}
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]


@pytest.mark.slow
def test_two_generate_commands_to_one_out_leave_one_whole_dataset(tmp_path):
    """Two `scenescore generate` of different seeds and sizes to one --out at once: the file is exactly
    what one of them writes alone."""
    runs = {"a": ("1", "3000"), "b": ("2", "2000")}
    alone = {}
    for who, (seed, n) in runs.items():  # what each writes alone (in this process: quick)
        ref = tmp_path / f"{who}.jsonl"
        assert main(["generate", "dining", "--n", n, "--seed", seed, "--out", str(ref), "--quiet"]) == 0
        alone[who] = ref.read_bytes()
    out = tmp_path / "shared" / "data.jsonl"
    out.parent.mkdir()
    argv = [sys.executable, "-m", "scenescore", "generate", "dining", "--quiet", "--out", str(out)]
    procs = [
        subprocess.Popen([*argv, "--seed", seed, "--n", n], env=ENV, stderr=subprocess.PIPE, text=True)
        for seed, n in runs.values()
    ]
    errors = [p.communicate(timeout=120)[1] for p in procs]
    assert [p.returncode for p in procs] == [0, 0], errors
    assert out.read_bytes() in alone.values()
    assert [p.name for p in out.parent.iterdir()] == ["data.jsonl"]


def test_threads_writing_one_file_leave_one_whole_write(tmp_path):
    """The same in one process: threads' temporary files never collide, the rename picks one whole."""
    path = tmp_path / "out.bin"

    def write(who: str) -> None:
        for i in range(10):
            atomic_write_bytes(path, (f"{who}:{i};".encode() * SIZE)[:SIZE])

    threads = [threading.Thread(target=write, args=(w,)) for w in ("a", "b", "c")]
    for t in threads:
        t.start()
    for t in threads:
        t.join()
    assert _content(path.read_bytes()) in {(w, 9) for w in "abc"}
    assert [p.name for p in tmp_path.iterdir()] == ["out.bin"]
